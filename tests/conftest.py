"""Shared fixtures: a small listening test on disk (real WAV files through soundfile);
a real JACK server for the live-audio tests (``jack_server``, from tests/jack_server.py);
Hypothesis's settings for the whole suite.

Hypothesis runs derandomized, with no example database, so every run of the suite tries
the same examples: a run never fails by luck, and what it finds is found again on any
machine. Every failure it ever found stays as an explicit ``@example`` on its test. To
hunt for new ones, run with ``BARSYNTH_HYPOTHESIS=explore`` (random examples, remembered in .hypothesis/),
and turn what fails into an ``@example``.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
import soundfile
from hypothesis import HealthCheck, settings
from jack_server import jack_daemon, jack_server  # noqa: F401 (a JACK server for the live-audio tests)

settings.register_profile("repeatable", derandomize=True, database=None, deadline=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("explore", derandomize=False, deadline=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("BARSYNTH_HYPOTHESIS", "repeatable"))

LISTENING_TEST = """
[test]
title = "Ruler realism"
sample_rate = 22050

[[clips]]
id = "real1"
file = "rec/real1.wav"

[[clips]]
id = "real2"
file = "rec/real2.wav"

[[clips]]
id = "proposed1"
file = "rec/proposed1.wav"

[[clips]]
id = "anchor1"
model = "farnell"
preset = "anchor"
duration_s = 0.4

[[mushra]]
clips = ["real1", "proposed1", "anchor1"]

[[mushra]]
clips = ["real2", "proposed1"]

[[ab]]
real = "real1"
synthetic = "proposed1"
label = "proposed"

[[ab]]
real = "real2"
synthetic = "anchor1"
label = "anchor"
"""

# Each recording is a decaying tone of its own pitch, so a test can tell clips apart by ear... or by FFT.
CLIP_TONES_HZ = {"real1": 440.0, "real2": 660.0, "proposed1": 550.0}


def tone(frequency_hz: float, rate: int = 22050, seconds: float = 0.4) -> np.ndarray:
    t = np.arange(int(rate * seconds)) / rate
    return 0.5 * np.sin(2 * np.pi * frequency_hz * t) * np.exp(-4 * t)


@pytest.fixture(autouse=True, scope="session")
def _design_cache_of_the_session(tmp_path_factory):
    """The program keeps designs on disk (barsynth.designcache): the programs the suite runs
    use a folder of the session's, never the user's cache."""
    old = os.environ.get("BARSYNTH_CACHE_DIR")
    os.environ["BARSYNTH_CACHE_DIR"] = str(tmp_path_factory.mktemp("design-cache"))
    yield
    if old is None:
        os.environ.pop("BARSYNTH_CACHE_DIR", None)
    else:
        os.environ["BARSYNTH_CACHE_DIR"] = old


@pytest.fixture
def listening_config(tmp_path):
    """A listening test with 2 MUSHRA pages and 2 A/B pairs; returns the TOML path."""
    (tmp_path / "rec").mkdir()
    for clip, frequency in CLIP_TONES_HZ.items():
        soundfile.write(tmp_path / "rec" / f"{clip}.wav", tone(frequency), 22050, subtype="PCM_16")
    config = tmp_path / "test.toml"
    config.write_text(LISTENING_TEST)
    return config
