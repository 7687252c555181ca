"""The twang and fd fits recover the physical settings of barsynth's own renders (spec 7.4:
synthetic ground truth, with white noise 40 dB below the peak)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from barsynth.cli import main
from barsynth.fitting import fit_recording
from barsynth.models import get_model

RATE = 44100


def rendered(model: str, parameters: dict, seconds: float = 1.5, noise_db: float = -40.0) -> np.ndarray:
    x = get_model(model).render(parameters, duration_s=seconds, sample_rate=RATE, normalize=False,
                                dtype=np.float64, seed=5)  # (the fit renders its templates with other seeds)
    return x + np.random.default_rng(7).normal(0.0, np.max(np.abs(x)) * 10.0 ** (noise_db / 20.0), x.size)


def db(a: float, b: float) -> float:
    return 20.0 * math.log10(a / b)


TWANGS = [  # (the ruler, and how close its Q and gain shape come back)
    dict(material="acrylic", length_m=0.30, thickness_m=0.003, q=100.0, shape=1.5),
    dict(material="aluminium", length_m=0.40, thickness_m=0.002, q=250.0, shape=2.5, short_length_ratio=0.8,
         full_cantilever_gain=0.7, free_bar_gain=0.5),
    dict(material="maple", length_m=0.30, thickness_m=0.004, q=60.0, shape=1.2),
]


@pytest.mark.parametrize("truth", TWANGS, ids=lambda t: f"{t['material']}-{t['length_m']}")
def test_twang_fit_recovers_the_ruler(truth):
    x = rendered("twang", truth)
    fit = fit_recording(x, RATE, model="twang", options={"material": truth["material"],
                                                         "thickness_m": truth["thickness_m"]})
    p = fit.parameters
    full = {"short_length_ratio": 0.7, "full_cantilever_gain": 1.0, "short_cantilever_gain": 0.75,
            "free_bar_gain": 1.0, **truth}
    assert p["material"] == truth["material"] and p["thickness_m"] == truth["thickness_m"]
    assert abs(p["length_m"] / truth["length_m"] - 1.0) < 0.005  # frequencies: the length to 0.5 %
    assert abs(p["short_length_ratio"] - full["short_length_ratio"]) < 0.005
    assert abs(math.log(p["q"] / truth["q"])) < math.log(1.15)
    assert abs(p["shape"] / truth["shape"] - 1.0) < 0.12
    # the mixes against the full-length cantilever's (a common factor is the level's)
    for name in ("short_cantilever_gain", "free_bar_gain"):
        fitted = db(p[name], p["full_cantilever_gain"])
        assert abs(fitted - db(full[name], full["full_cantilever_gain"])) < 3.0, (name, fitted)
    # the measured partials are the ruler's modes: a cantilever mode alone to a cent, one the
    # analysis hears between a free-bar band and the cantilever mode beside it within tens of cents
    residuals = sorted(abs(m["cents"]) for m in fit.details["modes"])
    assert len(residuals) >= 3 and residuals[0] < 1.0 and residuals[-1] < 30.0, residuals


def test_fitted_twang_preset_renders(tmp_path):
    import soundfile as sf

    recording = tmp_path / "ruler.wav"
    sf.write(recording, rendered("twang", TWANGS[0], seconds=1.0), RATE)
    preset = tmp_path / "ruler.toml"
    result = CliRunner().invoke(main, ["fit", str(recording), "--model", "twang", "--set", "material=acrylic",
                                       "-o", str(preset), "--json"], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    out = tmp_path / "again.wav"
    result = CliRunner().invoke(main, ["render", "twang", "--preset", str(preset), "--duration", "0.5", "-o", str(out)],
                                catch_exceptions=False)
    assert result.exit_code == 0, result.output
    again, rate = sf.read(out)
    assert again.size == int(0.5 * rate) and np.max(np.abs(again)) > 0.1


FD_BARS = [  # (the bar, options the fit is given)
    (dict(material="aluminium", length_m=0.30, thickness_m=0.01, width_m=0.04, points=100), {}),
    (dict(material="steel", length_m=0.25, thickness_m=0.01, width_m=0.04, points=100), {}),
    (dict(material="rosewood", length_m=0.38, thickness_m=0.02, width_m=0.05, profile="parabolic",
          undercut_depth=0.5895, undercut_width=0.6, points=120, strike_position=0.42, pickup_position=0.25,
          sigma0_per_s=4.0, sigma1_m2_s=0.004), {"points": 120}),
    (dict(material="maple", length_m=0.33, thickness_m=0.02, width_m=0.05, profile="parabolic", undercut_depth=0.5,
          undercut_width=0.6, points=100, strike_position=0.42, pickup_position=0.0), {}),
]


@pytest.mark.parametrize("truth, given", FD_BARS, ids=lambda t: t.get("material", "") if isinstance(t, dict) else "")
def test_fd_fit_recovers_the_bar(truth, given):
    x = rendered("fd", truth, seconds=1.0)
    fit = fit_recording(x, RATE, model="fd", options={"material": truth["material"],
                                                      "thickness_m": truth["thickness_m"], **given})
    p = fit.parameters
    assert abs(p["length_m"] / truth["length_m"] - 1.0) < 5e-4
    assert abs(p.get("undercut_depth", 0.0) - truth.get("undercut_depth", 0.0)) < 0.01
    modes = fit.details["modes"]
    assert len(modes) >= 2
    assert max(abs(m["cents"]) for m in modes) < 0.2  # well below a cent
    # the losses: the rendered bar's own, so each partial's T60 in the resynthesis within 3 %
    assert abs(p["sigma0_per_s"] / truth.get("sigma0_per_s", 1.0) - 1.0) < 0.05
    assert abs(p["sigma1_m2_s"] / truth.get("sigma1_m2_s", 0.002) - 1.0) < 0.05
    errors = [r.t60_error for r in fit.comparison if r.t60_error is not None]
    assert len(errors) >= 2 and max(abs(e) for e in errors) < 0.03, errors
    # each residual is what `describe` says about the fitted bar at the recording's rate
    played = get_model("fd").describe(p, sample_rate=RATE)
    for m in modes:
        there = played[m["mode"] - 1].frequency_hz
        assert m["model_hz"] == pytest.approx(there, rel=1e-12)
        assert m["cents"] == pytest.approx(1200.0 * math.log2(there / m["frequency_hz"]), abs=1e-9)


def test_fd_json_reports_each_mode_residual(tmp_path):
    import json

    import soundfile as sf

    recording = tmp_path / "bar.wav"
    sf.write(recording, rendered("fd", FD_BARS[0][0], seconds=0.8), RATE, subtype="FLOAT")
    result = CliRunner().invoke(main, ["fit", str(recording), "--model", "fd", "--set", "material=aluminium",
                                       "--set", "thickness_m=0.01", "-o", str(tmp_path / "bar.toml"), "--json"],
                                catch_exceptions=False)
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["parameters"]["material"] == "aluminium" and report["warnings"] == []
    assert [m["mode"] for m in report["modes"]][:2] == [1, 2]
    assert all(abs(m["cents"]) < 0.2 for m in report["modes"])
    text = CliRunner().invoke(main, ["fit", str(recording), "--model", "fd", "--set", "material=aluminium",
                                     "-o", str(tmp_path / "bar2.toml")], catch_exceptions=False)
    assert "residual (cents)" in text.stdout
