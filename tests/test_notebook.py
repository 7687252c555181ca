"""Hearing a sound in a notebook (barsynth.notebook): the player holds the very samples."""

from __future__ import annotations

import io

import numpy as np
import pytest
import soundfile

from barsynth.errors import ParameterError
from barsynth.models import get_model
from barsynth.notebook import audio, hear

RATE = 48000


def played(player) -> tuple[np.ndarray, int]:
    """The samples and rate IPython's player will play (it writes 16-bit PCM WAV)."""
    from IPython.display import Audio

    assert isinstance(player, Audio)
    samples, rate = soundfile.read(io.BytesIO(player.data), dtype="float64", always_2d=True)
    return samples.T, rate


def test_audio_plays_the_samples_at_their_rate():
    t = np.arange(RATE // 2) / RATE
    x = 0.5 * np.sin(2 * np.pi * 440.0 * t)
    samples, rate = played(audio(x, RATE, normalize=False))
    assert rate == RATE and samples.shape == (1, x.size)
    assert np.max(np.abs(samples[0] - x)) < 2.0 / 32768  # 16-bit rounding


def test_audio_normalises_by_default_and_keeps_channels():
    x = np.stack([0.01 * np.ones(1000), -0.02 * np.ones(1000)])
    samples, rate = played(audio(x, 44100))
    assert rate == 44100 and samples.shape == (2, 1000)
    assert np.max(np.abs(samples)) == pytest.approx(1.0, abs=1e-4)
    assert samples[0, 0] == pytest.approx(0.5, abs=1e-4)


def test_hear_is_the_models_render():
    player = hear("twang", "steel-30cm", duration_s=0.5)
    samples, rate = played(player)
    offline = get_model("twang").render(get_model("twang").preset("steel-30cm"), duration_s=0.5, sample_rate=RATE,
                                        dtype=np.float64)
    assert rate == RATE and samples.shape[1] == offline.size
    assert np.max(np.abs(samples[0] - offline / np.max(np.abs(offline)))) < 2.0 / 32768


@pytest.mark.parametrize("samples,rate,normalize,words", [
    (np.array([0.0, np.nan]), RATE, True, "NaN"),
    (np.zeros((3, 4, 5)), RATE, True, "shape"),
    (np.zeros(0), RATE, True, "at least one sample"),
    (np.ones(10) * 2.0, RATE, False, "peaks at 2"),
    (np.zeros(10), 1000, True, "sample_rate"),
    ("loud", RATE, True, "samples"),
])
def test_bad_input_is_one_line(samples, rate, normalize, words):
    with pytest.raises(ParameterError) as info:
        audio(samples, rate, normalize=normalize)
    assert words in str(info.value) and "\n" not in str(info.value) and "allowed" in str(info.value)


def test_without_ipython_it_says_how_to_install_it(monkeypatch):
    import barsynth.extras as extras
    from barsynth.extras import MissingExtraError

    monkeypatch.setattr(extras, "missing_modules", lambda extra: ["IPython"])
    with pytest.raises(MissingExtraError, match=r"pip install 'barsynth\[notebook\]'"):
        audio(np.zeros(10), RATE)
