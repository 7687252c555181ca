"""``barsynth fit`` on bad input, for every model: either a fit with its quality reported, or one
line, exit status 2 and no file written (and files already there left as they were); never a
traceback. Short files keep it quick."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from click.testing import CliRunner

from barsynth.cli import main
from barsynth.fitting.recording import MAX_RECORDING_S

MODELS = ("banded", "twang", "fd")
OLD = "old contents\n"


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def note(rate: float, seconds: float = 0.4, f0: float = 440.0) -> np.ndarray:
    """A struck note: two decaying partials (a bar's 1 : 2.76)."""
    t = np.arange(int(round(rate * seconds))) / rate
    return 0.5 * np.exp(-4.0 * t) * (np.sin(2 * np.pi * f0 * t) + 0.3 * np.sin(2 * np.pi * 2.76 * f0 * t))


def speech_like(rate: float = 16000.0, seconds: float = 0.6) -> np.ndarray:
    """A voice-like sound: a glottal pulse train whose pitch glides (90-160 Hz), through three
    formant resonators that move, with pauses."""
    from scipy.signal import lfilter

    n = int(rate * seconds)
    t = np.arange(n) / rate
    pitch = 125.0 + 35.0 * np.sin(2 * np.pi * 2.0 * t)
    pulses = np.diff(np.floor(np.cumsum(pitch / rate)), prepend=0.0)
    x = lfilter([1.0], [1.0, -0.95], pulses)
    block = 160
    for i, (formant, bandwidth) in enumerate(((700.0, 110.0), (1220.0, 110.0), (2600.0, 160.0))):
        out, state = np.zeros(n), np.zeros(2)
        for start in range(0, n, block):
            f = formant * (1.0 + 0.3 * np.sin(2 * np.pi * (1.5 + 0.5 * i) * t[start]))
            r = math.exp(-math.pi * bandwidth / rate)
            poles = [1.0, -2.0 * r * math.cos(2 * math.pi * f / rate), r * r]
            out[start:start + block], state = lfilter([1.0 - r], poles, x[start:start + block], zi=state)
        x = out
    return 0.5 * x / np.max(np.abs(x)) * (np.sin(2 * np.pi * 3.0 * t) > -0.3)


def outputs(tmp_path: Path, existing: bool) -> dict[str, Path]:
    paths = {"-o": tmp_path / "fit.toml", "--plot": tmp_path / "fit.png", "--render": tmp_path / "fit.wav"}
    if existing:
        for p in paths.values():
            p.write_text(OLD)
    return paths


def has_matplotlib() -> bool:
    import importlib.util

    return importlib.util.find_spec("matplotlib") is not None


def fit_args(recording: Path, model: str, paths: dict[str, Path], plot: bool = True) -> list[str]:
    args = ["fit", str(recording), "--model", model, "-o", str(paths["-o"]), "--render", str(paths["--render"])]
    if plot and has_matplotlib():
        args += ["--plot", str(paths["--plot"])]
    return args


def assert_refused(result, paths: dict[str, Path], existing: bool, *needles: str) -> None:
    assert result.exit_code == 2, (result.exit_code, result.output)
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("barsynth: error: "), result.stderr
    assert "Traceback" not in result.output
    for needle in needles:
        assert needle.lower() in lines[0].lower(), (needle, lines[0])
    for p in paths.values():
        if existing:
            assert p.read_text() == OLD, p
        else:
            assert not p.exists(), p
    assert not list(paths["-o"].parent.glob(".barsynth-*")), "a temporary file was left behind"


def assert_fitted(result, paths: dict[str, Path]) -> None:
    assert result.exit_code == 0, result.output
    assert "spectral distance" in result.stdout  # the quality, against one decaying sine
    assert paths["-o"].read_text().strip() and paths["--render"].stat().st_size > 44


def _write(kind: str, path: Path) -> Path:
    rng = np.random.default_rng(3)
    if kind == "silence":
        sf.write(path, np.zeros(8000), 16000)
    elif kind == "white noise":
        sf.write(path, rng.uniform(-0.5, 0.5, 8000), 16000)
    elif kind == "10 ms":
        sf.write(path, note(44100, 0.01), 44100)
    elif kind == "1 sample":
        sf.write(path, np.array([0.5]), 44100)
    elif kind == "empty file":
        path.write_bytes(b"")
    elif kind in ("NaN", "inf"):
        x = note(22050, 0.2).astype(np.float32)
        x[100] = np.nan if kind == "NaN" else np.inf
        sf.write(path, x, 22050, subtype="FLOAT")
    elif kind == "not audio":
        path.write_text("this is not a sound\n" * 50)
    elif kind == "stereo cancelling":
        x = note(22050)
        sf.write(path, np.stack([x, -x], axis=1), 22050)
    elif kind == "directory":
        path.mkdir()
    elif kind == "missing":
        pass
    return path


REFUSED = {  # the file, and words its one line must have
    "silence": ("no note", "silent"),
    "white noise": ("no note",),
    "10 ms": ("no note", "too short"),
    "1 sample": ("no note", "too short"),
    "empty file": ("empty",),
    "NaN": ("non-finite",),
    "inf": ("non-finite",),
    "not audio": ("cannot be read",),
    "stereo cancelling": ("channels cancel",),
    "directory": ("directory",),
    "missing": ("no such file",),
}


@pytest.mark.parametrize("kind", list(REFUSED))
def test_bad_recordings_are_one_line_and_no_file(tmp_path, kind):
    # every model refuses the file the same way, before any fit: one model per case keeps it quick
    model = MODELS[list(REFUSED).index(kind) % 3]
    recording = _write(kind, tmp_path / "in.wav")
    existing = list(REFUSED).index(kind) % 2 == 0  # half the cases with outputs already there
    paths = outputs(tmp_path, existing)
    assert_refused(run(*fit_args(recording, model, paths)), paths, existing, *REFUSED[kind])


@pytest.mark.parametrize("model", MODELS)
def test_no_note_is_refused_by_every_model(tmp_path, model):
    recording = _write("white noise", tmp_path / "noise.wav")
    paths = outputs(tmp_path, existing=True)
    assert_refused(run(*fit_args(recording, model, paths)), paths, True, "no note to fit")


@pytest.mark.parametrize("rate, subtype, suffix, model", [
    (8000, "PCM_16", ".wav", "twang"), (11025, "PCM_16", ".wav", "fd"), (22050, "PCM_24", ".wav", "banded"),
    (44100, "FLOAT", ".wav", "twang"), (48000, "PCM_24", ".flac", "fd"), (96000, "PCM_16", ".wav", "banded"),
    (192000, "FLOAT", ".wav", "fd"),
])
def test_any_rate_and_sample_format_fits(tmp_path, rate, subtype, suffix, model):
    recording = tmp_path / f"note{suffix}"
    sf.write(recording, note(rate, 0.3), rate, subtype=subtype)
    paths = outputs(tmp_path, existing=False)
    result = run(*fit_args(recording, model, paths, plot=False))
    assert_fitted(result, paths)
    info = sf.info(paths["--render"])
    assert info.samplerate == rate
    f0 = float(result.stdout.split("f0 ")[1].split(" Hz")[0])
    assert abs(1200 * math.log2(f0 / 440.0)) < 5.0


@pytest.mark.parametrize("model", MODELS)
def test_clipped_recording_fits_with_a_warning(tmp_path, model):
    recording = tmp_path / "clipped.wav"
    sf.write(recording, np.clip(8.0 * note(22050, 0.4), -1.0, 1.0), 22050)
    paths = outputs(tmp_path, existing=False)
    result = run(*fit_args(recording, model, paths, plot=False))
    assert_fitted(result, paths)
    assert "looks clipped" in result.stderr


def test_quiet_note_is_not_called_clipped(tmp_path):
    recording = tmp_path / "low.wav"
    t = np.arange(8000) / 8000.0
    sf.write(recording, 0.99 * np.exp(-3 * t) * np.sin(2 * np.pi * 30.0 * t), 8000)  # a slow sine near full scale
    paths = outputs(tmp_path, existing=False)
    result = run(*fit_args(recording, "banded", paths, plot=False))
    assert "clipped" not in result.stderr


def test_stereo_in_phase_is_mixed(tmp_path):
    recording = tmp_path / "stereo.wav"
    x = note(22050)
    sf.write(recording, np.stack([x, 0.5 * x], axis=1), 22050)
    paths = outputs(tmp_path, existing=False)
    assert_fitted(run(*fit_args(recording, "banded", paths, plot=False)), paths)


def test_long_recording_is_bounded_and_says_so(tmp_path):
    recording = tmp_path / "long.wav"
    rate = 8000
    x = np.concatenate([note(rate, 1.0), np.zeros(int(rate * (MAX_RECORDING_S + 2.0)))])
    sf.write(recording, x, rate)
    paths = outputs(tmp_path, existing=False)
    result = run(*fit_args(recording, "twang", paths, plot=False))
    assert_fitted(result, paths)
    assert f"reads its first {MAX_RECORDING_S:g} s" in result.stderr
    assert sf.info(paths["--render"]).duration <= MAX_RECORDING_S + 0.01


@pytest.mark.parametrize("model", MODELS)
def test_speech_is_a_fit_with_its_quality_or_one_line(tmp_path, model):
    recording = tmp_path / "speech.wav"
    sf.write(recording, speech_like(), 16000)
    paths = outputs(tmp_path, existing=True)
    result = run(*fit_args(recording, model, paths, plot=False))
    if result.exit_code == 0:
        assert_fitted(result, paths)
    else:
        assert_refused(result, paths, True)


@pytest.mark.skipif(shutil.which("espeak-ng") is None, reason="espeak-ng is not installed")
def test_real_speech_from_espeak(tmp_path):
    import subprocess

    recording = tmp_path / "espeak.wav"
    subprocess.run(["espeak-ng", "-w", str(recording), "one two three"], check=True, timeout=30)
    paths = outputs(tmp_path, existing=True)
    result = run(*fit_args(recording, "twang", paths, plot=False))
    if result.exit_code == 0:
        assert_fitted(result, paths)
    else:
        assert_refused(result, paths, True)


def test_output_folder_missing_or_a_folder(tmp_path):
    recording = tmp_path / "note.wav"
    sf.write(recording, note(22050), 22050)
    result = run("fit", str(recording), "-o", str(tmp_path / "nowhere" / "x.toml"))
    assert result.exit_code == 2 and "does not exist" in result.stderr
    (tmp_path / "dir.toml").mkdir()
    result = run("fit", str(recording), "-o", str(tmp_path / "dir.toml"))
    assert result.exit_code == 2 and "folder" in result.stderr
    result = run("fit", str(recording), "-o", str(tmp_path / "x.toml"), "--render", str(tmp_path / "x.mp3"))
    assert result.exit_code == 2 and not (tmp_path / "x.toml").exists()


def test_a_failed_write_leaves_every_output_as_it_was(tmp_path, monkeypatch):
    import barsynth.fitting.plots as plots

    recording = tmp_path / "note.wav"
    sf.write(recording, note(22050), 22050)
    paths = outputs(tmp_path, existing=True)

    def no_room(*args, **kwargs):
        raise OSError(28, "No space left on device")

    if not has_matplotlib():
        pytest.skip("matplotlib is not installed")
    monkeypatch.setattr(plots, "plot_fit", no_room)
    result = run(*fit_args(recording, "banded", paths, plot=True))
    assert_refused(result, paths, True, "no space left", "nothing written")


@pytest.mark.parametrize("model", MODELS)
def test_a_failing_fit_is_one_line(tmp_path, monkeypatch, model):
    import barsynth.fitting as fitting

    recording = tmp_path / "note.wav"
    sf.write(recording, note(22050), 22050)
    paths = outputs(tmp_path, existing=False)

    def broken(*args, **kwargs):
        raise np.linalg.LinAlgError("SVD did not converge")

    monkeypatch.setattr(fitting, "fit_recording", broken)
    assert_refused(run(*fit_args(recording, model, paths, plot=False)), paths, False, "could not fit",
                   "SVD did not converge")
