"""The bar on a grid (spec 1.6): convergence to spec 1.2, non-uniform profiles, the undercut tuner."""

from __future__ import annotations

import numpy as np
import pytest

from barsynth.errors import ParameterError
from barsynth.physics import BOUNDARY_CONDITIONS, bar_frequencies
from barsynth.physics.grid import bar_grid, grid_eigen, grid_modes
from barsynth.physics.profiles import Profile
from barsynth.physics.undercut import tune_undercut

ALUMINIUM = dict(youngs_modulus_pa=69e9, density_kg_m3=2700.0, length_m=0.3, thickness_m=0.01)
ROSEWOOD = dict(youngs_modulus_pa=12e9, density_kg_m3=850.0, length_m=0.38, thickness_m=0.02)


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
def test_the_grid_converges_to_the_closed_form_at_second_order(bc):
    exact = bar_frequencies(bc=bc, count=6, **ALUMINIUM)
    errors = [np.abs(grid_modes(bc=bc, count=6, points=points, extrapolate=False, **ALUMINIUM) / exact - 1)
              for points in (51, 101, 201)]
    for coarse, fine in zip(errors, errors[1:]):
        assert np.all(fine < coarse)
        assert np.all((coarse / fine > 3.5) & (coarse / fine < 4.5))  # halving dx quarters the error
    assert np.all(errors[-1] < 0.005)  # and it is already under 0.5 % at 201 points


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
def test_a_uniform_profile_reproduces_the_closed_form_to_a_hundredth_of_a_percent(bc):
    exact = bar_frequencies(bc=bc, count=8, **ALUMINIUM)
    found = grid_modes(bc=bc, count=8, profile=Profile("uniform"), **ALUMINIUM)
    assert np.max(np.abs(found / exact - 1)) < 1e-4
    assert np.max(np.abs(found / exact - 1)) < 1e-5  # (what it achieves)


def test_the_grid_keeps_mass_and_fixes_what_the_ends_fix():
    for bc, moving in (("free-free", 41), ("clamped-free", 40), ("pinned-pinned", 39)):
        grid = bar_grid(bc=bc, points=41, width_m=0.04, **ALUMINIUM)
        assert grid.mass.size == moving
    grid = bar_grid(bc="free-free", points=41, width_m=0.04, **ALUMINIUM)
    assert grid.mass.sum() == pytest.approx(2700.0 * 0.3 * 0.01 * 0.04)
    # a free bar's rigid motions cost no energy: K times a constant or a line is zero
    assert np.max(np.abs(grid.stiffness @ np.ones(41))) < 1e-6 * np.max(np.abs(grid.stiffness))
    assert np.max(np.abs(grid.stiffness @ grid.x_m)) < 1e-6 * np.max(np.abs(grid.stiffness))
    omega, shapes = grid_eigen(grid, 3)
    assert np.allclose(shapes.T @ (grid.mass[:, None] * shapes), np.eye(3), atol=1e-10)


def test_an_undercut_lowers_the_first_mode_most():
    uniform = grid_modes(bc="free-free", count=3, **ROSEWOOD)
    cut = grid_modes(bc="free-free", count=3, profile=Profile("parabolic", depth=0.5, width=0.6), **ROSEWOOD)
    assert cut[0] < 0.75 * uniform[0]
    assert cut[1] / cut[0] > uniform[1] / uniform[0] + 0.5


def test_a_sampled_profile_equals_the_same_shape_given_as_a_parabola():
    x = np.linspace(0.0, 1.0, 401)
    parabola = Profile("parabolic", depth=0.4, width=1.0)
    samples = Profile("samples", samples=tuple(parabola.relative_thickness(x, length_m=0.38, thickness_m=0.02)))
    a = grid_modes(bc="free-free", count=3, profile=parabola, points=101, extrapolate=False, **ROSEWOOD)
    b = grid_modes(bc="free-free", count=3, profile=samples, points=101, extrapolate=False, **ROSEWOOD)
    assert np.allclose(a, b, rtol=1e-4)


@pytest.mark.parametrize("kind", ["parabolic", "circular"])
def test_the_tuner_finds_the_depth_of_a_marimba_bar(kind):
    tuned = tune_undercut(target_ratio=4.0, kind=kind, undercut_width=0.6, **ROSEWOOD)
    assert tuned.ratios[1] == pytest.approx(4.0, abs=1e-6)
    assert 0.5 < tuned.profile.depth < 0.7
    assert 8.5 < tuned.ratios[2] < 10.0  # the third partial falls short of 10, as on real marimbas
    check = grid_modes(bc="free-free", count=2, profile=tuned.profile, points=250, **ROSEWOOD)  # another grid
    assert check[1] / check[0] == pytest.approx(4.0, abs=1e-4)
    xylophone = tune_undercut(target_ratio=3.0, kind=kind, **ROSEWOOD)
    assert xylophone.profile.depth < tuned.profile.depth


@pytest.mark.parametrize("call,needle", [
    (lambda: tune_undercut(target_ratio=2.0, **ROSEWOOD), "target_ratio = 2 cannot be reached"),
    (lambda: tune_undercut(target_ratio=40.0, **ROSEWOOD), "allowed: 2.7565 to"),
    (lambda: tune_undercut(target_ratio=float("nan"), **ROSEWOOD), "target_ratio = nan is not a number"),
    (lambda: Profile("wavy"), "profile = 'wavy' is unknown"),
    (lambda: Profile("parabolic", depth=1.0), "undercut_depth = 1.0 is out of range"),
    (lambda: Profile("samples", samples=(1.0,)), "profile_samples has 1 values"),
    (lambda: Profile("samples", samples=(1.0, 0.0)), "value 2 = 0.0 is out of range"),
    (lambda: bar_grid(bc="free-free", points=4, width_m=0.04, **ALUMINIUM), "points = 4 is out of range"),
    (lambda: bar_grid(bc="free-free", points=5000, width_m=0.04, **ALUMINIUM), "points = 5000 is out of range"),
    (lambda: grid_modes(bc="free-free", count=2, points=400, **ALUMINIUM), "points = 400 is out of range"),
    (lambda: grid_modes(bc="free-free", count=0, **ALUMINIUM), "count = 0 is out of range"),
    (lambda: bar_grid(bc="free-free", points=20, width_m=0.04, **{**ALUMINIUM, "thickness_m": 0.0}),
     "thickness_m = 0"),
    (lambda: bar_grid(bc="free-free", points=20, width_m=0.04, **{**ALUMINIUM, "length_m": float("nan")}),
     "length_m = nan"),
    (lambda: tune_undercut(count=0, **ROSEWOOD), "count = 0 is out of range"),
    (lambda: grid_modes(bc="glued-free", count=2, **ALUMINIUM), "bc = 'glued-free' is unknown"),
])
def test_bad_input_is_one_line(call, needle):
    with pytest.raises(ParameterError) as info:
        call()
    assert needle in str(info.value) and "\n" not in str(info.value)
