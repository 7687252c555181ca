"""The command line: every form, real WAV files, and bad input (one line, exit 2, no file)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile
from click.testing import CliRunner

from barsynth.cli import main
from barsynth.models import get_model, model_names
from barsynth.physics import bar_frequencies, lambdas

ROOT = Path(__file__).resolve().parents[1]


def run(*args: str):
    result = CliRunner().invoke(main, list(args), catch_exceptions=False)
    return result


def assert_one_line_error(result, *needles: str) -> None:
    assert result.exit_code == 2, result.output
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 or lines[0].startswith("Usage:"), result.stderr
    text = result.stderr.lower()
    for needle in needles:
        assert needle.lower() in text, (needle, result.stderr)


# -- modes ----------------------------------------------------------------------------
def test_modes_json_from_material_and_from_constants():
    r = run("modes", "--material", "acrylic", "--length", "0.3", "--thickness", "0.003",
            "--bc", "free-free", "--count", "8", "--json")
    assert r.exit_code == 0
    data = json.loads(r.stdout)
    expected = bar_frequencies(youngs_modulus_pa=3.2e9, density_kg_m3=1180.0, length_m=0.3,
                               thickness_m=0.003, bc="free-free", count=8)
    assert data["frequencies_hz"] == pytest.approx(expected, rel=1e-12)
    assert data["lambdas"] == pytest.approx(lambdas("free-free", 8), rel=1e-14)
    assert 55 < data["frequencies_hz"][0] < 57  # the spec's worked example: ~56 Hz
    r2 = run("modes", "--youngs-modulus", "3.2e9", "--density", "1180", "--length", "0.15",
             "--thickness", "0.003", "--bc", "clamped-free", "--json")
    assert 34 < json.loads(r2.stdout)["frequencies_hz"][0] < 36  # ~35 Hz


@pytest.mark.parametrize("bc", ["free-free", "clamped-free", "clamped-clamped", "pinned-pinned", "clamped-pinned"])
def test_modes_every_boundary_condition_text(bc):
    r = run("modes", "--material", "steel", "--length", "0.5", "--thickness", "0.01", "--bc", bc)
    assert r.exit_code == 0 and bc in r.stdout


@pytest.mark.parametrize("args,needle", [
    (["--length", "0.3", "--thickness", "0.003", "--bc", "free-free"], "--material"),
    (["--material", "unobtainium", "--length", "0.3", "--thickness", "0.003", "--bc", "free-free"], "unobtainium"),
    (["--material", "steel", "--youngs-modulus", "1e9", "--length", "0.3", "--thickness", "0.003",
      "--bc", "free-free"], "either"),
    (["--material", "steel", "--length", "-0.3", "--thickness", "0.003", "--bc", "free-free"], "length_m"),
    (["--material", "steel", "--length", "0.3", "--thickness", "0.003", "--bc", "free-free",
      "--count", "0"], "count"),
    (["--material", "steel", "--length", "0.3", "--thickness", "0.003", "--bc", "loose"], "loose"),
])
def test_modes_bad_input(args, needle):
    assert_one_line_error(run("modes", *args), needle)


# -- params, describe, presets --------------------------------------------------------
def test_params_json_lists_every_parameter_with_its_fields():
    data = json.loads(run("params", "twang", "--json").stdout)
    names = [p["name"] for p in data]
    assert names == list(get_model("twang").table.names)
    for p in data:
        assert {"name", "unit", "min", "max", "default", "doc"} <= set(p)
    q = next(p for p in data if p["name"] == "q")
    assert (q["min"], q["max"], q["default"]) == (50.0, 800.0, 100.0)


def test_params_text_and_unknown_model():
    assert "length_m" in run("params", "twang").stdout
    assert_one_line_error(run("params", "kazoo"), "kazoo", "twang")


def test_describe_json_has_parameters_and_modes():
    r = run("describe", "twang", "--preset", "steel-30cm", "--set", "q=300", "--sample-rate", "44100", "--json")
    data = json.loads(r.stdout)
    assert data["parameters"]["q"] == 300.0
    assert data["parameters"]["youngs_modulus_pa"] == 200e9
    assert len(data["modes"]) == 18
    for m in data["modes"]:
        assert set(m) == {"group", "frequency_hz", "gain", "t60_s"}
        assert 0 < m["frequency_hz"] < 22050
    groups = {m["group"] for m in data["modes"]}
    assert groups == {"full-cantilever", "short-cantilever", "free-bar"}


@pytest.mark.parametrize("args,needles", [
    (["--set", "q=5"], ["q", "5", "50", "800"]),
    (["--set", "length_m=2"], ["length_m", "0.05", "1", " m"]),
    (["--set", "nonsense=1"], ["nonsense"]),
    (["--set", "q"], ["name=value"]),
    (["--preset", "rubber"], ["rubber", "plastic-30cm"]),
    (["--sample-rate", "1000"], ["sample_rate", "hz"]),
])
def test_describe_bad_input(args, needles):
    assert_one_line_error(run("describe", "twang", *args), *needles)


def test_presets_lists_the_rulers():
    out = run("presets", "twang").stdout
    for name in ("plastic-30cm", "wooden-30cm", "steel-30cm"):
        assert name in out
    assert "twang" in run("presets").stdout
    assert "acrylic" in run("materials").stdout


# -- render and analyze -----------------------------------------------------------------
def test_render_writes_a_real_wav_and_plot(tmp_path):
    out = tmp_path / "twang.wav"
    png = tmp_path / "twang.png"
    r = run("render", "twang", "--preset", "plastic-30cm", "--duration", "1.5", "--sample-rate", "44100",
            "--seed", "4", "--plot", str(png), "-o", str(out))
    assert r.exit_code == 0, r.output
    data, rate = soundfile.read(out)
    assert rate == 44100 and data.shape == (int(1.5 * 44100),)
    assert np.max(np.abs(data)) == pytest.approx(10 ** (-1 / 20), abs=1e-4)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    same = tmp_path / "again.wav"
    run("render", "twang", "--preset", "plastic-30cm", "--duration", "1.5", "--sample-rate", "44100",
        "--seed", "4", "-o", str(same))
    assert np.array_equal(soundfile.read(same)[0], data)
    assert list(tmp_path.glob(".barsynth-*")) == []


@pytest.mark.parametrize("suffix,subtype", [(".flac", "PCM_16"), (".wav", "FLOAT")])
def test_render_other_formats(tmp_path, suffix, subtype):
    out = tmp_path / ("x" + suffix)
    assert run("render", "twang", "--duration", "0.2", "--subtype", subtype, "-o", str(out)).exit_code == 0
    assert soundfile.info(out).frames == int(0.2 * 48000)


@pytest.mark.parametrize("args,needles", [
    (["--set", "q=10"], ["q", "50 to 800"]),
    (["--set", "thickness_m=abc"], ["thickness_m", "abc"]),
    (["--duration", "0"], ["duration_s"]),
    (["--duration", "1e9"], ["duration_s", "600"]),
    (["--sample-rate", "-48000"], ["sample_rate"]),
    (["--sample-rate", "44100.5"], ["sample_rate", "whole"]),
    (["--seed", "-1"], ["seed"]),
    (["--preset", "nope"], ["nope"]),
    # barsynth's one line, not click's "Invalid value for ...", and non-finite numbers said as such
    (["--seed", "abc"], ["parameter seed = 'abc' is not a whole number", "allowed: >= 0"]),
    (["--seed", "1.5"], ["parameter seed = 1.5 is not a whole number"]),
    (["--subtype", "PCM_8"], ["parameter subtype = 'PCM_8' is not a known choice",
                              "allowed: one of PCM_16, PCM_24, FLOAT"]),
    (["--sample-rate", "abc"], ["parameter sample_rate = 'abc' is not a number", "8000 to 384000 Hz"]),
    (["--set", "q=nan"], ["parameter q = 'nan' is not a finite number", "allowed: 50 to 800"]),
    (["--set", "q=inf"], ["parameter q = 'inf' is not a finite number", "allowed: 50 to 800"]),
    (["--duration", "nan"], ["parameter duration_s = 'nan' is not a finite number", "allowed: auto, or", " s"]),
    (["--duration", "-inf"], ["parameter duration_s = '-inf' is not a finite number"]),
    (["--sample-rate", "inf"], ["parameter sample_rate = 'inf' is not a finite number", "Hz"]),
])
def test_render_bad_input_writes_nothing_and_keeps_an_existing_file(tmp_path, args, needles):
    out = tmp_path / "keep.wav"
    out.write_bytes(b"precious")
    r = run("render", "twang", *args, "-o", str(out))
    assert_one_line_error(r, *needles)
    assert "invalid value" not in r.stderr.lower()
    if args[-1].endswith(("nan", "inf")):
        assert "out of range" not in r.stderr
    assert out.read_bytes() == b"precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.wav"]


@pytest.mark.parametrize("args,needles", [
    (["-o", ".wav"], ["parameter output = .wav has no extension", "hidden file",
                      "allowed: a name ending in .wav, .flac or .ogg"]),
    (["-o", "/dev/null"], ["parameter output = /dev/null is a device", "allowed: a regular file or a new name"]),
    (["-o", "SOMEDIR"], ["parameter output = SOMEDIR is a folder", "allowed: a regular file or a new name"]),
    (["--plot", "SOMEDIR", "-o", "x.wav"], ["parameter plot = SOMEDIR is a folder", "allowed: a regular file"]),
    (["--plot", ".png", "-o", "x.wav"], ["parameter plot = .png has no extension", "allowed: a name ending in .png"]),
])
def test_render_names_what_is_wrong_with_an_output_path(tmp_path, monkeypatch, args, needles):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "SOMEDIR").mkdir()
    r = run("render", "twang", "--duration", "0.1", *args)
    assert_one_line_error(r, *needles)
    assert "invalid value" not in r.stderr.lower() and "unsupported" not in r.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["SOMEDIR"] and not any((tmp_path / "SOMEDIR").iterdir())


@pytest.mark.parametrize("args,needles", [
    (["modes", "--material", "steel", "--length", "1", "--thickness", "0.01", "--bc", "nope"],
     ["parameter bc = 'nope' is not a known choice", "allowed: one of free-free, clamped-free"]),
    (["modes", "--material", "steel", "--length", "1", "--thickness", "0.01", "--bc", "free-free", "--count", "abc"],
     ["parameter count = 'abc' is not a whole number", "allowed: 1 to 1000 modes"]),
    (["modes", "--material", "steel", "--length", "1", "--thickness", "0.01", "--bc", "free-free", "--count", "2.5"],
     ["parameter count = 2.5 is not a whole number", "allowed: 1 to 1000 modes"]),
    (["modes", "--material", "steel", "--length", "abc", "--thickness", "0.01", "--bc", "free-free"],
     ["parameter length_m = 'abc' is not a number", "allowed: > 0 m"]),
    (["modes", "--material", "steel", "--length", "nan", "--thickness", "0.01", "--bc", "free-free"],
     ["parameter length_m = 'nan' is not a finite number", "allowed: > 0 m"]),
    (["analyze", "--max-partials", "abc", "x.wav"], ["parameter max_partials = 'abc' is not a whole number",
                                                     "allowed: 1 to 500"]),
    (["bow-map", "banded", "--velocities", "many", "-o", "m.png"],
     ["parameter velocities = 'many' is not a whole number", "allowed: 2 to 200 values"]),
    (["bow-map", "banded", "-o", "SOMEDIR"], ["parameter output = SOMEDIR is a folder"]),
    (["tune-undercut", "--material", "steel", "--length", "0.3", "--thickness", "0.01", "--profile", "wavy"],
     ["parameter profile = 'wavy' is not a known choice", "allowed: one of parabolic, circular"]),
    (["tune-undercut", "--material", "steel", "--length", "0.3", "--thickness", "0.01", "--target-ratio", "x"],
     ["parameter target_ratio = 'x' is not a number", "allowed: >= 1"]),
    (["studio", "--port", "http"], ["parameter port = 'http' is not a whole number", "allowed: 0 to 65535"]),
    (["studio", "--port", "70000"], ["parameter port = 70000 is out of range", "allowed: 0 to 65535"]),
    (["listen", "report", "x.db", "--csv", "afile"], ["parameter csv = afile is a file", "allowed: a folder"]),
])
def test_bad_option_values_are_barsynths_one_line_not_clicks(tmp_path, monkeypatch, args, needles):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "SOMEDIR").mkdir()
    (tmp_path / "afile").write_text("")
    r = run(*args)
    assert_one_line_error(r, *needles)
    assert "invalid value" not in r.stderr.lower()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["SOMEDIR", "afile"]


def test_render_bad_paths(tmp_path):
    assert_one_line_error(run("render", "twang", "-o", str(tmp_path / "x.mp3")), ".mp3")
    assert_one_line_error(run("render", "twang", "-o", str(tmp_path / "no" / "x.wav")), "does not exist")
    assert_one_line_error(run("render", "twang", "--plot", str(tmp_path / "p.jpg"), "-o",
                              str(tmp_path / "x.wav")), ".png")
    assert not (tmp_path / "x.wav").exists()
    assert_one_line_error(run("render", "kazoo", "-o", str(tmp_path / "x.wav")), "kazoo")


def test_analyze_finds_the_rendered_partials(tmp_path):
    out = tmp_path / "steel.wav"
    args = ["--preset", "steel-30cm", "--set", "free_bar_gain=0", "--set", "short_cantilever_gain=0"]
    run("render", "twang", *args, "--duration", "3", "--subtype", "FLOAT", "-o", str(out))
    modes = json.loads(run("describe", "twang", *args, "--json").stdout)["modes"]
    png = tmp_path / "a.png"
    r = run("analyze", str(out), "--json", "--plot", str(png))
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout)
    partials, below = data["partials"], data["below_f0"]
    assert png.exists()
    assert data["file"] == str(out) and data["sample_rate"] == 48000 and data["duration_s"] == 3.0
    for p in partials + below:
        assert set(p) >= {"frequency_hz", "level_db", "t60_s", "ratio", "decay"}
        assert p["decay"]["range_db"] > 0 and p["decay"]["rms_db"] < 1.0
    found = [p["frequency_hz"] for p in partials + below]
    for m in modes:
        if m["gain"] > 0.05:
            nearest = min(found, key=lambda f: abs(math.log2(f / m["frequency_hz"])))
            assert abs(1200 * math.log2(nearest / m["frequency_hz"])) < 1.0, (m, nearest)
    # ratios are to f0, the first of the partials; what lies below it is reported apart
    assert data["f0_hz"] == partials[0]["frequency_hz"] and partials[0]["ratio"] == 1.0
    assert all(p["frequency_hz"] < data["f0_hz"] and p["ratio"] < 1.0 for p in below)
    assert [p["ratio"] for p in partials] == pytest.approx([p["frequency_hz"] / data["f0_hz"] for p in partials])
    text = run("analyze", str(out)).stdout
    assert "f0:" in text and "ratio" in text and "T60" in text and "attack:" in text


@pytest.mark.parametrize("kind", ["silence", "noise", "short"])
def test_analyze_reports_a_file_without_a_note(tmp_path, kind):
    rng = np.random.default_rng(0)
    samples = {"silence": np.zeros(48000), "noise": 0.1 * rng.standard_normal(48000),
               "short": 0.1 * rng.standard_normal(20)}[kind]
    wav = tmp_path / f"{kind}.wav"
    soundfile.write(wav, samples, 48000, subtype="FLOAT")
    r = run("analyze", str(wav))
    assert r.exit_code == 0, r.output
    assert "f0: none" in r.stdout
    data = json.loads(run("analyze", str(wav), "--json").stdout)
    assert data["f0_hz"] is None and data["partials"] == [] and data["notes"]


def test_analyze_with_a_nominal_pitch(tmp_path):
    t = np.arange(48000) / 48000
    decay = np.exp(-t * math.log(1000) / 1.0)
    samples = decay * (0.01 * np.cos(2 * np.pi * 500 * t) + 0.5 * np.cos(2 * np.pi * 1378 * t))
    wav = tmp_path / "bar.wav"
    soundfile.write(wav, samples, 48000, subtype="FLOAT")
    assert json.loads(run("analyze", str(wav), "--json").stdout)["f0_hz"] == pytest.approx(1378, rel=1e-4)
    nominal = json.loads(run("analyze", str(wav), "--json", "--nominal-hz", "494").stdout)
    assert nominal["f0_hz"] == pytest.approx(500, rel=1e-4)
    assert nominal["partials"][1]["ratio"] == pytest.approx(2.756, rel=1e-4)
    assert_one_line_error(run("analyze", str(wav), "--nominal-hz", "30000"), "nominal_hz")
    assert_one_line_error(run("analyze", str(wav), "--nominal-hz", "-5"), "nominal_hz")


def test_analyze_bad_files(tmp_path):
    assert_one_line_error(run("analyze", str(tmp_path / "missing.wav")), "missing.wav")
    fake = tmp_path / "fake.wav"
    fake.write_text("not audio at all")
    assert_one_line_error(run("analyze", str(fake)), "fake.wav")


def test_the_installed_command_exits_2_with_one_line(tmp_path):
    exe = Path(sys.executable).with_name("barsynth")
    if not exe.exists():
        pytest.skip("the barsynth script is not installed next to this Python")
    out = tmp_path / "x.wav"
    proc = subprocess.run([str(exe), "render", "twang", "--set", "q=9000", "-o", str(out)],
                          capture_output=True, text=True, env=dict(os.environ))
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "q" in proc.stderr
    assert not out.exists()
    proc = subprocess.run([str(exe), "render", "twang", "--duration", "0.3", "-o", str(out)],
                          capture_output=True, text=True)
    assert proc.returncode == 0 and soundfile.info(out).samplerate == 48000


@pytest.mark.parametrize("model", model_names())
def test_docs_parameter_table_is_generated_from_the_table(model):
    doc = (ROOT / "docs" / f"{model}.md").read_text(encoding="utf-8")
    inside = doc.split("<!-- parameters:begin -->\n", 1)[1].split("<!-- parameters:end -->", 1)[0]
    assert inside == get_model(model).table.to_markdown()


def test_farnell_through_the_cli(tmp_path):
    out = tmp_path / "anchor.wav"
    assert run("render", "farnell", "--preset", "anchor", "--duration", "0.5", "-o", str(out)).exit_code == 0
    assert soundfile.info(out).frames == 24000
    data = json.loads(run("describe", "farnell", "--set", "frequency_hz=300", "--json").stdout)
    assert data["parameters"]["frequency_hz"] == 300.0
    assert {m["group"] for m in data["modes"]} == {"clamped", "free-bar"}
    assert [p["name"] for p in json.loads(run("params", "farnell", "--json").stdout)] == \
        ["frequency_hz", "vibrato_depth_hz", "anchor", "level_db"]
    listed = run("presets", "farnell").stdout
    assert "anchor" in listed and "patch-default" in listed
    assert_one_line_error(run("render", "farnell", "--set", "frequency_hz=900", "-o", str(tmp_path / "x.wav")),
                          "frequency_hz", "20 to 800 Hz")


# -- failures at write time, formats, extremes --------------------------------------------
@pytest.mark.parametrize("args,needles", [
    (["--sample-rate", "256000", "-o", "x.ogg"], ["sample_rate", "192000", ".ogg"]),
    (["--subtype", "FLOAT", "-o", "x.flac"], ["subtype", "flac"]),
    (["--duration", "0.00001", "-o", "x.wav"], ["duration_s", "one sample"]),
    (["--set", "youngs_modulus_pa=4e11", "--set", "density_kg_m3=100", "--set", "length_m=0.05",
      "--set", "thickness_m=0.02", "--sample-rate", "8000", "-o", "x.wav"], ["nyquist"]),
])
def test_render_refuses_what_it_cannot_write_well(tmp_path, monkeypatch, args, needles):
    monkeypatch.chdir(tmp_path)
    assert_one_line_error(run("render", "twang", "--duration", "0.3", *args) if "--duration" not in args
                          else run("render", "twang", *args), *needles)
    assert list(tmp_path.iterdir()) == []


def test_a_failing_plot_leaves_no_audio_file_either(tmp_path, monkeypatch):
    import barsynth.analysis

    def full_disk(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(barsynth.analysis, "plot_sound", full_disk)
    r = run("render", "twang", "--duration", "0.2", "--plot", str(tmp_path / "p.png"), "-o", str(tmp_path / "a.wav"))
    assert_one_line_error(r, "no space left", "nothing written")
    assert list(tmp_path.iterdir()) == []


def test_unwritable_places_are_one_line_errors(tmp_path):
    assert_one_line_error(run("render", "twang", "--duration", "0.1", "-o", "/proc/barsynth-test.wav"),
                          "could not write")


def test_written_files_get_the_usual_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        out = tmp_path / "m.wav"
        png = tmp_path / "m.png"
        assert run("render", "twang", "--duration", "0.2", "--plot", str(png), "-o", str(out)).exit_code == 0
    finally:
        os.umask(old)
    assert out.stat().st_mode & 0o777 == 0o644
    assert png.stat().st_mode & 0o777 == 0o644


@pytest.mark.parametrize("length,thickness", [("1e300", "1e-300"), ("1e150", "1e-150"), ("1e-300", "1e300")])
def test_modes_refuses_overflowing_bars(length, thickness):
    r = run("modes", "--material", "steel", "--bc", "free-free", "--length", length,
            "--thickness", thickness, "--json")
    assert_one_line_error(r, "length_m", "thickness_m", "finite")


def test_ogg_render_at_its_highest_rate(tmp_path):
    out = tmp_path / "hi.ogg"
    assert run("render", "twang", "--duration", "0.2", "--sample-rate", "192000", "-o", str(out)).exit_code == 0
    assert soundfile.info(out).samplerate == 192000


@pytest.mark.parametrize("args", [
    ["modes", "--count", "abc", "--material", "steel", "--length", "1", "--thickness", "0.01", "--bc", "free-free"],
    ["render", "twang"],
    ["render"],
    ["no-such-command"],
    ["analyze", "--max-partials", "1e309", "x.wav"],
])
def test_usage_errors_are_one_line_too(args):
    r = run(*args)
    assert r.exit_code == 2
    assert len(r.stderr.strip().splitlines()) == 1 and r.stderr.startswith("barsynth: error:")


def test_help_and_version_still_exit_0():
    assert run("--help").exit_code == 0
    assert run("render", "--help").exit_code == 0
    assert "barsynth" in run("--version").stdout


def test_analyze_refuses_a_fifo_and_a_very_low_rate(tmp_path):
    fifo = tmp_path / "pipe.wav"
    os.mkfifo(fifo)
    assert_one_line_error(run("analyze", str(fifo)), "not a regular file")
    low = tmp_path / "low.wav"
    soundfile.write(low, np.zeros(10), 1)
    assert_one_line_error(run("analyze", str(low)), "low.wav", "sample rate")


def test_output_through_a_symlink_keeps_the_link_and_the_mode(tmp_path):
    target = tmp_path / "real.wav"
    target.write_bytes(b"old")
    os.chmod(target, 0o640)
    link = tmp_path / "link.wav"
    link.symlink_to(target)
    assert run("render", "twang", "--duration", "0.1", "-o", str(link)).exit_code == 0
    assert link.is_symlink()
    assert soundfile.info(target).frames == 4800
    assert target.stat().st_mode & 0o777 == 0o640


def test_empty_preset_name_is_refused(tmp_path):
    assert_one_line_error(run("render", "twang", "-p", "", "-o", str(tmp_path / "x.wav")), "preset")


# -- banded waveguides and the bow map ---------------------------------------------------
@pytest.mark.parametrize("excitation", ["strike", "bow", "pluck"])
def test_banded_renders_every_excitation_at_the_set_pitch(tmp_path, excitation):
    out = tmp_path / f"{excitation}.wav"
    r = run("render", "banded", "--preset", "marimba", "--set", "frequency_hz=330", "--set",
            f"excitation={excitation}", "--duration", "1.5", "-o", str(out))
    assert r.exit_code == 0, r.output
    x, rate = soundfile.read(out)
    assert rate == 48000 and 0.85 < np.max(np.abs(x)) <= 0.9  # peak-normalised to -1 dBFS
    segment = x[int(0.3 * rate):int(1.3 * rate)]
    spectrum = np.abs(np.fft.rfft(segment * np.hanning(segment.size)))
    assert np.fft.rfftfreq(segment.size, 1 / rate)[np.argmax(spectrum)] == pytest.approx(330.0, abs=2.0)


def test_banded_params_describe_and_presets():
    names = [p["name"] for p in json.loads(run("params", "banded", "--json").output)]
    assert {"excitation", "bow_velocity_m_s", "bow_force_n", "bow_position", "mode_ratios"} <= set(names)
    d = json.loads(run("describe", "banded", "--preset", "xylophone", "--set", "frequency_hz=440", "--json").output)
    assert [round(m["frequency_hz"]) for m in d["modes"]] == [440, 1320, 2640]
    listed = run("presets", "banded").output
    assert all(name in listed for name in ("uniform-bar", "marimba", "xylophone", "vibraphone", "glass", "bowl"))


def test_bow_map_draws_the_region_and_prints_its_limits(tmp_path):
    out = tmp_path / "map.png"
    r = run("bow-map", "banded", "--preset", "uniform-bar", "--velocities", "12", "--forces", "3",
            "--duration", "1.5", "--json", "-o", str(out))
    assert r.exit_code == 0, r.output
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    found = json.loads(r.output)
    limits = found["velocity_limits"]
    assert len(limits) >= 2
    assert limits[-1]["least_velocity_m_s"] > limits[0]["least_velocity_m_s"]
    assert limits[-1]["greatest_velocity_m_s"] > limits[0]["greatest_velocity_m_s"]
    text = run("bow-map", "banded", "--velocities", "6", "--forces", "2", "--duration", "1", "-o", str(out))
    assert "least velocity (m/s)" in text.output and "wrote" in text.output


@pytest.mark.parametrize("args,needles", [
    (["twang"], ["model 'twang' cannot be bowed"]),
    (["banded", "--duration", "0.2"], ["duration_s = 0.2", "1 to 30 s"]),
    (["banded", "--duration", "soon"], ["duration = 'soon'"]),
    (["banded", "--forces", "1"], ["forces = 1", "2 to 200"]),
    (["banded", "--set", "bow_force_n=50"], ["bow_force_n", "0.01 to 20 N"]),
    (["nosuchmodel"], ["nosuchmodel"]),
])
def test_bow_map_bad_input_writes_nothing(tmp_path, args, needles):
    out = tmp_path / "map.png"
    r = run("bow-map", *args, "-o", str(out))
    assert_one_line_error(r, *needles)
    assert not out.exists()
    assert_one_line_error(run("bow-map", "banded", "-o", str(tmp_path / "map.jpg")), "ending in .png")


# -- the finite-difference bar and the undercut tuner ---------------------------------------
def test_fd_renders_describes_with_errors_and_lists_presets(tmp_path):
    out = tmp_path / "marimba.wav"
    r = run("render", "fd", "--preset", "marimba-bar", "--duration", "1", "-o", str(out))
    assert r.exit_code == 0, r.output
    x, rate = soundfile.read(out)
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    assert np.fft.rfftfreq(x.size, 1 / rate)[np.argmax(spectrum)] == pytest.approx(262.7, abs=1.5)
    d = json.loads(run("describe", "fd", "--preset", "marimba-bar", "--json").output)
    assert d["modes"][1]["frequency_hz"] / d["modes"][0]["frequency_hz"] == pytest.approx(4.0, rel=0.003)
    assert all(m["error_cents"] < 0 for m in d["modes"])
    assert "error (cents)" in run("describe", "fd").output
    listed = run("presets", "fd").output
    assert all(name in listed for name in ("uniform-bar", "marimba-bar", "xylophone-bar", "tapered-bar", "ruler"))


def test_tune_undercut_finds_the_depth_and_says_how_to_hear_it():
    r = run("tune-undercut", "--material", "rosewood", "--length", "0.38", "--thickness", "0.02", "--json")
    assert r.exit_code == 0, r.output
    found = json.loads(r.output)
    assert found["ratios"][1] == pytest.approx(4.0, abs=1e-6) and 0.5 < found["undercut_depth"] < 0.7
    assert found["fd_parameters"]["profile"] == "parabolic"
    text = run("tune-undercut", "--material", "rosewood", "--length", "0.25", "--thickness", "0.02",
               "--target-ratio", "3", "--profile", "circular", "--undercut-width", "0.5").output
    assert "circular undercut over 0.5 of the length" in text and "barsynth render fd --set" in text


@pytest.mark.parametrize("args,needles", [
    (["--material", "rosewood", "--length", "0.38", "--thickness", "0.02", "--target-ratio", "1.5"],
     ["target_ratio = 1.5 cannot be reached", "allowed: 2.7565"]),
    (["--material", "rosewood", "--length", "9", "--thickness", "0.02"], ["length_m", "0.02 to 3 m"]),
    (["--length", "0.38", "--thickness", "0.02"], ["give --material name"]),
    (["--material", "rosewood", "--length", "0.38", "--thickness", "0.02", "--undercut-width", "0"],
     ["undercut_width = 0.0", "0.05 to 1"]),
])
def test_tune_undercut_bad_input(args, needles):
    assert_one_line_error(run("tune-undercut", *args), *needles)


# -- the command line as users expect it: auto duration, Ctrl-C, progress, warnings, -o - ---------
def _every_preset():
    from barsynth.presets import preset_names

    return [(m, p) for m in model_names() for p in preset_names(m)]


def _db(ratio: float) -> float:
    return 20.0 * math.log10(ratio) if ratio > 0 else -math.inf


@pytest.mark.parametrize("model_name,preset", _every_preset())
def test_auto_duration_ends_every_preset_quietly_and_without_a_click(model_name, preset):
    import warnings

    from barsynth.models.rendering import AUTO_FADE_S, AUTO_MAX_S, NeverQuietWarning
    from barsynth.presets import preset_parameters

    rate = 48000
    model = get_model(model_name)
    resolved = model.table.resolve(preset_parameters(model_name, preset))
    with warnings.catch_warnings():
        warnings.simplefilter("error", NeverQuietWarning)  # every preset falls quiet before the cap
        x = model.render(resolved, duration_s="auto", sample_rate=rate, normalize=False, dtype=np.float64)
    from scipy.signal import butter, sosfilt

    assert 0 < x.size <= AUTO_MAX_S * rate
    assert x[-1] == 0.0
    # what is heard (above 20 Hz: a ruler's few-hertz sway is not) has fallen 90 dB by the end
    heard = butter(2, 20.0, "highpass", fs=rate, output="sos")
    plain = model.render(resolved, duration_s=x.size / rate, sample_rate=rate, normalize=False, dtype=np.float64)
    unfaded = sosfilt(heard, plain)
    assert _db(np.max(np.abs(unfaded[-rate // 100:])) / np.max(np.abs(unfaded))) <= -90.0  # the last 10 ms
    # and the fade adds nothing one could hear as a click
    faded = sosfilt(heard, x)
    assert _db(np.max(np.abs(faded[-rate // 20:])) / np.max(np.abs(faded))) <= -80.0
    # the fade is a raised cosine over the very samples a fixed duration of the same length gives
    n = int(round(AUTO_FADE_S * rate))
    fade = 0.5 * (1.0 + np.cos(np.pi * np.arange(1, n + 1) / n))
    np.testing.assert_array_equal(x[:-n], plain[:-n])
    np.testing.assert_allclose(x[-n:], plain[-n:] * fade, rtol=1e-12, atol=0)
    assert np.max(np.abs(np.diff(x[-n:]))) <= 2.0 * np.max(np.abs(plain[-n:]))  # no step beyond the sound's own


@pytest.mark.parametrize("model_name", ["banded", "fd"])
def test_auto_waits_for_the_bow_to_be_lifted_then_for_the_decay(model_name):
    from barsynth.dsp.bow_stroke import LIFT_DELAY_S

    rate = 48000
    settings = {"excitation": "bow", "bow_duration_s": 2.5, "bow_ramp_ms": 50.0}
    x = get_model(model_name).render(settings, duration_s="auto", sample_rate=rate, normalize=False,
                                     dtype=np.float64)
    lifted_s = 2.5 + 2 * 0.05 + LIFT_DELAY_S
    assert x.size / rate >= lifted_s
    peak = np.max(np.abs(x))
    assert _db(np.max(np.abs(x[-rate // 20:])) / peak) <= -90.0 and x[-1] == 0.0
    # while the bow moves the bar sounds: the second before it slows is far above -90 dB
    assert _db(np.max(np.abs(x[int(1.5 * rate):int(2.5 * rate)])) / peak) > -20.0


def test_auto_stops_at_the_cap_with_one_warning_line(tmp_path):
    from barsynth.models.rendering import AUTO_MAX_S, NeverQuietWarning

    with pytest.warns(NeverQuietWarning, match="cap of 60 s"):
        x = get_model("banded").render({"tuning": "ratios", "mode_t60s_s": (120.0,)}, duration_s="auto",
                                       sample_rate=8000, dtype=np.float64)
    assert x.size == AUTO_MAX_S * 8000 and x[-1] == 0.0
    out = tmp_path / "long.wav"
    r = run("render", "banded", "--set", "tuning=ratios", "--set", "mode_t60s_s=120", "--sample-rate", "8000",
            "-o", str(out))
    assert r.exit_code == 0
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("barsynth: warning: duration auto stopped at its cap of 60 s")
    assert soundfile.info(out).frames == 60 * 8000
    r = run("render", "banded", "--set", "excitation=bow", "--set", "bow_duration_s=100", "--sample-rate", "8000",
            "-o", str(out))
    assert r.stderr.count("\n") == 1 and "the bow is still on the bar" in r.stderr


def test_render_defaults_to_auto_and_says_how_long(tmp_path):
    out = tmp_path / "marimba.wav"
    r = run("render", "banded", "--preset", "marimba", "-o", str(out))
    assert r.exit_code == 0 and r.stderr == ""
    x, rate = soundfile.read(out)
    assert 0.5 < x.size / rate < 60.0 and x[-1] == 0.0
    assert f"(auto: {x.size / rate:.2f} s at 48000 Hz)" in r.stdout
    assert np.max(np.abs(x)) == pytest.approx(10 ** (-1 / 20), abs=1e-4)
    assert run("render", "banded", "--duration", "AUTO", "-o", str(out)).exit_code == 0


@pytest.mark.parametrize("value", ["soon", "0", "-1", "601"])
def test_a_bad_duration_names_auto_among_the_allowed(tmp_path, value):
    assert_one_line_error(run("render", "banded", "--duration", value, "-o", str(tmp_path / "x.wav")),
                          "duration_s", "auto", "600 s")
    assert list(tmp_path.iterdir()) == []


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process's CPU time from /proc")
def test_ctrl_c_stops_a_long_render_with_one_line_and_no_file(tmp_path):
    import signal
    import time

    out = tmp_path / "long.wav"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    # a 10-minute finite-difference bar: over a minute of computing on any machine
    proc = subprocess.Popen([sys.executable, "-m", "barsynth", "render", "fd", "--set", "points=200",
                             "--duration", "600", "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    try:
        deadline = time.monotonic() + 120.0
        # past start-up (imports, the model, numba's cache: ~2 s of CPU) and into the blocks
        while proc.poll() is None and _cpu_seconds(proc.pid) < 3.0 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, proc.communicate()
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=20)  # generous: a loaded machine
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130
    assert stderr.decode() == "barsynth: interrupted; nothing written\n" and stdout == b""
    assert list(tmp_path.iterdir()) == []


def test_an_interrupted_write_leaves_no_temporary_file(tmp_path):
    from barsynth.cli import _write_all

    def write(tmp):
        Path(tmp).write_bytes(b"half a file")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _write_all([(tmp_path / "a.wav", write)])
    assert list(tmp_path.iterdir()) == []


def test_progress_shows_on_a_terminal_only(tmp_path, monkeypatch):
    import barsynth.cli as cli

    monkeypatch.setenv("COLUMNS", "80")
    out = tmp_path / "x.wav"
    quiet = run("render", "fd", "--preset", "ruler", "--duration", "0.5", "-o", str(out))
    assert quiet.exit_code == 0 and quiet.stderr == ""  # not a terminal: nothing
    monkeypatch.setattr(cli, "_is_terminal", lambda stream: True)
    monkeypatch.setattr(cli, "PROGRESS_AFTER_S", 0.0)
    monkeypatch.setattr(cli, "PROGRESS_EVERY_S", 0.0)
    shown = run("render", "fd", "--preset", "ruler", "--duration", "0.5", "-o", str(out))
    assert shown.exit_code == 0
    assert "\rbarsynth: rendering 0.5 of 0.5 s (100 %)\x1b[K" in shown.stderr
    assert shown.stderr.endswith("\r\x1b[K")  # erased when done
    auto = run("render", "fd", "--preset", "ruler", "-o", str(out))
    assert " of 90 dB down (auto, at most 60 s)\x1b[K" in auto.stderr and "-0 of" not in auto.stderr
    assert auto.stderr.endswith("\r\x1b[K") and "\n" not in auto.stderr
    lines = auto.stderr.split("\r")[1:-1]
    assert lines and all(len(line.removesuffix("\x1b[K")) <= 79 for line in lines)


def _drawn(stream_text: str) -> list[str]:
    """The lines a progress stream drew (between its carriage returns, without the erase)."""
    return [part.removesuffix("\x1b[K") for part in stream_text.split("\r") if part.removesuffix("\x1b[K")]


@pytest.mark.parametrize("columns", [80, 40])
def test_progress_lines_fit_the_terminal(monkeypatch, columns):
    """A line as wide as the terminal wraps, and the next \\r redraw leaves its first row behind:
    every line is at most columns - 1 wide, whatever the render reports."""
    import io

    from barsynth.cli import _Progress

    monkeypatch.setenv("COLUMNS", str(columns))  # a stream without a terminal of its own: $COLUMNS
    stream = io.StringIO()
    progress = _Progress(stream, terminal=True, after_s=0.0)
    monkeypatch.setattr("barsynth.cli.PROGRESS_EVERY_S", 0.0)
    for args in [(4.1, None, -81.4), (4.1, None, None), (59.95, None, -0.0), (123.4, 600.0, None),
                 (0.5, 0.5, None)]:
        progress(*args)
    progress.close()
    drawn = _drawn(stream.getvalue())
    assert len(drawn) == 5 and all(len(line) <= columns - 1 for line in drawn), drawn
    assert all(line.startswith("barsynth: rendering ") for line in drawn)
    if columns == 80:  # whole: what it says
        assert drawn[0] == "barsynth: rendering 4.1 s, 81 of 90 dB down (auto, at most 60 s)"
        assert drawn[2] == "barsynth: rendering 60.0 s, 0 of 90 dB down (auto, at most 60 s)"
        assert drawn[3] == "barsynth: rendering 123.4 of 600 s (21 %)"


def test_progress_reads_the_width_of_its_own_terminal(monkeypatch):
    """On a terminal (a pty 40 columns wide) the width is the terminal's own, not $COLUMNS'."""
    import fcntl
    import pty
    import struct
    import termios

    from barsynth.cli import _Progress

    monkeypatch.setenv("COLUMNS", "200")
    monkeypatch.setattr("barsynth.cli.PROGRESS_EVERY_S", 0.0)
    leader, follower = pty.openpty()
    try:
        fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 40, 0, 0))
        with open(follower, "w", closefd=False) as stream:
            progress = _Progress(stream, after_s=0.0)  # a terminal: on by itself
            progress(4.1, None, -81.0)
            progress.close()
        shown = os.read(leader, 4096).decode()
    finally:
        os.close(follower)
        os.close(leader)
    drawn = _drawn(shown.replace("\r\n", "\n"))
    assert drawn == ["barsynth: rendering 4.1 s, 81 of 90 dB "] and len(drawn[0]) == 39


def test_progress_line_redraws_in_place():
    import io

    from barsynth.cli import _Progress

    stream = io.StringIO()
    progress = _Progress(stream, terminal=True, after_s=0.0)
    progress(1.0, 4.0, None)
    progress.close()
    assert stream.getvalue() == "\rbarsynth: rendering 1.0 of 4 s (25 %)\x1b[K\r\x1b[K"
    silent = io.StringIO()
    off = _Progress(silent, terminal=False, after_s=0.0)
    off(1.0, 4.0, None)
    off.close()
    assert silent.getvalue() == ""


def test_a_parameter_without_effect_gets_one_warning_and_still_renders(tmp_path):
    out = tmp_path / "x.wav"
    r = run("render", "banded", "--set", "bow_force_n=5", "--duration", "0.2", "-o", str(out))
    assert r.exit_code == 0 and soundfile.info(out).frames == int(0.2 * 48000)
    assert r.stderr == "barsynth: warning: bow_force_n has no effect unless excitation = bow\n"
    r = run("render", "banded", "--set", "excitation=bow", "--set", "bow_force_n=5", "--duration", "0.2",
            "-o", str(out))
    assert r.exit_code == 0 and r.stderr == ""
    assert run("render", "banded", "--preset", "marimba", "--duration", "0.2", "-o", str(out)).stderr == ""
    # a preset file of one's own: its values that differ from the defaults count as given
    mine = tmp_path / "mine.toml"
    mine.write_text('[parameters]\ntuning = "ratios"\nlength_m = 0.5\nbow_force_n = 3.0\nq = 200.0\n'
                    'mallet_hardness = 0.2\n')
    r = run("describe", "banded", "--preset", str(mine))
    assert r.exit_code == 0  # (an instrument's settings for another excitation are not warned about)
    assert r.stderr == "barsynth: warning: length_m has no effect unless tuning = physics or geometry\n"
    r = run("describe", "banded", "--preset", str(mine), "--set", "mallet_hardness=0.3", "--set", "excitation=bow")
    assert r.stderr == ("barsynth: warning: length_m has no effect unless tuning = physics or geometry\n"
                        "barsynth: warning: mallet_hardness has no effect unless excitation = strike\n")  # --set warned


@pytest.mark.parametrize("model_name,args,warning", [
    ("twang", ["--set", "vibrato_depth_hz=30"], "vibrato_depth_hz has no effect unless vibrato_rate_hz > 0"),
    ("twang", ["--set", "short_cantilever_gain=0", "--set", "short_length_ratio=0.5"],
     "short_length_ratio has no effect unless short_cantilever_gain > 0"),
    ("banded", ["--set", "mode_count=2", "--set", "mode_t60s_s=1,0.5", "--set", "q=50"],
     "q has no effect unless tuning = physics or geometry and mode_t60s_s has fewer values than mode_count, "
     "or tuning = ratios and mode_t60s_s has fewer values than mode_ratios"),
    ("fd", ["--set", "profile=parabolic", "--set", "undercut_width=0.4"],
     "undercut_width has no effect unless profile = parabolic or circular and undercut_depth > 0"),
])
def test_a_parameter_without_effect_under_a_number_gets_one_warning_and_the_same_sound(tmp_path, model_name, args,
                                                                                      warning):
    """A row that acts only while a number (or a list's length) says so: one warning line, and the
    file is the one rendered without that --set."""
    given, out = tmp_path / "given.wav", tmp_path / "without.wav"
    r = run("render", model_name, *args, "--duration", "0.3", "-o", str(given))
    assert r.exit_code == 0 and r.stderr == f"barsynth: warning: {warning}\n"
    assert run("render", model_name, *args[:-2], "--duration", "0.3", "-o", str(out)).stderr == ""
    assert given.read_bytes() == out.read_bytes()


def test_a_parameter_acting_under_a_number_gets_no_warning(tmp_path):
    out = tmp_path / "x.wav"
    for model_name, args in [("twang", ["--set", "vibrato_rate_hz=5", "--set", "vibrato_depth_hz=30"]),
                             ("banded", ["--set", "mode_count=3", "--set", "mode_t60s_s=1,0.5", "--set", "q=50"]),
                             ("banded", ["--set", "tuning=ratios", "--set", "mode_t60s_s=1,0.5", "--set", "q=50"])]:
        r = run("render", model_name, *args, "--duration", "0.2", "-o", str(out))
        assert r.exit_code == 0 and r.stderr == "", (model_name, args, r.stderr)


def test_material_in_params_set_and_materials(tmp_path):
    from barsynth.physics import materials as table

    names = list(table())
    text = run("params", "banded").stdout
    assert all(len(line) <= 100 for line in text.splitlines())
    block = text[text.index("  material "):text.index("  length_m ")]
    assert all(name in block for name in names)
    d = json.loads(run("describe", "banded", "--set", "material=steel", "--json").stdout)
    assert d["parameters"]["youngs_modulus_pa"] == 2e11 and d["parameters"]["density_kg_m3"] == 7850
    out = tmp_path / "steel.wav"
    assert run("render", "twang", "--set", "material=steel", "--duration", "0.2", "-o", str(out)).exit_code == 0
    listed = run("materials").stdout
    for name, mat in table().items():
        assert f"{name:<16} {mat.youngs_modulus_pa:>9.3g}" in listed
    data = json.loads(run("materials", "--json").stdout)
    assert [m["name"] for m in data] == names
    for entry in data:
        mat = table()[entry["name"]]
        assert entry == {"name": mat.name, "youngs_modulus_pa": mat.youngs_modulus_pa,
                         "density_kg_m3": mat.density_kg_m3, "typical_q": mat.typical_q,
                         "description": mat.description, "source": mat.source}


def test_render_help_lists_every_model_with_its_summary():
    text = " ".join(run("render", "--help").stdout.split())
    for name in model_names():
        assert f"{name} {' '.join(get_model(name).summary.split())}" in text


def test_presets_json_lists_each_models_presets_with_descriptions():
    from barsynth.presets import load_preset, preset_names

    data = json.loads(run("presets", "--json").stdout)
    assert list(data) == list(model_names())
    for name, listed in data.items():
        assert [p["name"] for p in listed] == list(preset_names(name))
        for p in listed:
            assert p["description"] == load_preset(name, p["name"])["preset"]["description"]
            assert p["parameters"] == load_preset(name, p["name"])["parameters"]
    assert list(json.loads(run("presets", "fd", "--json").stdout)) == ["fd"]


def _barsynth(*args: str, **kwargs):
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    return subprocess.run([sys.executable, "-m", "barsynth", *args], env=env, **kwargs)


def test_output_dash_writes_the_wav_to_stdout_and_nothing_else(tmp_path):
    import io

    proc = _barsynth("render", "banded", "--preset", "marimba", "--duration", "0.5", "-o", "-",
                     capture_output=True, cwd=tmp_path)
    assert proc.returncode == 0 and proc.stderr == b""
    x, rate = soundfile.read(io.BytesIO(proc.stdout))
    assert rate == 48000 and x.size == 24000
    assert soundfile.info(io.BytesIO(proc.stdout)).subtype == "PCM_24"
    assert run("render", "banded", "--preset", "marimba", "--duration", "0.5", "-o", str(tmp_path / "m.wav")
               ).exit_code == 0
    assert np.array_equal(soundfile.read(tmp_path / "m.wav")[0], x)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.wav"]  # no file called -
    auto = _barsynth("render", "twang", "--subtype", "FLOAT", "-o", "-", capture_output=True)
    y, _ = soundfile.read(io.BytesIO(auto.stdout))
    assert auto.returncode == 0 and y[-1] == 0.0


def test_output_dash_to_a_terminal_is_refused(tmp_path):
    import pty

    leader, follower = pty.openpty()
    try:
        proc = _barsynth("render", "twang", "--duration", "0.2", "-o", "-", stdout=follower,
                         stderr=subprocess.PIPE, cwd=tmp_path, timeout=60)
    finally:
        os.close(follower)
        os.close(leader)
    assert proc.returncode == 2
    assert proc.stderr.decode().count("\n") == 1 and "parameter output = - is standard output" in proc.stderr.decode()
    assert list(tmp_path.iterdir()) == []


def test_output_dash_with_stdout_closed_is_refused_in_one_line(tmp_path):
    """`-o - >&-`: Python starts without a standard output; the render is refused before it begins."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    proc = subprocess.run(["sh", "-c", 'exec "$0" -m barsynth render banded --preset marimba -o - >&-', sys.executable],
                          env=env, cwd=tmp_path, stderr=subprocess.PIPE, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == ("barsynth: error: parameter output = - is standard output, which is closed; allowed: "
                           "- only with standard output open and redirected to a file or a pipe\n")
    assert list(tmp_path.iterdir()) == []


def test_a_reader_that_goes_away_ends_the_command_quietly_with_status_141(tmp_path):
    """`render -o - | head -c 10`: the WAV was cut, so not 0; the reader chose to stop, so no message."""
    proc = subprocess.Popen([sys.executable, "-m", "barsynth", "render", "banded", "--preset", "marimba",
                             "--duration", "2", "-o", "-"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env={**os.environ, "PYTHONPATH": str(ROOT / "src")}, cwd=tmp_path)
    try:
        head = os.read(proc.stdout.fileno(), 10)  # (the WAV, 288 kB, cannot fit in the pipe: it must wait)
        proc.stdout.close()
        stderr = proc.stderr.read()
        proc.wait(timeout=120)
    finally:
        proc.kill()
    assert head.startswith(b"RIFF")
    assert proc.returncode == 141 and stderr == b""
    assert list(tmp_path.iterdir()) == []
    reader, writer = os.pipe()
    os.close(reader)  # gone before the first line
    try:
        listed = _barsynth("params", "twang", stdout=writer, stderr=subprocess.PIPE, timeout=60)
    finally:
        os.close(writer)
    assert listed.returncode == 141 and listed.stderr == b""


def test_json_ready_makes_numpy_and_non_finite_values_strict_json():
    from barsynth.jsonout import json_ready

    data = {"t60_s": (1.5, float("inf")), "gain": np.float32(0.5), "count": np.int64(3), "on": np.bool_(True),
            "modes": [{"hz": np.float64(220.0), "error": np.nan}], "shape": np.array([[1, 2], [3, 4]]),
            "name": "x", "none": None, "level": -np.inf}
    ready = json_ready(data)
    assert ready == {"t60_s": [1.5, None], "gain": 0.5, "count": 3, "on": True, "modes": [{"hz": 220.0, "error": None}],
                     "shape": [[1, 2], [3, 4]], "name": "x", "none": None, "level": None}
    assert type(ready["count"]) is int and type(ready["on"]) is bool and type(ready["modes"][0]["hz"]) is float
    json.dumps(ready, allow_nan=False)
    assert data["t60_s"] == (1.5, float("inf"))  # the input is left as it was


def test_auto_ends_at_the_same_sample_whatever_the_block_sizes(monkeypatch):
    from barsynth.models import rendering

    def auto(name, settings):
        return get_model(name).render(settings, duration_s="auto", sample_rate=44100, normalize=False,
                                      dtype=np.float64)

    cases = [("banded", {}), ("twang", {"q": 60.0}), ("banded", {"excitation": "bow", "bow_duration_s": 0.3})]
    usual = [auto(*case) for case in cases]
    monkeypatch.setattr(rendering, "MAX_BLOCK_S", 0.003)  # blocks of at most 132 samples
    monkeypatch.setattr(rendering, "BLOCK_WALL_S", 1e-9)
    for case, x in zip(cases, usual):
        y = auto(*case)
        assert np.array_equal(x, y)
        assert round(x.size / 441) == x.size / 441  # a whole number of 10 ms hops


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process's CPU time from /proc")
@pytest.mark.parametrize("after_cpu_s", [1.2, 1.8, 2.4])
def test_ctrl_c_while_numba_compiles_stops_after_the_compile(tmp_path, after_cpu_s):
    """The first render after install compiles its kernels (imports take about 0.6 s of CPU,
    compiling fd's kernels several s): a Ctrl-C then (numba's cache empty, the signal sent at
    several points of the compile) still ends in the one line and no file, once it is done.
    (Raised inside numba's compiler, a KeyboardInterrupt was swallowed or became a RuntimeError.)"""
    import signal
    import time

    out = tmp_path / "long.wav"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    proc = subprocess.Popen([sys.executable, "-m", "barsynth", "render", "fd", "--set", "points=200",
                             "--duration", "600", "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    try:
        deadline = time.monotonic() + 120.0
        while proc.poll() is None and _cpu_seconds(proc.pid) < after_cpu_s and time.monotonic() < deadline:
            time.sleep(0.02)
        assert proc.poll() is None, proc.communicate()
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=120)  # the compile goes on: generous on a loaded machine
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, stderr.decode()[-2000:]
    assert stderr.decode() == "barsynth: interrupted; nothing written\n" and stdout == b""
    assert not out.exists()
