"""barsynth's bar frequencies against an independent finite-element oracle (scikit-fem,
tests/fem_oracle.py): the closed-form Timoshenko bar, the Euler–Bernoulli closed form and grid, and
the two-field Timoshenko grid, for every pair of ends, uniform and undercut."""

import numpy as np
import pytest
from fem_oracle import euler_bernoulli_fem, timoshenko_fem

from barsynth.physics import (
    BOUNDARY_CONDITIONS,
    bar_frequencies,
    shear_coefficient,
    timoshenko_frequencies,
)
from barsynth.physics.grid import grid_modes
from barsynth.physics.profiles import Profile
from barsynth.physics.timoshenko_grid import timoshenko_grid_modes

ROSEWOOD = dict(youngs_modulus_pa=20e9, density_kg_m3=1000.0, shear_modulus_pa=1.4e9)
ALUMINIUM = dict(youngs_modulus_pa=69e9, density_kg_m3=2700.0, shear_modulus_pa=26e9)
THICK_BARS = {
    # a 40 x 5 x 2 cm marimba bar, Cowper's kappa for nu = 0.3
    "rosewood": dict(ROSEWOOD, shear_coefficient=shear_coefficient(0.3), length_m=0.4, thickness_m=0.02),
    # h / L = 0.05
    "aluminium": dict(ALUMINIUM, shear_coefficient=shear_coefficient(0.33), length_m=0.3, thickness_m=0.015),
    # h / L = 0.3: most of its modes are above the cut-off (the second spectrum)
    "block": dict(ROSEWOOD, shear_coefficient=5 / 6, length_m=0.2, thickness_m=0.06),
    # h / L = 0.002
    "thin": dict(ALUMINIUM, shear_coefficient=5 / 6, length_m=0.5, thickness_m=0.001),
}
PROFILES = {
    "uniform": Profile(),
    "parabolic": Profile("parabolic", depth=0.6, width=0.6),
    "circular": Profile("circular", depth=0.6, width=0.6),
}
EULER_BERNOULLI = dict(youngs_modulus_pa=20e9, density_kg_m3=1000.0, length_m=0.4, thickness_m=0.02)
COUNT = 6


def test_the_oracle_has_converged():
    """Finer meshes change nothing that matters: Timoshenko to about 1e-10; Euler–Bernoulli to about
    1e-7 (the round-off of the Hermite elements' stiff h^4 matrices, largest for a cantilever's first mode)."""
    for bc in ("free-free", "clamped-free"):
        bar = dict(THICK_BARS["rosewood"], bc=bc, count=COUNT, profile=PROFILES["parabolic"])
        assert np.abs(timoshenko_fem(**bar) / timoshenko_fem(elements=96, **bar) - 1.0).max() < 1e-9
        bar = dict(EULER_BERNOULLI, bc=bc, count=COUNT, profile=PROFILES["circular"])
        assert np.abs(euler_bernoulli_fem(**bar) / euler_bernoulli_fem(elements=96, **bar) - 1.0).max() < 1e-6


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
@pytest.mark.parametrize("name", sorted(THICK_BARS))
def test_closed_form_timoshenko_matches_finite_elements(name, bc):
    bar = THICK_BARS[name]
    count = 10 if name == "block" else COUNT
    exact = timoshenko_frequencies(bc=bc, count=count, **bar)
    oracle = timoshenko_fem(bc=bc, count=count, **bar)
    assert np.abs(exact / oracle - 1.0).max() < 1e-6


def test_the_block_reaches_the_second_spectrum():
    bar = THICK_BARS["block"]
    cut_off_hz = np.sqrt(bar["shear_coefficient"] * bar["shear_modulus_pa"] * 12.0
                         / (bar["density_kg_m3"] * bar["thickness_m"] ** 2)) / (2.0 * np.pi)
    assert np.sum(timoshenko_fem(bc="clamped-free", count=10, **bar) > cut_off_hz) >= 5


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
def test_euler_bernoulli_closed_form_matches_finite_elements(bc):
    exact = bar_frequencies(bc=bc, count=COUNT, **EULER_BERNOULLI)
    oracle = euler_bernoulli_fem(bc=bc, count=COUNT, **EULER_BERNOULLI)
    assert np.abs(exact / oracle - 1.0).max() < 1e-7


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
@pytest.mark.parametrize("profile", ["parabolic", "circular"])
def test_euler_bernoulli_grid_matches_finite_elements_for_undercut_bars(profile, bc):
    bar = dict(EULER_BERNOULLI, bc=bc, count=COUNT, profile=PROFILES[profile])
    grid = grid_modes(width_m=0.05, **bar)
    oracle = euler_bernoulli_fem(**bar)
    assert np.abs(grid / oracle - 1.0).max() < 1e-4
    # the undercut matters: far from the uniform bar (a check that the oracle saw the profile)
    uniform = euler_bernoulli_fem(**dict(bar, profile=Profile()))
    assert np.abs(oracle / uniform - 1.0).max() > 0.05


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
@pytest.mark.parametrize("profile", sorted(PROFILES))
def test_timoshenko_grid_matches_finite_elements(profile, bc):
    bar = dict(THICK_BARS["rosewood"], bc=bc, count=COUNT, profile=PROFILES[profile])
    grid = timoshenko_grid_modes(width_m=0.05, points=250, extrapolate=True, **bar)
    oracle = timoshenko_fem(**bar)
    assert np.abs(grid / oracle - 1.0).max() < 1e-4
    # and it is a thick bar: Euler–Bernoulli on the same profile is far off
    keep = ("youngs_modulus_pa", "density_kg_m3", "length_m", "thickness_m", "bc", "count", "profile")
    thin = euler_bernoulli_fem(**{k: bar[k] for k in keep})
    assert np.abs(thin / oracle - 1.0).max() > 0.05


def test_a_free_bar_with_a_symmetric_and_an_antisymmetric_mode_0_1_percent_apart():
    # E / (kappa G) = 3.06, h / L = 0.112: modes 15 and 16 (above the cut-off) are 0.08 % apart
    bar = dict(youngs_modulus_pa=2.6e9 / 0.85, density_kg_m3=1000.0, shear_modulus_pa=1e9, shear_coefficient=1.0,
               length_m=1.0, thickness_m=0.1118544589701035, bc="free-free", count=18)
    exact, oracle = timoshenko_frequencies(**bar), timoshenko_fem(**bar)
    assert exact[15] / exact[14] - 1.0 < 1e-3
    assert np.abs(exact / oracle - 1.0).max() < 1e-8
