"""barsynth fit's command line: outputs that would replace the recording or each other, fd's
grid from --set, and a nominal pitch that retunes a fit with high partials."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
import soundfile as sf
from click.testing import CliRunner

from barsynth.cli import main

RATE = 44100


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def two_partials(path, f0: float = 440.0, high: float = 1716.0, seconds: float = 1.0) -> bytes:
    t = np.arange(int(seconds * RATE)) / RATE
    x = 0.5 * np.exp(-t / 0.4) * np.sin(2 * np.pi * f0 * t) + 0.2 * np.exp(-t / 0.2) * np.sin(2 * np.pi * high * t)
    x += 1e-4 * np.random.default_rng(1).standard_normal(x.size)
    sf.write(path, x, RATE, subtype="PCM_16", format="WAV")
    return path.read_bytes()


@pytest.mark.parametrize("option", ["--render", "--plot", "-o"])
def test_an_output_that_is_the_recording_is_refused_and_the_recording_kept(tmp_path, option):
    recording = tmp_path / ("note.toml" if option == "-o" else "note.png" if option == "--plot" else "note.wav")
    before = two_partials(recording)
    args = ["fit", str(recording), option, str(recording)]
    if option != "-o":
        args += ["-o", str(tmp_path / "fit.toml")]
    result = run(*args)
    assert result.exit_code == 2
    assert "is the recording itself" in result.output and len(result.output.strip().splitlines()) == 1
    assert recording.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [recording.name]


def test_a_hard_link_to_the_recording_is_the_recording(tmp_path):
    recording = tmp_path / "note.wav"
    before = two_partials(recording)
    os.link(recording, tmp_path / "link.wav")
    result = run("fit", str(recording), "-o", str(tmp_path / "fit.toml"), "--render", str(tmp_path / "link.wav"))
    assert result.exit_code == 2 and "is the recording itself" in result.output
    assert recording.read_bytes() == before and not (tmp_path / "fit.toml").exists()


def test_two_outputs_in_one_file_are_refused(tmp_path):
    recording = tmp_path / "note.wav"
    two_partials(recording)
    (tmp_path / "fit.png").symlink_to(tmp_path / "fit.toml")  # not there yet: the link dangles
    result = run("fit", str(recording), "-o", str(tmp_path / "fit.toml"), "--plot", str(tmp_path / "fit.png"))
    assert result.exit_code == 2 and "is also the output file" in result.output
    assert not (tmp_path / "fit.toml").exists()


def test_fd_points_from_set(tmp_path):
    recording = tmp_path / "note.wav"
    two_partials(recording, 440.0, 440.0 * 2.756)  # a free-free bar's first two modes
    out = tmp_path / "bar.toml"
    result = run("fit", str(recording), "--model", "fd", "--set", "material=aluminium", "--set", "points=80",
                 "-o", str(out), "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.output)["parameters"]["points"] == 80
    bad = run("fit", str(recording), "--model", "fd", "--set", "points=7", "-o", str(out))
    assert bad.exit_code == 2 and "points" in bad.output and "8 to 400" in bad.output


def test_a_nominal_pitch_above_f0_keeps_the_high_partials(tmp_path):
    """Tuned to a nominal pitch twice f0, the fit's render must still reach its highest mode
    (11.5 kHz at 44.1 kHz: rendered at twice the rate): it is found in the resynthesis."""
    recording = tmp_path / "note.wav"
    two_partials(recording, 1000.0, 11500.0)
    result = run("fit", str(recording), "--nominal-hz", "2000", "-o", str(tmp_path / "fit.toml"), "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.output)
    assert report["parameters"]["frequency_hz"] == pytest.approx(2000.0)
    high = [p for p in report["partials"] if abs(p["frequency_hz"] - 11500.0) < 50.0]
    assert high and high[0]["cents"] is not None and abs(high[0]["cents"]) < 3.0, high


def test_twang_refuses_both_thickness_and_length(tmp_path):
    recording = tmp_path / "note.wav"
    two_partials(recording, 110.0, 110.0 * 6.27)
    result = run("fit", str(recording), "--model", "twang", "--set", "thickness_m=0.002", "--set", "length_m=0.3",
                 "-o", str(tmp_path / "ruler.toml"))
    assert result.exit_code == 2 and "thickness_m" in result.output and "length_m" in result.output
    assert len(result.output.strip().splitlines()) == 1 and not (tmp_path / "ruler.toml").exists()


def test_a_twang_fit_is_compared_partial_by_partial():
    """The twang's free bar is band-passed noise: its resynthesis is measured over the recording's
    noise floor, so each partial of a ruler finds its counterpart (without: 5 of 10)."""
    from test_fit_physics import RATE as TWANG_RATE, TWANGS, rendered

    from barsynth.fitting import fit_recording

    x = rendered("twang", TWANGS[0], seconds=2.0)
    fit = fit_recording(x, TWANG_RATE, model="twang", options={"material": "acrylic"})
    found = [r for r in fit.comparison if r.cents is not None]
    assert len(fit.comparison) >= 8 and len(found) >= 0.8 * len(fit.comparison), fit.comparison
    assert max(abs(r.cents) for r in found) < 10.0
