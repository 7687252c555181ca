"""Batch runs (spec 11.2, 11.4): refused draws redrawn and counted, the Parquet manifest typed
as the CSV one, resume only within one spec, an earlier batch's files replaced (and nobody
else's touched), progress on a terminal."""

from __future__ import annotations

import csv
import io
import os

import numpy as np
import pytest

from barsynth.batch import items as items_module
from barsynth.batch.items import designed_item, item_rng, make_items
from barsynth.batch.progress import BatchProgress
from barsynth.batch.run import MANIFEST, PARQUET, file_sha256, read_manifest, run_batch
from barsynth.batch.sampler import check_draw
from barsynth.batch.spec import parse_spec, spec_toml
from barsynth.errors import BatchSpecError, ParameterError
from barsynth.models import get_model

TUBES = """model = "banded"
preset = "concert-marimba-bar"
count = 6
seed = 2
duration_s = 0.3
format = "flac"
[vary.tube_mode]
random = [1, 24]
[vary.strike_position]
mutate = 0.2
"""
"""The marimba bar's tube must sit on one of its few modes: most tube_mode draws are refused."""


@pytest.fixture(scope="module")
def tubes(tmp_path_factory):
    spec = parse_spec(TUBES, source="tubes.toml")
    out = tmp_path_factory.mktemp("tubes")
    return spec, out, run_batch(spec, out, workers=2, spec_text=TUBES)


def test_refused_draws_are_redrawn_and_counted_in_the_manifest(tubes):
    spec, out, rows = tubes
    model = get_model("banded")
    assert sum(int(r["rejected"]) for r in rows) >= 6  # measured: 1 to 22 per item
    for row, item in zip(rows, make_items(spec)):
        assert row["error"] == "" and int(row["rejected"]) == item.rejected
        assert int(row["tube_mode"]) == item.parameters["tube_mode"] <= 4
        assert file_sha256(out / row["file"]) == row["sha256"]
    # replayed by hand: item 1's stream gives `rejected` sets the model refuses, then the one kept
    item = make_items(spec, start=1, stop=2)[0]
    rng, base = item_rng(spec.seed, 1), model.preset("concert-marimba-bar")
    for _ in range(item.rejected):
        values = {v.name: items_module.draw_value(model.table[v.name], v, getattr(base, v.name), rng)
                  for v in spec.vary}
        with pytest.raises(ParameterError):
            check_draw(model, {**model.table.as_dict(base), **values}, sample_rate=48000)
    kept = {v.name: items_module.draw_value(model.table[v.name], v, getattr(base, v.name), rng) for v in spec.vary}
    assert kept == item.values


def test_the_parquet_manifest_is_the_csv_one_typed(tubes):
    import pyarrow.parquet as pq

    spec, out, rows = tubes
    table = pq.read_table(out / PARQUET)
    assert table.column_names == list(rows[0])
    types = {f.name: str(f.type) for f in table.schema}
    assert types["id"] == types["seed"] == types["rejected"] == types["tube_mode"] == "int64"
    assert types["f0_hz"] == types["strike_position"] == "double" and types["tube"] == "string"
    assert types["mode_ratios"].startswith("list<") and types["mode_ratios"].endswith(": double>")
    records = table.to_pylist()
    for record, row in zip(records, rows):
        assert record["sha256"] == row["sha256"] and record["file"] == row["file"]
        assert record["f0_hz"] == float(row["f0_hz"]) and record["seed"] == int(row["seed"])
        assert record["mode_ratios"] == [float(x) for x in row["mode_ratios"].split(",")]
        assert record["error"] is None and 100 < record["f0_hz"] < 2000


def test_every_draw_refused_is_a_row_with_its_reason(tmp_path, monkeypatch):
    monkeypatch.setattr(items_module, "MAX_ATTEMPTS", 5)
    spec = parse_spec('model = "ruler"\ncount = 1\nseed = 1\nduration_s = 0.1\n'
                      '[vary.overhang_m]\nrandom = [0.9, 0.95]\n', source="r.toml")
    item, voice = designed_item(spec, 0)
    assert voice is None and item.rejected == 5 and "overhang_m" in item.error and "\n" not in item.error
    (row,) = run_batch(spec, tmp_path, workers=1, features=False)  # (in a worker: 1000 draws)
    assert row["file"] == row["sha256"] == "" and row["rejected"] == "1000"
    assert row["error"].startswith("1000 drawn settings were all refused, the last: parameter overhang_m")
    assert os.listdir(tmp_path / "audio") == []


def test_resume_refuses_another_spec_and_a_new_run_replaces_the_old_items(tubes, tmp_path):
    spec, out, rows = tubes
    work = tmp_path / "w"
    (work / "audio").mkdir(parents=True)
    for name in os.listdir(out):
        if name != "audio":
            (work / name).write_bytes((out / name).read_bytes())
    for name in os.listdir(out / "audio"):
        (work / "audio" / name).write_bytes((out / "audio" / name).read_bytes())
    (work / "audio" / "mine.wav").write_bytes(b"not ours")  # a user's file: never touched
    (work / "audio" / "notes.txt").write_text("mine")
    fewer = parse_spec(TUBES.replace("count = 6", "count = 4"), source="tubes.toml")
    calls = []
    again = run_batch(fewer, work, workers=1, resume=True, progress=lambda d, t: calls.append((d, t)))
    assert calls[0] == (4, 4) and again == rows[:4]  # the same spec, fewer items: all kept
    assert sorted(os.listdir(work / "audio")) == [f"0000000{i}.flac" for i in range(4)] + ["mine.wav", "notes.txt"]
    other = parse_spec(TUBES.replace("seed = 2", "seed = 3"), source="tubes.toml")
    calls.clear()
    with pytest.raises(BatchSpecError, match="cannot resume in .* another spec"):
        run_batch(other, work, workers=1, resume=True, features=False)
    rows3 = run_batch(other, work, workers=1, features=False, progress=lambda d, t: calls.append((d, t)))
    assert calls[0] == (0, 6) and [r["sha256"] for r in rows3] != [r["sha256"] for r in rows]
    assert (work / "audio" / "mine.wav").read_bytes() == b"not ours"
    assert parse_spec((work / "spec.toml").read_text()) == parse_spec(spec_toml(other))
    assert len(read_manifest(work / MANIFEST)) == 6


def test_a_folder_that_held_no_batch_keeps_files_named_like_items(tmp_path):
    (tmp_path / "audio").mkdir()
    (tmp_path / "audio" / "20240101.wav").write_bytes(b"a recording of mine")
    (tmp_path / "audio" / "00000007.flac").write_bytes(b"another")
    spec = parse_spec('model = "twang"\ncount = 1\nseed = 1\nduration_s = 0.05\n', source="s.toml")
    (row,) = run_batch(spec, tmp_path, workers=1, features=False)
    assert sorted(os.listdir(tmp_path / "audio")) == ["00000000.wav", "00000007.flac", "20240101.wav"]
    assert (tmp_path / "audio" / "20240101.wav").read_bytes() == b"a recording of mine"
    assert file_sha256(tmp_path / row["file"]) == row["sha256"]


def test_the_spec_copy_reads_back_to_the_same_spec():
    spec = parse_spec(TUBES, source="tubes.toml")
    assert parse_spec(spec_toml(spec), source="tubes.toml") == spec


def test_progress_on_a_terminal_shows_items_rate_and_time_left():
    stream = io.StringIO()
    with BatchProgress(stream, terminal=True) as progress:
        progress(2, 10)  # two kept by a resume
        for done in range(3, 11):
            progress(done, 10)
    text = stream.getvalue()
    assert "10/10" in text and "items/s" in text and "left" in text
    quiet = io.StringIO()
    with BatchProgress(quiet) as progress:  # not a terminal: nothing
        progress(1, 2)
    assert quiet.getvalue() == ""


def test_the_command_says_how_many_draws_were_refused(tmp_path):
    from click.testing import CliRunner

    from barsynth.cli import main

    spec_path = tmp_path / "tubes.toml"
    spec_path.write_text(TUBES.replace("count = 6", "count = 2"))
    result = CliRunner().invoke(main, ["batch", str(spec_path), "-o", str(tmp_path / "out"), "--workers", "1"],
                                catch_exceptions=False)
    rows = read_manifest(tmp_path / "out" / MANIFEST)
    redrawn = sum(int(r["rejected"]) for r in rows.values())
    assert result.exit_code == 0 and f"wrote 2 items to {tmp_path / 'out'} ({redrawn} refused draws redrawn)" \
        in result.output and redrawn > 0
    with open(tmp_path / "out" / "metadata.csv", newline="") as f:
        assert [m["file_name"] for m in csv.DictReader(f)] == ["audio/00000000.flac", "audio/00000001.flac"]
    assert np.all([os.path.getsize(tmp_path / "out" / r["file"]) > 1000 for r in rows.values()])


def test_the_docs_spec_reads_and_its_first_items_are_as_described():
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "batch.md").read_text()
    block = text.split("<!-- batch-spec:begin -->")[1].split("<!-- batch-spec:end -->")[0]
    spec = parse_spec(block.split("```toml")[1].split("```")[0], source="docs/batch.md")
    assert spec.count == 1000 and spec.format == "flac" and spec.duration_s == "auto"
    first = make_items(spec, stop=8)
    assert [it.values["q"] for it in first] == [60.0, 100.0, 200.0, 400.0] * 2
    assert [it.values["gain_mapping"] for it in first] == ["linear", "log"] * 4
    assert all(0.15 <= it.values["length_m"] <= 0.4 for it in first)
