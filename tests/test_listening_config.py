"""Listening-test configs: good ones load every clip, bad ones fail at once with one line."""

from __future__ import annotations

import numpy as np
import pytest
import soundfile

from barsynth.listening.config import ConfigError, load_test

GOOD = """
[test]
title = "Ruler realism"
sample_rate = 44100

[[clips]]
id = "real1"
file = "rec/real1.wav"

[[clips]]
id = "proposed1"
model = "twang"
preset = "plastic-30cm"
parameters = { q = 120 }
duration_s = 0.5
seed = 2

[[clips]]
id = "anchor1"
model = "farnell"
preset = "anchor"
duration_s = 0.5

[[mushra]]
clips = ["real1", "proposed1", "anchor1"]

[[ab]]
real = "real1"
synthetic = "proposed1"
label = "proposed"
"""


def write(tmp_path, text, wav=True):
    if wav:
        (tmp_path / "rec").mkdir(exist_ok=True)
        soundfile.write(tmp_path / "rec" / "real1.wav", 0.1 * np.sin(np.arange(22050) / 10), 22050)
    cfg = tmp_path / "test.toml"
    cfg.write_text(text)
    return cfg


def test_a_good_config_loads_files_and_renders_models(tmp_path):
    test = load_test(write(tmp_path, GOOD))
    assert test.title == "Ruler realism"
    assert set(test.clips) == {"real1", "proposed1", "anchor1"}
    # The 22.05 kHz recording is served at the test's 44.1 kHz like every clip, its tone unmoved.
    real = test.clips["real1"]
    assert real.sample_rate == 44100 and real.samples.size == 44100 and "resampled from 22050 Hz" in real.source
    spectrum = np.abs(np.fft.rfft(real.samples[2000:-2000] * np.hanning(real.samples.size - 4000), 1 << 20))
    assert np.argmax(spectrum) * 44100 / (1 << 20) == pytest.approx(22050 / (2 * np.pi * 10), abs=0.1)
    assert np.max(np.abs(real.samples)) == pytest.approx(0.1, rel=0.01)
    proposed = test.clips["proposed1"]
    assert proposed.sample_rate == 44100 and proposed.samples.size == 22050
    assert np.max(np.abs(proposed.samples)) == pytest.approx(10 ** (-1 / 20), rel=1e-6)
    assert test.pages == (("real1", "proposed1", "anchor1"),)
    assert test.ab_pairs[0].label == "proposed"


@pytest.mark.parametrize("change,needle", [
    (("[[mushra]]", "[[mushra]]\nshuffle = true"), "unknown key 'shuffle'"),
    (('file = "rec/real1.wav"', 'file = "rec/missing.wav"'), "no such file"),
    (("parameters = { q = 120 }", "parameters = { q = 5 }"), "q"),
    (('preset = "plastic-30cm"', 'preset = "rubber"'), "rubber"),
    (('model = "farnell"', 'model = "kazoo"'), "kazoo"),
    (('clips = ["real1", "proposed1", "anchor1"]', 'clips = ["real1", "ghost"]'), "unknown clip 'ghost'"),
    (('clips = ["real1", "proposed1", "anchor1"]', 'clips = ["real1"]'), "at least 2"),
    (('id = "anchor1"', 'id = "real1"'), "used twice"),
    (('id = "anchor1"', 'id = "bad id!"'), "needs an id"),
    (('synthetic = "proposed1"', 'synthetic = "real1"'), "with itself"),
    (("sample_rate = 44100", "sample_rate = 100"), "sample_rate"),
    (("sample_rate = 44100", "sample_rate = 384000"), "more than browsers play"),
    (("[test]", "[test\n"), "not valid TOML"),
    (('file = "rec/real1.wav"', 'file = "rec/real1.wav"\nseed = 3'), "only id and file"),
    (('label = "proposed"', 'label = "proposed"\n[[ab]]\nreal = "real1"\nsynthetic = "proposed1"'),
     "repeats the pair"),
])
def test_bad_configs_fail_at_start_up_with_one_line(tmp_path, change, needle):
    old, new = change
    assert old in GOOD
    with pytest.raises(ConfigError) as info:
        load_test(write(tmp_path, GOOD.replace(old, new, 1)))
    message = str(info.value)
    assert needle in message and "\n" not in message and "test.toml" in message


def test_unreadable_audio_is_a_config_error(tmp_path):
    cfg = write(tmp_path, GOOD)
    (tmp_path / "rec" / "real1.wav").write_text("not a wav")
    with pytest.raises(ConfigError, match="real1.wav"):
        load_test(cfg)


def test_missing_config(tmp_path):
    with pytest.raises(ConfigError, match="no such file"):
        load_test(tmp_path / "none.toml")


@pytest.mark.parametrize("samples,rate,needle", [
    (0.1 * np.ones(100), 4000, "sample rate 4000 Hz is not supported"),
    (np.zeros(1000), 22050, "is silent"),
    (np.full(1000, 1.5), 22050, "peaks at +3.5 dBFS"),
    (0.1 * np.ones(8000 * 121), 8000, "lasts 121.0 s"),
])
def test_recordings_a_browser_cannot_play_faithfully_are_refused(tmp_path, samples, rate, needle):
    cfg = write(tmp_path, GOOD)
    soundfile.write(tmp_path / "rec" / "real1.wav", samples, rate, subtype="FLOAT")
    with pytest.raises(ConfigError) as info:
        load_test(cfg)
    assert needle in str(info.value) and "real1.wav" in str(info.value)
