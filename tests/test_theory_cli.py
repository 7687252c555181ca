"""`barsynth modes` and `barsynth tune-undercut` in either bar theory: options, JSON, bad input (spec 8)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from barsynth.cli import main
from barsynth.physics import bar_frequencies, lambdas, material, shear_coefficient
from barsynth.physics.grid import grid_modes
from barsynth.physics.profiles import Profile
from barsynth.physics.timoshenko_grid import timoshenko_grid_modes

ROSEWOOD_BAR = ["--material", "rosewood", "--length", "0.4", "--thickness", "0.02", "--width", "0.05",
                "--bc", "free-free"]
CUT = ["--profile", "parabolic", "--undercut-depth", "0.59", "--undercut-width", "0.6"]


def run(*args: str):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def modes_json(*args: str) -> dict:
    r = run("modes", *args, "--json")
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout)


def test_default_theory_keeps_the_old_output():
    data = modes_json("--material", "acrylic", "--length", "0.3", "--thickness", "0.003", "--bc", "free-free")
    assert data["theory"] == "euler-bernoulli" and data["profile"] == "uniform"
    expected = bar_frequencies(youngs_modulus_pa=3.2e9, density_kg_m3=1180.0, length_m=0.3, thickness_m=0.003,
                               bc="free-free", count=6)
    assert data["frequencies_hz"] == expected.tolist() and data["lambdas"] == lambdas("free-free", 6).tolist()
    assert "shear_modulus_pa" not in data and "cents_from_euler_bernoulli" not in data
    text = run("modes", "--material", "acrylic", "--length", "0.3", "--thickness", "0.003", "--bc", "free-free").stdout
    assert text.splitlines()[1].split() == ["n", "lambda", "frequency", "(Hz)", "ratio"]
    assert "4.7300" in text and "cents" not in text


def test_timoshenko_undercut_bar_from_the_material_table():
    data = modes_json(*ROSEWOOD_BAR, *CUT, "--theory", "timoshenko", "--count", "4")
    wood = material("rosewood")
    assert data["theory"] == "timoshenko" and data["profile"] == {"kind": "parabolic", "undercut_depth": 0.59,
                                                                   "undercut_width": 0.6}
    assert data["shear_modulus_pa"] == wood.shear_modulus_pa and data["shear_coefficient"] == 5 / 6
    assert data["poisson_ratio"] is None
    bar = dict(youngs_modulus_pa=20e9, density_kg_m3=1000.0, length_m=0.4, thickness_m=0.02, width_m=0.05,
               bc="free-free", count=4, profile=Profile("parabolic", depth=0.59, width=0.6))
    thick = timoshenko_grid_modes(shear_modulus_pa=wood.shear_modulus_pa, shear_coefficient=5 / 6, **bar)
    np.testing.assert_allclose(data["frequencies_hz"], thick, rtol=1e-12)
    np.testing.assert_allclose(data["ratios"], thick / thick[0], rtol=1e-12)
    cents = 1200 * np.log2(thick / grid_modes(**bar))
    np.testing.assert_allclose(data["cents_from_euler_bernoulli"], cents, rtol=1e-9)
    assert all(c < 0 for c in data["cents_from_euler_bernoulli"])
    assert 3.8 < data["ratios"][1] < 3.9  # tuned to 4 in Euler-Bernoulli, it really rings flat
    text = run("modes", *ROSEWOOD_BAR, *CUT, "--theory", "timoshenko").stdout
    assert "vs E-B (cents)" in text and "G = 1.33e+09 Pa, kappa = 0.8333" in text and "parabolic undercut" in text


def test_shear_options_override_the_material():
    base = ["--material", "aluminium", "--length", "0.3", "--thickness", "0.01", "--bc", "free-free", *CUT,
            "--theory", "timoshenko", "--count", "3"]
    table = modes_json(*base)
    assert table["poisson_ratio"] == 0.33
    assert table["shear_coefficient"] == pytest.approx(shear_coefficient(0.33))
    assert table["shear_modulus_pa"] == pytest.approx(69e9 / 2.66)
    nu = modes_json(*base, "--poisson", "0.25")
    assert nu["shear_modulus_pa"] == pytest.approx(69e9 / 2.5) and nu["shear_coefficient"] == pytest.approx(
        shear_coefficient(0.25))
    assert nu["frequencies_hz"][2] > table["frequencies_hz"][2]  # a smaller nu: stiffer in shear
    g = modes_json(*base, "--shear-modulus", "2e10")
    assert g["shear_modulus_pa"] == 2e10 and g["shear_coefficient"] == 5 / 6 and g["poisson_ratio"] is None
    kappa = modes_json(*base, "--shear-modulus", "2e10", "--shear-coefficient", "0.7")
    assert kappa["shear_coefficient"] == 0.7 and kappa["frequencies_hz"][2] < g["frequencies_hz"][2]
    constants = modes_json("--youngs-modulus", "69e9", "--density", "2700", "--length", "0.3", "--thickness", "0.01",
                           "--bc", "free-free", *CUT, "--theory", "timoshenko", "--poisson", "0.33", "--count", "3")
    np.testing.assert_allclose(constants["frequencies_hz"], table["frequencies_hz"], rtol=1e-12)


def test_uniform_timoshenko_bar_in_the_cli():
    timoshenko = pytest.importorskip("barsynth.physics.timoshenko")
    data = modes_json(*ROSEWOOD_BAR, "--theory", "timoshenko", "--count", "5")
    wood = material("rosewood")
    expected = timoshenko.timoshenko_frequencies(youngs_modulus_pa=20e9, density_kg_m3=1000.0,
                                                 shear_modulus_pa=wood.shear_modulus_pa, shear_coefficient=5 / 6,
                                                 length_m=0.4, thickness_m=0.02, bc="free-free", count=5)
    np.testing.assert_allclose(data["frequencies_hz"], expected, rtol=1e-12)
    assert data["cents_from_euler_bernoulli"][1] < -20 and data["cents_from_euler_bernoulli"][4] < -100


def assert_one_line_error(result, *needles: str) -> None:
    assert result.exit_code == 2, result.output
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    for needle in needles:
        assert needle.lower() in result.stderr.lower(), (needle, result.stderr)


@pytest.mark.parametrize("args,needles", [
    (["--theory", "timoshenko", "--poisson", "0.3", "--shear-modulus", "1e9"], ["given together"]),
    (["--poisson", "0.3"], ["poisson_ratio = 0.3 given with theory = euler-bernoulli", "--theory timoshenko"]),
    (["--shear-coefficient", "0.8"], ["shear_coefficient = 0.8 given with theory = euler-bernoulli"]),
    (["--undercut-depth", "0.3"], ["undercut_depth = 0.3 given with profile = uniform"]),
    (["--profile", "uniform", "--undercut-width", "0.5"], ["undercut_width = 0.5 given with profile = uniform"]),
    (["--profile", "parabolic"], ["undercut_depth is missing", "fraction"]),
    (["--profile", "parabolic", "--undercut-depth", "1.5"], ["undercut_depth = 1.5 is out of range", "0 to 0.98"]),
    (["--profile", "wavy"], ["profile = 'wavy'", "uniform, parabolic, circular"]),
    (["--theory", "thick"], ["theory = 'thick'", "euler-bernoulli, timoshenko"]),
    (["--theory", "timoshenko", "--poisson", "0.7"], ["poisson_ratio = 0.7 is out of range", "< 0.5"]),
    (["--theory", "timoshenko", "--shear-coefficient", "0"], ["shear_coefficient = 0", "0.5 to 1"]),
    (["--theory", "timoshenko", "--shear-coefficient", "1e-9"], ["shear_coefficient = 1e-09", "0.5 to 1"]),
    (["--theory", "timoshenko", "--shear-modulus", "-5"], ["shear_modulus_pa", "-5"]),
])
def test_modes_bad_combinations(args, needles):
    assert_one_line_error(run("modes", *ROSEWOOD_BAR, *args), *needles)


@pytest.mark.parametrize("length,thickness", [("1e300", "1e299"), ("1e-300", "1e-301")])
@pytest.mark.parametrize("cut", [[], CUT])
def test_sizes_outside_the_float_range_get_one_line(length, thickness, cut):
    """(They had raised OverflowError and ZeroDivisionError: h^2 and L^2 alone leave the float range.)"""
    r = run("modes", "--material", "steel", "--bc", "free-free", "--length", length, "--thickness", thickness,
            "--theory", "timoshenko", *cut)
    assert_one_line_error(r, "length_m")


def test_the_shear_coefficient_range_is_the_tables():
    from barsynth.models import rows
    from barsynth.physics import theory, timoshenko

    row = rows.theory_parameters()[2]
    assert (row.minimum, row.maximum) == timoshenko.SHEAR_COEFFICIENT_RANGE and rows.THEORIES == theory.THEORIES


def test_timoshenko_without_shear_is_refused():
    r = run("modes", "--youngs-modulus", "20e9", "--density", "1000", "--length", "0.4", "--thickness", "0.02",
            "--bc", "free-free", "--theory", "timoshenko")
    assert_one_line_error(r, "shear_modulus_pa is missing", "--shear-modulus PA or --poisson NU")


def test_tune_undercut_in_timoshenko():
    r = run("tune-undercut", "--material", "rosewood", "--length", "0.4", "--thickness", "0.02", "--width", "0.05",
            "--theory", "timoshenko", "--json")
    assert r.exit_code == 0, r.output
    found = json.loads(r.stdout)
    assert found["theory"] == "timoshenko" and found["ratios"][1] == pytest.approx(4.0, abs=1e-5)
    assert found["f2_over_f1"] == found["ratios"][1] and found["f3_over_f1"] == found["ratios"][2]
    assert 8.8 < found["f3_over_f1"] < 9.4 and 0.6 < found["undercut_depth"] < 0.65
    assert found["shear_modulus_pa"] == material("rosewood").shear_modulus_pa
    text = run("tune-undercut", "--material", "rosewood", "--length", "0.4", "--thickness", "0.02",
               "--width", "0.05").stdout
    assert "euler-bernoulli" in text and "f2/f1 = 4.0000, f3/f1 = 9.34" in text
    assert_one_line_error(run("tune-undercut", "--material", "rosewood", "--length", "0.4", "--thickness", "0.02",
                              "--poisson", "0.3"), "given with theory = euler-bernoulli")
    assert_one_line_error(run("tune-undercut", "--youngs-modulus", "20e9", "--density", "1000", "--length", "0.4",
                              "--thickness", "0.02", "--theory", "timoshenko"), "shear_modulus_pa is missing")


def test_the_fd_bar_tune_undercut_offers_rings_as_tuned():
    """The JSON's fd_parameters (the "hear it" line) carry the theory and the shear stiffness: the
    fd model they describe rings at the target ratio (it had rung 4.104 with fd's default G)."""
    from barsynth.models import get_model

    r = run("tune-undercut", "--material", "rosewood", "--length", "0.4", "--thickness", "0.02", "--width", "0.05",
            "--theory", "timoshenko", "--json")
    settings = json.loads(r.stdout)["fd_parameters"]
    assert settings["theory"] == "timoshenko" and settings["shear_modulus_pa"] == pytest.approx(1.33e9)
    modes = get_model("fd").describe({**settings, "points": 160}, sample_rate=44100)
    assert modes[1].frequency_hz / modes[0].frequency_hz == pytest.approx(4.0, rel=2e-3)


def test_tune_undercut_with_g_alone_takes_a_rectangle_s_kappa():
    from barsynth.physics.undercut import tune_undercut

    bar = {"youngs_modulus_pa": 20e9, "density_kg_m3": 1000.0, "length_m": 0.4, "thickness_m": 0.02, "width_m": 0.05,
           "theory": "timoshenko", "shear_modulus_pa": 1.33e9}
    alone = tune_undercut(**bar)
    given = tune_undercut(**bar, shear_coefficient=5 / 6)
    assert alone.profile.depth == given.profile.depth and alone.ratios[1] == pytest.approx(4.0, abs=1e-9)
