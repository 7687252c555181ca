"""Closed-form Timoshenko frequencies of uniform bars: Euler–Bernoulli when thin, the simply supported
bar's exact frequencies through the cut-off, Cowper's shear coefficient, and clear errors."""

import math

import numpy as np
import pytest

from barsynth.errors import ParameterError
from barsynth.physics import (
    BOUNDARY_CONDITIONS,
    bar_frequencies,
    lambdas,
    shear_coefficient,
    timoshenko_frequencies,
)

ROSEWOOD = dict(youngs_modulus_pa=20e9, density_kg_m3=1000.0, shear_modulus_pa=1.4e9, shear_coefficient=5 / 6)
ALUMINIUM = dict(youngs_modulus_pa=69e9, density_kg_m3=2700.0, shear_modulus_pa=26e9, shear_coefficient=0.85)


def euler_bernoulli(bar, bc, count):
    keep = ("youngs_modulus_pa", "density_kg_m3", "length_m", "thickness_m")
    return bar_frequencies(bc=bc, count=count, **{k: bar[k] for k in keep})


def simply_supported_hz(count, *, youngs_modulus_pa, density_kg_m3, shear_modulus_pa, shear_coefficient, length_m,
                        thickness_m):
    """The lowest ``count`` modes of a pinned-pinned Timoshenko bar (Timoshenko 1921): for each
    ``k = n pi / L`` the two roots in ``w^2`` of ``rho^2 A I w^4 - rho (A (E I k^2 + G') + I G' k^2) w^2 +
    G' E I k^4 = 0``, ``G' = kappa G A`` (the flexural and the second-spectrum mode of shape
    ``sin(k x)``); ``n = 0`` gives the cut-off ``kappa G A / (rho I)`` alone (a uniform rotation)."""
    area, inertia = thickness_m, thickness_m**3 / 12.0  # per metre of width
    ga, ei, rho = shear_coefficient * shear_modulus_pa * area, youngs_modulus_pa * inertia, density_kg_m3
    out = [ga / (rho * inertia)]
    for n in range(1, count + 1):
        k2 = (n * math.pi / length_m) ** 2
        a, b, c = rho * rho * area * inertia, rho * (area * (ei * k2 + ga) + inertia * ga * k2), ga * ei * k2 * k2
        upper = (b + math.sqrt(b * b - 4.0 * a * c)) / (2.0 * a)
        out += [c / (a * upper), upper]
    return np.sqrt(np.sort(out)[:count]) / (2.0 * math.pi)


def test_cowper_shear_coefficient_of_a_rectangle():
    assert shear_coefficient(0.0) == pytest.approx(10.0 / 12.0, rel=1e-15)
    assert shear_coefficient(0.33) == pytest.approx(13.3 / 15.63, rel=1e-15)
    assert shear_coefficient(0.5) == pytest.approx(15.0 / 17.5, rel=1e-15)


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
def test_a_thin_bar_is_euler_bernoulli_with_an_error_of_order_slenderness_squared(bc):
    errors = {}
    for slenderness in (1e-3, 1e-4, 1e-6):
        bar = dict(ROSEWOOD, length_m=0.5, thickness_m=0.5 * slenderness)
        found = timoshenko_frequencies(bc=bc, count=6, **bar)
        errors[slenderness] = found / euler_bernoulli(bar, bc, 6) - 1.0
    # shear and rotary inertia lower every mode, by (lambda_n h / L)^2 times a constant of order E / (kappa G) / 12
    scaled = -errors[1e-4] / (lambdas(bc, 6) * 1e-4) ** 2
    assert np.all(scaled > 0.1) and np.all(scaled < 2.0)
    assert np.abs(errors[1e-4][:2]).max() < 1e-6 and np.abs(errors[1e-4]).max() < 1e-5
    np.testing.assert_allclose(errors[1e-3] / errors[1e-4], 100.0, rtol=0.01)  # (h / L)^2
    assert np.abs(errors[1e-6]).max() < 1e-9


@pytest.mark.parametrize("thickness_m", [0.002, 0.02, 0.08, 0.3])
def test_pinned_pinned_matches_the_exact_frequencies_through_the_cut_off(thickness_m):
    bar = dict(ROSEWOOD, length_m=0.4, thickness_m=thickness_m)
    found = timoshenko_frequencies(bc="pinned-pinned", count=50, **bar)
    exact = simply_supported_hz(50, **bar)
    np.testing.assert_allclose(found, exact, rtol=1e-10)
    cut_off = math.sqrt(5 / 6 * 1.4e9 * 12.0 / (1000.0 * thickness_m**2)) / (2.0 * math.pi)
    if thickness_m >= 0.02:
        assert np.sum(found > cut_off) >= 20  # the second spectrum is in the list


def test_aluminium_pinned_pinned_is_exact_too():
    bar = dict(ALUMINIUM, length_m=0.3, thickness_m=0.05)
    np.testing.assert_allclose(timoshenko_frequencies(bc="pinned-pinned", count=30, **bar),
                               simply_supported_hz(30, **bar), rtol=1e-10)


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
@pytest.mark.parametrize("thickness_m", [0.004, 0.02, 0.1, 0.4])
def test_frequencies_increase_and_the_count_is_kept(bc, thickness_m):
    bar = dict(ROSEWOOD, length_m=0.4, thickness_m=thickness_m)
    found = timoshenko_frequencies(bc=bc, count=60, **bar)
    assert found.shape == (60,) and found.dtype == np.float64
    assert np.all(np.diff(found) > 0.0)
    assert np.all(found <= euler_bernoulli(bar, bc, 60) * (1.0 + 1e-12))  # shear only ever lowers a mode
    first = timoshenko_frequencies(bc=bc, count=7, **bar)
    np.testing.assert_allclose(first, found[:7], rtol=1e-13)


def test_the_width_does_not_matter_and_units_scale():
    bar = dict(ROSEWOOD, length_m=0.4, thickness_m=0.02)
    base = timoshenko_frequencies(bc="free-free", count=5, **bar)
    # twice the length and thickness: same slenderness, half the frequencies
    double = timoshenko_frequencies(bc="free-free", count=5, **dict(bar, length_m=0.8, thickness_m=0.04))
    np.testing.assert_allclose(double, 0.5 * base, rtol=1e-13)
    # four times the moduli: twice the frequencies
    stiff = dict(bar, youngs_modulus_pa=80e9, shear_modulus_pa=5.6e9)
    np.testing.assert_allclose(timoshenko_frequencies(bc="free-free", count=5, **stiff), 2.0 * base, rtol=1e-13)


def test_a_marimba_bar_is_flat_of_euler_bernoulli_by_the_expected_cents():
    """A 40 x 5 x 2 cm rosewood bar (E / G = 14.3): Euler–Bernoulli is sharp by 45 cents at the
    fundamental and by more than a semitone from the second mode on (spec 8.1)."""
    bar = dict(ROSEWOOD, length_m=0.4, thickness_m=0.02)
    cents = 1200.0 * np.log2(euler_bernoulli(bar, "free-free", 5) / timoshenko_frequencies(bc="free-free", count=5,
                                                                                            **bar))
    np.testing.assert_allclose(cents, [45.4, 147.0, 281.7, 435.9, 597.3], atol=0.1)


@pytest.mark.parametrize(
    "name, value",
    [("youngs_modulus_pa", 0.0), ("density_kg_m3", -1.0), ("shear_modulus_pa", math.nan), ("shear_coefficient", 1.5),
     ("shear_coefficient", 0.0), ("length_m", "long"), ("thickness_m", 0.5), ("bc", "glued-free"), ("count", 0),
     ("count", 2.5), ("count", 10**6)],
)
def test_bad_input_names_the_parameter(name, value):
    args = dict(ROSEWOOD, length_m=0.4, thickness_m=0.02, bc="free-free", count=3)
    args[name] = value
    with pytest.raises(ParameterError, match=f"parameter {name} = "):
        timoshenko_frequencies(**args)


def test_bad_poisson_ratio_names_the_parameter():
    for value in (-1.0, 0.6, "x"):
        with pytest.raises(ParameterError, match="parameter poisson_ratio = "):
            shear_coefficient(value)


@pytest.mark.parametrize(
    "ratio, slenderness",
    [(17.0, 0.1890694716298513),  # modes 6 and 7: 2915.446 and 2916.012 Hz, a first- and a second-spectrum mode
     (13.588171936972937, 0.5598953088844966),  # a mode 2 % below the cut-off mode
     (3.4374025275080706, 0.32541316439557244)],  # two modes 0.1 % apart, inside one scan step
)
def test_nearly_coinciding_modes_are_both_found(ratio, slenderness):
    bar = dict(youngs_modulus_pa=ratio * 1e9, density_kg_m3=1000.0, shear_modulus_pa=1e9, shear_coefficient=1.0,
               length_m=1.0, thickness_m=slenderness)
    found = timoshenko_frequencies(bc="pinned-pinned", count=20, **bar)
    np.testing.assert_allclose(found, simply_supported_hz(20, **bar), rtol=1e-10)
