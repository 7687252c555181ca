"""docs/listening/physical-twang.toml: one MUSHRA page of the paper's twang, Farnell's, the
anchor and the physical ruler, loaded and rendered exactly as `barsynth listen serve` does."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from barsynth.listening.config import load_test

CONFIG = Path(__file__).resolve().parents[1] / "docs" / "listening" / "physical-twang.toml"
SAMPLE_RATE = 48000
DURATION_S = 2.0
PHYSICAL = "ruler"
KINDS = {  # kind of clip -> (model, presets that make it that kind)
    "paper twang": ("twang", {"plastic-30cm", "steel-30cm"}),
    "farnell": ("farnell", {"patch-default"}),
    "anchor": ("farnell", {"anchor"}),
    "physical twang": (PHYSICAL, {"plastic-ruler-wooden-desk", "steel-ruler-metal-desk"}),
}


def _kind(entry: dict) -> str:
    for kind, (model, presets) in KINDS.items():
        if entry["model"] == model and entry.get("preset") in presets:
            return kind
    raise AssertionError(f"clip {entry['id']} is none of {sorted(KINDS)}")


@pytest.fixture(scope="module")
def doc():
    return tomllib.loads(CONFIG.read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def test(doc):
    return load_test(CONFIG)


def test_one_page_holds_every_kind_at_comparable_settings(doc):
    entries = {entry["id"]: entry for entry in doc["clips"]}
    assert doc["test"]["sample_rate"] == SAMPLE_RATE
    assert len(doc["mushra"]) == 1
    page = doc["mushra"][0]["clips"]
    assert set(page) == set(entries)
    kinds = [_kind(entries[clip_id]) for clip_id in page]
    assert set(kinds) == set(KINDS)
    physical = {entries[c]["preset"] for c, k in zip(page, kinds) if k == "physical twang"}
    assert physical == KINDS["physical twang"][1]
    assert all(entry["duration_s"] == DURATION_S and "file" not in entry for entry in entries.values())
    # No soundfont sample stands in for a recording: every clip is rendered by a model.
    assert "soundfont" not in CONFIG.read_text(encoding="utf-8").split("[test]")[1]


def test_every_clip_renders_two_seconds_at_minus_one_dbfs(test, doc):
    assert test.pages == (tuple(doc["mushra"][0]["clips"]),)
    for entry in doc["clips"]:
        clip = test.clips[entry["id"]]
        assert clip.source == f"model {entry['model']} preset {entry['preset']}"
        assert clip.sample_rate == SAMPLE_RATE
        assert clip.samples.size == int(DURATION_S * SAMPLE_RATE)
        assert np.all(np.isfinite(clip.samples))
        assert np.max(np.abs(clip.samples)) == pytest.approx(10 ** (-1 / 20), rel=1e-6)
        # A ringing sound, not a lone click: the first half second holds far more energy than a
        # single full-scale sample (whose RMS over 0.5 s would be 0.0041).
        head = clip.samples[: SAMPLE_RATE // 2].astype(np.float64)
        assert np.sqrt(np.mean(head ** 2)) > 0.02


def test_the_clips_are_different_sounds(test):
    spectra = {}
    for clip_id, clip in test.clips.items():
        spectrum = np.abs(np.fft.rfft(clip.samples[: SAMPLE_RATE // 2].astype(np.float64)))
        spectra[clip_id] = spectrum / np.linalg.norm(spectrum)
    ids = sorted(spectra)
    for i, a in enumerate(ids):
        for b in ids[i + 1:]:
            assert float(spectra[a] @ spectra[b]) < 0.99, (a, b)
