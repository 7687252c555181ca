"""The banded fit's quality (issue 14): barsynth's presets recovered through noise and a room,
real recordings from Debian's two soundfonts fitted to spec 7's targets, and `barsynth fit`'s
preset playing at the recording's pitch and at another with its ratios kept.

The measurements are scripts/fit_quality.py's (the table in docs/fitting.md); a soundfont
that is not installed skips its cases (CI installs both)."""

from __future__ import annotations

import importlib.util
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile
from click.testing import CliRunner

from barsynth.analysis import analyze_note
from barsynth.cli import main
from barsynth.fitting import fit_recording

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "fit_quality.py"


def load_script():
    spec = importlib.util.spec_from_file_location("fit_quality", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules["fit_quality"] = module  # (its dataclasses look their module up)
    spec.loader.exec_module(module)
    return module


fq = load_script()


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


# -- synthetic ground truth ------------------------------------------------------------------
@pytest.mark.parametrize("preset, frequency_hz", [("marimba", None), ("xylophone", 1046.5), ("vibraphone", 220.0),
                                                  ("glass", None)])
def test_presets_come_back_through_noise_and_a_room(preset, frequency_hz):
    x, truth = fq.synthetic(preset, frequency_hz)
    fit = fit_recording(x, fq.SYNTH_RATE, model="banded")
    freqs, t60s, levels = fq.fitted_modes(fit)
    top = truth.levels_db.max()
    judged = np.flatnonzero((truth.levels_db >= top - 40.0) & (truth.t60s_s >= fq.ROOM_LENGTHS * fq.ROOM_LENGTH_S))
    assert judged.size >= 2
    strongest = int(np.argmax(truth.levels_db))
    anchor = int(np.argmin(np.abs(np.log(freqs / truth.frequencies_hz[strongest]))))
    for i in judged:
        j = int(np.argmin(np.abs(np.log(freqs / truth.frequencies_hz[i]))))
        assert abs(1200.0 * math.log2(freqs[j] / truth.frequencies_hz[i])) <= 0.5, (i, freqs[j])
        assert abs(t60s[j] / truth.t60s_s[i] - 1.0) <= 0.03, (i, t60s[j], truth.t60s_s[i])
        assert abs((levels[j] - levels[anchor]) - (truth.levels_db[i] - top)) <= 1.0, (i, levels, truth.levels_db)


def test_the_script_counts_a_miss():
    """A partial 5 cents and 4 dB off, one never found and a T60 20 % long are counted as misses;
    a hum below a quarter of f0 and a partial 45 dB down are not judged."""
    from types import SimpleNamespace

    from barsynth.analysis.records import Decay
    from barsynth.fitting import PartialComparison

    def partial(f, level, t60):
        decay = Decay(method="line", t60_s=t60, range_start_s=0.05, range_end_s=1.0, range_start_db=-1.0,
                      range_end_db=-40.0, floor_db=-70.0, rms_db=0.2, r2=0.99, points=100, knee_s=None,
                      second_t60_s=None, line_rms_db=0.2, sustains=False)
        return SimpleNamespace(frequency_hz=f, level_db=level, t60_s=t60, decay=decay)

    recorded = [partial(50.0, -10.0, 1.0), partial(400.0, -6.0, 1.0), partial(1600.0, -12.0, 0.5),
                partial(4000.0, -20.0, 0.3), partial(5000.0, -51.0, 0.2)]
    rows = (PartialComparison(50.0, -10.0, 1.0),
            PartialComparison(400.0, -6.0, 1.0, 400.0, -6.0, 1.01),
            PartialComparison(1600.0, -12.0, 0.5, 1600.0 * 2 ** (5 / 1200), -8.0, 0.6),
            PartialComparison(4000.0, -20.0, 0.3),
            PartialComparison(5000.0, -51.0, 0.2))
    fit = SimpleNamespace(comparison=rows, analysis=SimpleNamespace(f0_hz=400.0, partials=recorded[1:],
                                                                    below_f0=recorded[:1]))
    judged, freq_ok, level_ok, t60_judged, t60_ok, worst = fq.judge(fit)
    assert (judged, freq_ok, level_ok, t60_judged, t60_ok) == (3, 1, 1, 3, 1)
    assert "1600 Hz +5.0 c" in worst


# -- real recordings ---------------------------------------------------------------------------
REAL = [  # font, instrument, key: a marimba, a glockenspiel or vibraphone, a kalimba or tubular bell
    ("MuseScore", "marimba", 60), ("MuseScore", "glockenspiel", 84), ("MuseScore", "kalimba", 65),
    ("MuseScore", "vibraphone", 63), ("TimGM6mb", "marimba", 58), ("TimGM6mb", "glockenspiel", 94),
    ("TimGM6mb", "kalimba", 72),
]


def real_note(font: str, instrument: str, key: int):
    path = fq.FONTS[font]
    if not path.exists():
        pytest.skip(f"{path} is not installed (apt-get install musescore-general-soundfont-small timgm6mb-soundfont)")
    found = [n for n in fq.notes({font: path}, fq.KEYS, (instrument,)) if n.key == key]
    assert found, (font, instrument, key)
    return found[0]


@pytest.mark.parametrize("font, instrument, key", REAL)
def test_real_recordings_meet_the_targets(font, instrument, key):
    """Issue 14's targets on partials within 40 dB of the strongest: 3 cents, 3 dB, T60 within
    15 % where the recording's decay is single-slope over 20 dB, and half the sine's distance."""
    note = real_note(font, instrument, key)
    fit = fit_recording(note.samples, note.sample_rate, model="banded", nominal_hz=note.nominal_hz)
    rows = fq.judged(fit)
    assert len(rows) >= 2
    for r in rows:
        assert r.cents is not None and abs(r.cents) <= 3.0, (r.frequency_hz, r.cents)
        assert abs(r.level_error_db) <= 3.0, (r.frequency_hz, r.level_error_db)
    judged, *_, t60_judged, t60_ok, worst = fq.judge(fit)
    assert t60_ok == t60_judged, worst
    assert fit.distance_db <= 0.5 * fit.baseline_db, (fit.distance_db, fit.baseline_db)


# -- the command line: the preset plays, at any pitch -----------------------------------------
def peaks_hz(samples: np.ndarray, rate: float, count: int) -> list[float]:
    """The ``count`` strongest partials' frequencies (Hz) of a sound, measured after its first
    0.15 s (the fit's attack, the recording's own first 100 ms, has ended)."""
    note = analyze_note(samples[int(0.15 * rate):], rate)
    strongest = sorted((*note.below_f0, *note.partials), key=lambda p: -p.level_db)[:count]
    return sorted(p.frequency_hz for p in strongest)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    note = real_note("MuseScore", "marimba", 60)
    folder = tmp_path_factory.mktemp("fit")
    wav = folder / "marimba.wav"
    soundfile.write(wav, note.samples, int(note.sample_rate), subtype="FLOAT")
    out = folder / "marimba.toml"
    result = run("fit", str(wav), "--nominal-hz", f"{note.nominal_hz}", "-o", str(out), "--json",
                 "--plot", str(folder / "fit.png"), "--render", str(folder / "again.wav"))
    assert result.exit_code == 0, result.output
    return note, folder, json.loads(result.output)


def test_fit_json_plot_and_render(fitted):
    note, folder, report = fitted
    for key in ("model", "f0_hz", "parameters", "partials", "spectral_distance_db", "sine_baseline_db"):
        assert key in report
    assert report["spectral_distance_db"] <= 0.5 * report["sine_baseline_db"]
    assert len(report["partials"]) >= 3
    for p in report["partials"]:
        for key in ("frequency_hz", "level_db", "t60_s", "cents", "level_error_db", "t60_error_percent"):
            assert key in p
    assert abs(report["partials"][0]["cents"]) < 3.0
    assert (folder / "fit.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    again, rate = soundfile.read(folder / "again.wav")
    assert rate == note.sample_rate and again.size > 0.5 * rate
    assert abs(analyze_note(again, rate).f0_hz / report["f0_hz"] - 1.0) < 1e-3


@pytest.mark.parametrize("frequency_hz", [None, 392.0])
def test_the_fitted_preset_plays_at_its_pitch_and_at_another_with_its_ratios(fitted, frequency_hz):
    note, folder, report = fitted
    wav = folder / f"played-{frequency_hz}.wav"
    args = ["render", "banded", "--preset", str(folder / "marimba.toml"), "--duration", "1.5",
            "--sample-rate", "44100", "-o", str(wav)]
    if frequency_hz is not None:
        args += ["--set", f"frequency_hz={frequency_hz}"]
    result = run(*args)
    assert result.exit_code == 0, result.output
    played, rate = soundfile.read(wav)
    ratios = np.array(report["parameters"]["mode_ratios"])
    pitch = report["parameters"]["frequency_hz"] if frequency_hz is None else frequency_hz
    heard = peaks_hz(played, rate, 4)
    assert len(heard) == 4
    for got in heard:  # each partial heard is a mode, at its ratio to the pitch asked for
        assert np.min(np.abs(1200.0 * np.log2(got / (ratios * pitch)))) < 1.0, (heard, ratios * pitch)
    assert abs(1200.0 * math.log2(min(heard) / pitch)) < 1.0  # the fundamental sounds
    if frequency_hz is None:
        assert abs(1200.0 * math.log2(pitch / note.nominal_hz)) < 5.0


def band_level_db(x: np.ndarray, rate: float, frequency_hz: float, width_cents: float = 50.0) -> float:
    """Power of ``x`` within ``width_cents`` of ``frequency_hz`` (dB, Hann-windowed spectrum)."""
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size), 8 * x.size)) ** 2
    freqs = np.fft.rfftfreq(8 * x.size, 1.0 / rate)
    near = np.abs(1200.0 * np.log2(np.maximum(freqs, 1e-9) / frequency_hz)) <= width_cents
    return float(10.0 * np.log10(spectrum[near].sum() + 1e-300))


def test_the_recorded_attack_follows_the_pitch(fitted):
    """The attack sample (the recording less the modes as the model plays them) holds sines at
    the recording's partials; played at another pitch it is transposed with the note
    (attack_pitch_hz), so the onset has nothing at the old f0: over the first 100 ms the old
    f0's band is far below the new one's, and within a few dB of it without the transposition
    (the defect this pins)."""
    note, folder, report = fitted
    old = report["parameters"]["frequency_hz"]
    assert report["parameters"]["attack_pitch_hz"] == pytest.approx(old)
    rate, new = 44100, 0.75 * old
    levels = {}
    for pitch_hz in (old, 0.0):
        wav = folder / f"onset-{pitch_hz}.wav"
        result = run("render", "banded", "--preset", str(folder / "marimba.toml"), "--duration", "0.3",
                     "--sample-rate", str(rate), "--set", f"frequency_hz={new}", "--set",
                     f"attack_pitch_hz={pitch_hz}", "-o", str(wav))
        assert result.exit_code == 0, result.output
        played, _ = soundfile.read(wav)
        onset = played[:int(0.1 * rate)]
        levels[pitch_hz] = band_level_db(onset, rate, old) - band_level_db(onset, rate, new)
    assert levels[old] < -20.0, levels
    assert levels[0.0] > levels[old] + 15.0, levels
