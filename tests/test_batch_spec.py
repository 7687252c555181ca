"""Batch specs (spec 11.1), their items and local batch runs: refusals, determinism, resume."""

from __future__ import annotations

import csv
import doctest
import importlib
import math
import os

import numpy as np
import pytest
import soundfile

from barsynth.batch.items import (
    _combination,
    _product_order,
    item_seed,
    make_item,
    make_items,
)
from barsynth.batch.run import MANIFEST, METADATA, PARQUET, file_sha256, read_manifest, run_batch
from barsynth.batch.spec import load_spec, parse_spec
from barsynth.errors import BarsynthError, BatchSpecError

SPEC = """model = "twang"
preset = "plastic-30cm"
count = {count}
seed = 7
duration_s = 0.2
[vary.q]
grid = [60, 100, 200]
[vary.gain_mapping]
list = ["linear", "log"]
[vary.length_m]
random = [0.15, 0.4]
[vary.thickness_m]
random = [0.002, 0.004]
[vary.shape]
mutate = 0.2
[vary.slide]
random = true
"""


def spec_of(count=12, text=SPEC):
    return parse_spec(text.format(count=count), source="batch.toml")


@pytest.mark.parametrize("name", ["barsynth.batch.spec", "barsynth.batch.items"])
def test_docstring_examples(name):
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.attempted >= 3 and result.failed == 0


# -- reading a spec ---------------------------------------------------------------------------

def test_a_spec_is_read_with_its_defaults(tmp_path):
    path = tmp_path / "b.toml"
    path.write_text('model = "banded"\ncount = 3\nseed = 0\n')
    spec = load_spec(path)
    assert (spec.model, spec.preset, spec.count, spec.seed) == ("banded", None, 3, 0)
    assert (spec.sample_rate, spec.duration_s, spec.format, spec.vary) == (48000.0, "auto", "wav", ())
    assert spec.grid_size == 1 and spec.source == str(path)


def test_every_variation_is_kept_in_the_specs_order():
    spec = spec_of()
    assert [(v.name, v.kind) for v in spec.vary] == [
        ("q", "grid"), ("gain_mapping", "list"), ("length_m", "random"), ("thickness_m", "random"),
        ("shape", "mutate"), ("slide", "random")]
    assert spec.vary[0].values == (60.0, 100.0, 200.0) and spec.vary[1].values == ("linear", "log")
    assert spec.vary[4].spread == 0.2 and spec.vary[5].values == (False, True)
    assert spec.grid_size == 3


BASE = 'model = "twang"\ncount = 4\nseed = 1\n'


@pytest.mark.parametrize("text, words", [
    ("model = 'twang'\ncount = 4\nseed = 1\nwidth = 3\n", ["unknown key 'width'", "allowed: model, preset"]),
    ("count = 4\nseed = 1\n", ["no model", "twang"]),
    ("model = 'flute'\ncount = 4\nseed = 1\n", ["model = 'flute'", "one of twang"]),
    ("model = 'twang'\npreset = 'marimba'\ncount = 4\nseed = 1\n", ["preset = 'marimba'", "plastic-30cm"]),
    ("model = 'twang'\nseed = 1\n", ["no count", "whole number from 1"]),
    ("model = 'twang'\ncount = 0\nseed = 1\n", ["count = 0", "whole number from 1"]),
    ("model = 'twang'\ncount = 2.5\nseed = 1\n", ["count = 2.5", "whole number"]),
    ("model = 'twang'\ncount = 4\nseed = -1\n", ["seed = -1", "whole number from 0"]),
    ("model = 'twang'\ncount = 4\n", ["no seed"]),
    (BASE + "sample_rate = 100\n", ["sample_rate = 100", "8000 to 384000 Hz"]),
    (BASE + "duration_s = 'long'\n", ["duration_s = 'long'", "auto"]),
    (BASE + "format = 'mp3'\n", ["format = 'mp3'", "wav or flac"]),
    (BASE + "vary = 3\n", ["vary = 3", "[vary.NAME]"]),
    (BASE + "[vary.pitch]\ngrid = [1]\n", ["vary.pitch", "unknown parameter 'pitch'", "known: youngs_modulus_pa"]),
    (BASE + "[vary.q]\nsweep = [1]\n", ["vary.q = ['sweep']", "exactly one of grid, list, random, mutate"]),
    (BASE + "[vary.q]\ngrid = [60]\nlist = [60]\n", ["vary.q", "exactly one of"]),
    (BASE + "[vary.q]\ngrid = []\n", ["vary.q.grid = []", "non-empty list", "50 to 800"]),
    (BASE + "[vary.q]\ngrid = [60, 900]\n", ["vary.q.grid value 2 = 900", "50 to 800"]),
    (BASE + "[vary.material]\nlist = ['gold']\n", ["vary.material.list value 1 = 'gold'", "one of"]),
    (BASE + "[vary.q]\nrandom = [60]\n", ["vary.q.random = [60]", "[low, high] within 50 to 800"]),
    (BASE + "[vary.q]\nrandom = [400, 60]\n", ["vary.q.random = [400, 60]", "low <= high"]),
    (BASE + "[vary.q]\nrandom = [40, 60]\n", ["vary.q.random value 1 = 40", "50 to 800"]),
    (BASE + "[vary.slide]\nrandom = 3\n", ["vary.slide.random = 3", "true (any of true or false)"]),
    (BASE + "[vary.q]\nmutate = 0\n", ["vary.q.mutate = 0", "above 0 and at most 1"]),
    (BASE + "[vary.q]\nmutate = 1.5\n", ["vary.q.mutate = 1.5", "above 0 and at most 1"]),
    (BASE + "[vary.material]\nmutate = 0.1\n", ["vary.material.mutate", "mutate is for numbers"]),
    ("model = 'twang\n", ["not valid TOML"]),
    (BASE + "[vary.material]\nlist = ['steel', 'custom']\n[vary.youngs_modulus_pa]\ngrid = [1e9, 2e9]\n",
     ["vary.material and vary.youngs_modulus_pa", "material = 'steel' sets youngs_modulus_pa", "vary one of them"]),
    (BASE + "[vary.density_kg_m3]\nmutate = 0.1\n[vary.material]\nrandom = true\n",
     ["vary.material and vary.density_kg_m3", "sets density_kg_m3"]),
])
def test_a_bad_spec_is_refused_in_one_line_naming_file_key_and_value(text, words):
    with pytest.raises(BatchSpecError) as info:
        parse_spec(text, source="bad.toml")
    message = str(info.value)
    assert isinstance(info.value, BarsynthError) and isinstance(info.value, ValueError)
    assert message.startswith("bad.toml: ") and "\n" not in message
    for word in words:
        assert word in message, (word, message)


def test_a_list_parameter_takes_grid_or_list_only():
    text = 'model = "banded"\ncount = 2\nseed = 1\n[vary.mode_ratios]\n'
    with pytest.raises(BatchSpecError, match="random and mutate take one number"):
        parse_spec(text + "mutate = 0.1\n", source="k.toml")
    spec = parse_spec(text + "list = [[1.0, 2.76], [1.0, 3.0]]\n")
    assert [item.parameters["mode_ratios"] for item in make_items(spec)] == [(1.0, 2.76), (1.0, 3.0)]


def test_a_missing_file_is_one_line(tmp_path):
    with pytest.raises(BatchSpecError, match=r"cannot read batch spec .*nope\.toml"):
        load_spec(tmp_path / "nope.toml")


# -- items ------------------------------------------------------------------------------------

def test_items_are_deterministic_and_independent_of_the_count():
    few, many = make_items(spec_of(5)), make_items(spec_of(40))
    assert few == many[:5] == make_items(spec_of(5))
    assert make_items(spec_of(40), start=17, stop=19) == many[17:19]
    assert make_item(spec_of(40), 33) == many[33]


def test_the_seed_is_numpys_spawned_seed_sequence():
    children = np.random.SeedSequence(7).spawn(12)
    for i, child in enumerate(children):  # the render seed: the first word of the item's first child
        assert item_seed(7, i) == int(child.spawn(1)[0].generate_state(1)[0])
    seeds = [item.seed for item in make_items(spec_of(40))]
    assert len(set(seeds)) == 40
    assert [item.seed for item in make_items(parse_spec(SPEC.format(count=3).replace("seed = 7", "seed = 8")))] \
        != seeds[:3]


def test_grid_and_list_cycle_and_draws_stay_within_their_bounds():
    spec, items = spec_of(60), make_items(spec_of(60))
    grid = [v for v in spec.vary if v.kind == "grid"]
    assert [_combination(grid, i) for i in range(6)] == _product_order(grid) * 2
    assert [it.values["q"] for it in items[:6]] == [60.0, 100.0, 200.0] * 2
    assert [it.values["gain_mapping"] for it in items[:4]] == ["linear", "log"] * 2
    lengths = np.array([it.values["length_m"] for it in items])
    thick = np.array([it.values["thickness_m"] for it in items])
    assert lengths.min() >= 0.15 and lengths.max() <= 0.4 and lengths.std() > 0.04
    assert thick.min() >= 0.002 and thick.max() <= 0.004
    shapes = np.array([it.values["shape"] for it in items])  # preset 1.5, range 0.5-10: +-1.9, clipped at 0.5
    assert shapes.min() >= 0.5 and shapes.max() <= 1.5 + 0.2 * 9.5 + 1e-12
    assert {it.values["slide"] for it in items} == {False, True}
    for it in items:  # every parameter resolved, the varied ones as drawn, the others the preset's
        assert it.parameters["length_m"] == it.values["length_m"] and it.parameters["density_kg_m3"] == 1180.0


def test_random_draws_are_uniform_on_the_tables_scale():
    """thickness_m is a log row: half its draws fall below the geometric mean of the bounds
    (2.83 mm; a linear draw would put 41 % there); length_m is linear: half below 0.275 m."""
    from barsynth.batch.items import draw_value
    from barsynth.models import get_model

    spec, table = spec_of(), get_model("twang").table
    rng = np.random.default_rng(1)
    thick = np.array([draw_value(table["thickness_m"], spec.vary[3], 0.003, rng) for _ in range(4000)])
    length = np.array([draw_value(table["length_m"], spec.vary[2], 0.3, rng) for _ in range(4000)])
    assert abs(np.mean(thick < math.sqrt(0.002 * 0.004)) - 0.5) < 0.03
    assert abs(np.mean(length < 0.275) - 0.5) < 0.03


def test_a_custom_material_and_its_modulus_may_both_vary():
    spec = parse_spec(BASE + "[vary.material]\nlist = ['custom']\n[vary.youngs_modulus_pa]\ngrid = [1e9, 2e9]\n")
    assert [item.parameters["youngs_modulus_pa"] for item in make_items(spec)] == [1e9, 2e9, 1e9, 2e9]


def test_a_material_on_a_grid_sets_its_modulus():
    spec = parse_spec('model = "twang"\ncount = 2\nseed = 1\n[vary.material]\ngrid = ["steel", "maple"]\n')
    a, b = make_items(spec)
    assert a.parameters["material"] == "steel" and b.parameters["material"] == "maple"
    assert a.parameters["youngs_modulus_pa"] > 10 * b.parameters["youngs_modulus_pa"]


# -- running a batch --------------------------------------------------------------------------

SMALL = """model = "twang"
preset = "plastic-30cm"
count = 6
seed = 3
duration_s = 0.2
[vary.q]
grid = [60, 200]
[vary.length_m]
random = [0.15, 0.4]
"""


def _tree(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def small_runs(tmp_path_factory):
    spec = parse_spec(SMALL, source="small.toml")
    one, two = tmp_path_factory.mktemp("one"), tmp_path_factory.mktemp("two")
    rows = run_batch(spec, one, workers=1, spec_text=SMALL)
    run_batch(spec, two, workers=2, spec_text=SMALL)
    return spec, one, two, rows


def test_one_and_two_workers_write_byte_identical_files_and_manifests(small_runs):
    _, one, two, _ = small_runs
    a, b = _tree(one), _tree(two)
    assert sorted(a) == [f"audio/0000000{i}.wav" for i in range(6)] + [MANIFEST, PARQUET, METADATA, "spec.toml"]
    assert a == b
    assert not [name for name in os.listdir(one / "audio") if name.startswith(".")]  # no temporary left


def test_the_manifest_holds_hashes_seeds_parameters_and_features(small_runs):
    spec, one, _, rows = small_runs
    with open(one / MANIFEST, newline="") as f:
        table = list(csv.DictReader(f))
    assert table == rows and [r["id"] for r in table] == [str(i) for i in range(6)]
    items = make_items(spec)
    for row, item in zip(table, items):
        assert row["sha256"] == file_sha256(one / row["file"]) and row["error"] == ""
        assert row["seed"] == str(item.seed) and float(row["length_m"]) == item.values["length_m"]
        samples, rate = soundfile.read(one / row["file"])
        assert rate == 48000 and samples.size == 9600 and abs(np.max(np.abs(samples)) - 10 ** (-1 / 20)) < 1e-3
        # the features measure the sound: f0 is a spectral peak of the file, the centroid its spectrum's mean
        f0 = float(row["f0_hz"])
        spectrum = np.abs(np.fft.rfft(samples * np.hanning(samples.size)))
        freqs = np.fft.rfftfreq(samples.size, 1 / rate)
        near = (freqs > f0 - 15) & (freqs < f0 + 15)
        assert spectrum[near].max() > 0.1 * spectrum.max()
        power = np.abs(np.fft.rfft(samples)) ** 2
        assert float(row["centroid_hz"]) == pytest.approx(float((freqs * power).sum() / power.sum()), rel=0.01)
        assert 0.03 < float(row["t60_s"]) < 30
    with open(one / METADATA, newline="") as f:
        meta = list(csv.DictReader(f))
    assert [m["file_name"] for m in meta] == [r["file"] for r in table]


def test_resume_redoes_only_a_deleted_or_corrupted_file(small_runs, tmp_path):
    spec, one, _, rows = small_runs
    work = tmp_path / "work"
    for name, data in _tree(one).items():
        (work / name).parent.mkdir(parents=True, exist_ok=True)
        (work / name).write_bytes(data)
    os.remove(work / "audio/00000002.wav")
    corrupt = work / "audio/00000004.wav"
    corrupt.write_bytes(corrupt.read_bytes()[:-10] + b"0123456789")
    before = {name: os.stat(work / "audio" / name).st_mtime_ns for name in os.listdir(work / "audio")}
    calls = []
    again = run_batch(spec, work, workers=1, resume=True, progress=lambda done, total: calls.append((done, total)))
    assert calls[0] == (4, 6) and calls[-1] == (6, 6)  # 4 kept, 2 rendered
    assert again == rows and _tree(work) == _tree(one)
    after = {name: os.stat(work / "audio" / name).st_mtime_ns for name in os.listdir(work / "audio")}
    assert [n for n in before if n in after and after[n] != before[n]] == ["00000004.wav"]  # the rest untouched
    assert "00000002.wav" in after


def test_an_item_the_model_refuses_is_a_row_with_its_reason_and_no_file(tmp_path):
    spec = parse_spec('model = "twang"\ncount = 2\nseed = 1\nduration_s = 0.1\n'
                      '[vary.youngs_modulus_pa]\nlist = [1e8, 3.2e9]\n[vary.length_m]\nlist = [1.0, 0.3]\n'
                      '[vary.thickness_m]\nlist = [0.0003, 0.003]\n[vary.density_kg_m3]\nlist = [22000, 1180]\n')
    refused, kept = run_batch(spec, tmp_path, features=False)
    assert "below 20 Hz" in refused["error"] and refused["file"] == refused["sha256"] == ""
    assert kept["error"] == "" and file_sha256(tmp_path / kept["file"]) == kept["sha256"]
    assert os.listdir(tmp_path / "audio") == ["00000001.wav"]
    with open(tmp_path / METADATA, newline="") as f:
        assert [m["file_name"] for m in csv.DictReader(f)] == ["audio/00000001.wav"]


def test_resume_refuses_a_folder_of_another_spec_and_touches_nothing(small_runs, tmp_path):
    _, one, _, _ = small_runs
    other = parse_spec(SMALL.replace("seed = 3", "seed = 4").replace("grid = [60, 200]", "grid = [60, 100]"),
                       source="other.toml")
    work = tmp_path / "w"
    for name, data in _tree(one).items():
        (work / name).parent.mkdir(parents=True, exist_ok=True)
        (work / name).write_bytes(data)
    with pytest.raises(BatchSpecError) as info:
        run_batch(other, work, resume=True, features=False)
    assert str(info.value) == (f"other.toml: cannot resume in {work}: it holds the batch of another spec (its seed, "
                               "vary differ); allowed: the same spec (its count may change), or a run without "
                               "--resume, which replaces that batch")
    assert _tree(work) == _tree(one)
    rows = run_batch(other, work, features=False)  # without --resume: replaced
    assert [r["seed"] for r in rows] == [str(it.seed) for it in make_items(other)]
    assert all(r["sha256"] == file_sha256(work / r["file"]) for r in rows)
    assert read_manifest(work / MANIFEST)[0]["sha256"] != read_manifest(one / MANIFEST)[0]["sha256"]


# -- the command --------------------------------------------------------------------------------

def test_the_batch_command_writes_the_same_files_as_the_library(small_runs, tmp_path):
    from click.testing import CliRunner

    from barsynth.cli import main

    spec_path = tmp_path / "small.toml"
    spec_path.write_text(SMALL)
    result = CliRunner().invoke(main, ["batch", str(spec_path), "-o", str(tmp_path / "out"), "--workers", "2"],
                                catch_exceptions=False)
    assert result.exit_code == 0 and "wrote 6 items" in result.output
    _, one, _, _ = small_runs
    assert _tree(tmp_path / "out") == _tree(one)


@pytest.mark.parametrize("text, words", [
    ('model = "twang"\ncount = 3\nseed = 1\n[vary.q]\ngrid = [1]\n', "vary.q.grid value 1 = 1"),
    ('model = "twang"\ncount = 3\n', "no seed"),
])
def test_a_bad_spec_exits_2_in_one_line_and_writes_nothing(tmp_path, text, words):
    from click.testing import CliRunner

    from barsynth.cli import main

    spec_path = tmp_path / "bad.toml"
    spec_path.write_text(text)
    result = CliRunner().invoke(main, ["batch", str(spec_path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("barsynth: error: ") and words in lines[0]
    assert not (tmp_path / "out").exists()


def _ignore_sigint():
    """As a shell starts a job in the background: SIGINT ignored (the command must still stop on it)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


@pytest.mark.parametrize("whom", ["group", "command"])
def test_ctrl_c_stops_the_pool_and_leaves_no_partial_file(tmp_path, whom):
    """The command interrupted mid-batch: status 130 in one line, no temporary file, and every
    item in the manifest has its file with its hash (what --resume trusts); every file written
    is in the manifest. ``whom``: a terminal's Ctrl-C (the command and its workers) or a
    SIGINT to the command alone (kill -INT; the workers' chunks were rendered to the end, then
    none of their items listed)."""
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    spec_path, out = tmp_path / "many.toml", tmp_path / "out"
    spec_path.write_text(SMALL.replace("count = 6", "count = 300"))
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"))
    proc = subprocess.Popen([sys.executable, "-m", "barsynth", "batch", str(spec_path), "-o", str(out),
                             "--workers", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env,
                            start_new_session=True, preexec_fn=_ignore_sigint)
    try:
        for _ in range(1200):  # until a few chunks of items are written (at most 60 s)
            if (out / "audio").is_dir() and len(os.listdir(out / "audio")) >= 50:
                break
            time.sleep(0.05)
        if whom == "group":
            os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the command and its workers
        else:
            os.kill(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130 and err.decode().strip() == "barsynth: interrupted"
    names = os.listdir(out / "audio")
    assert names and not [n for n in names if n.startswith(".")] and len(names) < 300
    rows = read_manifest(out / MANIFEST)
    assert rows and all(file_sha256(out / r["file"]) == r["sha256"] for r in rows.values())
    assert sorted(f"audio/{n}" for n in names) == sorted(r["file"] for r in rows.values())
