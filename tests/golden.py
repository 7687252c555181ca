"""The golden sounds: every shipped preset of every model, and a few non-default settings,
rendered raw; their hashes pin barsynth's sounds through any redesign.

``python tests/golden.py`` rewrites ``tests/golden_sounds.json`` (only when a sound changes
on purpose: say why in the commit). :mod:`tests.test_golden` checks against it.

Each sound is hashed exactly (SHA-256 of its float64 samples). NumPy's vectorised
``sin``/``exp`` may differ in the last bit between CPU families (AVX-512 SVML against
AVX2), so the file also records the CPU features it was made with and, per sound, a
fingerprint (the RMS of each 10 ms frame): on the same CPU features the hash must match
exactly; on other ones the fingerprints must match within 1e-9 relative (the RMS of each
frame, and a signed one that sees a flipped sign). "The same features" are those that can
change a float64 sample (:data:`FLOAT64_FEATURES`), not every feature of the CPU.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

GOLDEN_FILE = Path(__file__).with_name("golden_sounds.json")
DURATION_S = 0.3
SAMPLE_RATES = (44100, 48000)
FRAME_S = 0.010
CHANGE_AT_S = 0.1  # a parameter change while sounding, in the "glide" sounds

# Non-default settings per model: excitations, vibrato, slide, shapes, and glides
# (a change while the note sounds: the smoothing and cross-fading paths).
EXTRA_SETTINGS: dict[str, dict[str, dict[str, Any]]] = {
    "twang": {
        "vibrato": {"vibrato_rate_hz": 5.0, "vibrato_depth_hz": 30.0},
        "slide": {"slide": True, "slide_time_s": 0.1},
        "log-gains": {"gain_mapping": "log", "shape": 3.0, "free_bar_gain": 2.5},
    },
    "farnell": {
        "vibrato": {"vibrato_depth_hz": 2.0, "frequency_hz": 300.0},
    },
    "banded": {
        "bow": {"excitation": "bow", "bow_duration_s": 0.2},
        "pluck": {"excitation": "pluck", "strike_position": 0.3},
        "ring": {"tuning": "ratios", "shape": "ring", "mode_ratios": (1.0, 2.7, 5.1), "mode_t60s_s": (1.0, 0.5)},
        "geometry-eb": {"tuning": "geometry", "theory": "euler-bernoulli", "profile": "circular",
                        "undercut_depth": 0.4, "material": "maple"},
    },
    "allpass": {
        "pluck": {"excitation": "pluck", "strike_position": 0.3},
        "clamped": {"bc": "clamped-free", "strike_position": 0.9, "allpass_order": 8},
    },
    "fd": {
        "bow": {"excitation": "bow", "bow_duration_s": 0.2, "points": 40},
        "bow-explicit": {"excitation": "bow", "bow_solver": "explicit", "points": 40},
        "pluck": {"excitation": "pluck", "strike_position": 0.3, "points": 40},
        "undercut": {"profile": "parabolic", "undercut_depth": 0.5, "points": 50},
    },
}

# A change made 0.1 s into the note, per model (the voice's own smoothing or redesign).
GLIDES: dict[str, dict[str, Any]] = {
    "twang": {"length_m": 0.2, "q": 300.0, "level_db": -12.0},
    "farnell": {"frequency_hz": 500.0, "level_db": -6.0},
    "banded": {"mallet_hardness": 0.2, "q": 100.0, "level_db": -6.0},
    "allpass": {"q": 100.0, "level_db": -6.0},
    "fd": {"sigma0_per_s": 5.0, "level_db": -6.0},
    "ruler": {"q": 60.0, "level_db": -6.0},
    "kalimba": {"q": 500.0, "level_db": -6.0},
}


# The features that can change a float64 sample: NumPy's float64 exp/log/sin/cos dispatch on
# AVX512_SKX (SVML), AVX512F and AVX2 with FMA3, and numba compiles for the host, contracting
# a*b+c into one FMA where its kernels allow it. Others (AVX512FP16, AVX512_SPR, VNNI, ...)
# touch no float64 arithmetic: a newer CPU of the same family gives the very same samples.
FLOAT64_FEATURES = ("AVX512_SKX", "AVX512F", "AVX2", "FMA3", "AVX", "SSE42")


# Long tails, each its own duration: the kernels set what has decayed below 1e-30 (-600 dB) to
# exactly 0 (farnell, banded: no subnormal arithmetic), which the 0.3 s sounds never reach.
TAILS: dict[str, tuple[str, dict[str, Any], int, float]] = {
    "farnell/tail@22050": ("farnell", {}, 22050, 3.0),
    "banded/tail@22050": ("banded", {"q": 3.0}, 22050, 1.0),
    "banded/bow-tail@22050": ("banded", {"excitation": "bow", "bow_duration_s": 0.3}, 22050, 1.5),
}


def duration_of(name: str) -> float:
    """How long the golden sound ``name`` is (s)."""
    return TAILS[name][3] if name in TAILS else DURATION_S


def cpu_features() -> str:
    """The SIMD features NumPy dispatches on here, as one sorted string."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # NumPy 1.x
        from numpy.core._multiarray_umath import __cpu_features__ as features
    return ",".join(sorted(name for name, on in features.items() if on))


def float64_family(features: str) -> str:
    """Those of ``features`` (a :func:`cpu_features` string) that can change a float64 sample."""
    present = set(features.split(","))
    return ",".join(name for name in FLOAT64_FEATURES if name in present)


def sound_cases() -> list[tuple[str, str, dict[str, Any], int, dict[str, Any] | None]]:
    """``(name, model, parameters, sample_rate, change)`` for every golden sound."""
    from barsynth.models import model_names
    from barsynth.presets import preset_names, preset_parameters

    cases = []
    for model in model_names():
        settings = {f"preset:{p}": preset_parameters(model, p) for p in preset_names(model)}
        settings["default"] = {}
        settings.update(EXTRA_SETTINGS.get(model, {}))
        for label, params in settings.items():
            for rate in SAMPLE_RATES:
                cases.append((f"{model}/{label}@{rate}", model, params, rate, None))
        cases.append((f"{model}/glide@48000", model, {}, 48000, GLIDES[model]))
    cases += [(name, model, params, rate, None) for name, (model, params, rate, _) in TAILS.items()]
    return cases


def render_case(model: str, params: dict[str, Any], rate: int, change: dict[str, Any] | None,
                duration_s: float = DURATION_S) -> np.ndarray:
    """The raw float64 samples of one golden sound."""
    from barsynth.models import get_model

    m = get_model(model)
    if change is None:
        return m.render(params, duration_s=duration_s, sample_rate=rate, seed=7, normalize=False,
                        dtype=np.float64)
    voice = m.voice(params, sample_rate=rate, seed=7)
    voice.trigger()
    first = int(CHANGE_AT_S * rate)
    head = voice.process(first, dtype=np.float64)
    voice.set_parameters(**change)
    tail = voice.process(int(DURATION_S * rate) - first, dtype=np.float64)
    return np.concatenate([head, tail])


def frames(samples: np.ndarray, rate: int) -> np.ndarray:
    frame = int(FRAME_S * rate)
    return samples[: samples.size // frame * frame].reshape(-1, frame)


def fingerprint(samples: np.ndarray, rate: int) -> list[float]:
    """The RMS of each 10 ms frame."""
    return [float(x) for x in np.sqrt(np.mean(frames(samples, rate) ** 2, axis=1))]


def signed_fingerprint(samples: np.ndarray, rate: int) -> list[float]:
    """Each 10 ms frame's samples weighted by a ramp (sum of k x[k]): unlike the RMS, it sees
    a flipped sign or samples in another order."""
    usable = frames(samples, rate)
    return [float(x) for x in usable @ np.arange(1.0, usable.shape[1] + 1.0)]


def digest(samples: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(samples, dtype="<f8").tobytes()).hexdigest()


def measure_all() -> dict[str, Any]:
    sounds = {}
    for name, model, params, rate, change in sound_cases():
        samples = render_case(model, params, rate, change, duration_of(name))
        sounds[name] = {"sha256": digest(samples), "rms": fingerprint(samples, rate),
                        "ramp": signed_fingerprint(samples, rate)}
    return {"cpu_features": cpu_features(), "sounds": sounds}


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))
    GOLDEN_FILE.write_text(json.dumps(measure_all(), indent=1) + "\n")
    print(f"wrote {GOLDEN_FILE}")
