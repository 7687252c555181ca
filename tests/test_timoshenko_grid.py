"""The staggered two-field (Timoshenko) grid: exact where a closed form exists, Euler–Bernoulli
when thin, energy-consistent, second order."""

import math

import numpy as np
import pytest

from barsynth.errors import ParameterError
from barsynth.physics import bar_frequencies
from barsynth.physics.grid import grid_eigen
from barsynth.physics.profiles import Profile
from barsynth.physics.timoshenko_grid import timoshenko_grid, timoshenko_grid_modes

ROSEWOOD = dict(youngs_modulus_pa=20e9, density_kg_m3=1000.0, shear_modulus_pa=1.4e9, shear_coefficient=5 / 6)
BCS = ("free-free", "clamped-free", "clamped-clamped", "pinned-pinned", "clamped-pinned")


def pinned_pinned_hz(n, *, youngs_modulus_pa, density_kg_m3, shear_modulus_pa, shear_coefficient, length_m,
                     thickness_m, width_m=0.05):
    """Mode n of a simply supported Timoshenko beam: w = sin(k x), k = n pi / L, the lower root of the
    2 x 2 dispersion determinant (Timoshenko 1921)."""
    area, inertia = width_m * thickness_m, width_m * thickness_m ** 3 / 12.0
    k = n * math.pi / length_m
    ga = shear_coefficient * shear_modulus_pa * area
    ei = youngs_modulus_pa * inertia
    a = density_kg_m3 ** 2 * area * inertia
    b = -(density_kg_m3 * area * (ei * k ** 2 + ga) + density_kg_m3 * inertia * ga * k ** 2)
    c = ga * k ** 2 * ei * k ** 2
    w2 = 2.0 * c / (-b + math.sqrt(b * b - 4.0 * a * c))
    return math.sqrt(w2) / (2.0 * math.pi)


@pytest.mark.parametrize("thickness_m", [0.04, 0.02, 0.004])
def test_pinned_pinned_matches_the_closed_form(thickness_m):
    bar = dict(ROSEWOOD, length_m=0.4, thickness_m=thickness_m)
    found = timoshenko_grid_modes(bc="pinned-pinned", count=6, width_m=0.05, **bar)
    exact = np.array([pinned_pinned_hz(n, **bar) for n in range(1, 7)])
    assert np.abs(found / exact - 1.0).max() < 1e-7


@pytest.mark.parametrize("bc", BCS)
def test_a_thin_bar_rings_as_euler_bernoulli(bc):
    bar = dict(youngs_modulus_pa=20e9, density_kg_m3=1000.0, length_m=0.4, thickness_m=0.4e-4)
    thin = timoshenko_grid_modes(bc=bc, count=5, shear_modulus_pa=1.4e9, shear_coefficient=5 / 6,
                                 **{k: v for k, v in bar.items() if k != "shear_modulus_pa"})
    assert np.abs(thin / bar_frequencies(bc=bc, count=5, **bar) - 1.0).max() < 2e-5


@pytest.mark.parametrize("bc", BCS)
def test_shear_lowers_every_mode_more_the_higher_it_is(bc):
    bar = dict(ROSEWOOD, length_m=0.4, thickness_m=0.02)
    thick = timoshenko_grid_modes(bc=bc, count=5, width_m=0.05, **bar)
    thin = bar_frequencies(bc=bc, count=5, youngs_modulus_pa=20e9, density_kg_m3=1000.0, length_m=0.4,
                           thickness_m=0.02)
    flat_cents = 1200.0 * np.log2(thin / thick)
    assert np.all(flat_cents > 10.0) and np.all(np.diff(flat_cents) > 0.0)


def test_the_error_falls_as_dx_squared():
    bar = dict(ROSEWOOD, length_m=0.4, thickness_m=0.02, width_m=0.05, bc="pinned-pinned", count=3)
    exact = np.array([pinned_pinned_hz(n, **{k: v for k, v in bar.items() if k not in ("bc", "count")})
                      for n in range(1, 4)])
    errors = [np.abs(timoshenko_grid_modes(points=p, extrapolate=False, **bar) / exact - 1.0) for p in (51, 101)]
    assert np.all((3.8 < errors[0] / errors[1]) & (errors[0] / errors[1] < 4.2))


def test_rigid_motions_store_no_energy_and_shapes_are_mass_normalised():
    grid = timoshenko_grid(bc="free-free", points=30, length_m=0.4, thickness_m=0.02, width_m=0.05,
                           profile=Profile("parabolic", depth=0.5, width=0.6), **ROSEWOOD)
    for motion in grid.rigid_motions():
        assert np.abs(grid.stiffness @ motion).max() < 1e-6 * np.abs(grid.stiffness).max()
    assert np.all(np.linalg.eigvalsh(grid.stiffness) > -1e-6 * np.abs(grid.stiffness).max())
    omega, shapes = grid_eigen(grid, 4)
    assert np.allclose(shapes.T @ (grid.mass[:, None] * shapes), np.eye(4), atol=1e-6)
    assert np.allclose(shapes.T @ grid.stiffness @ shapes / omega ** 2, np.eye(4), atol=1e-6)
    assert not np.any(np.triu(grid.stiffness, 3))  # pentadiagonal: the FD step solves it


def test_a_deflection_is_read_at_the_deflection_nodes():
    grid = timoshenko_grid(bc="clamped-free", points=11, length_m=0.4, thickness_m=0.02, width_m=0.05, **ROSEWOOD)
    index, weight = grid.weights_at(0.25)  # between nodes 2 and 3, of which node 0 is fixed
    assert index.tolist() == [grid.w_index[1], grid.w_index[2]] and weight.tolist() == [0.5, 0.5]
    assert grid.weights_at(0.0)[0].size == 0


def test_bad_input_names_the_parameter():
    with pytest.raises(ParameterError, match="shear_modulus_pa"):
        timoshenko_grid_modes(bc="free-free", count=3, length_m=0.4, thickness_m=0.02, youngs_modulus_pa=20e9,
                              density_kg_m3=1000.0, shear_modulus_pa=-1.0, shear_coefficient=0.8)
    with pytest.raises(ParameterError, match="shear_coefficient"):
        timoshenko_grid_modes(bc="free-free", count=3, length_m=0.4, thickness_m=0.02, youngs_modulus_pa=20e9,
                              density_kg_m3=1000.0, shear_modulus_pa=1e9, shear_coefficient=1.5)
