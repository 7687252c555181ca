"""Tests of barsynth.physics against spec 1 (01-physics.md)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from barsynth.errors import ParameterError
from barsynth.physics import (
    BOUNDARY_CONDITIONS,
    Material,
    alpha_from_q,
    alpha_from_t60,
    bar_frequencies,
    bending_wave_constant,
    damped_frequency,
    lambda_ratios,
    lambdas,
    material,
    materials,
    mode_shape,
    q_from_t60,
    t60_from_alpha,
    t60_from_q,
)

EPS = np.finfo(float).eps

# --------------------------------------------------------------------------------------
# Spec 1.2, Table 1 (Selfridge et al. 2022), to every printed digit.
TABLE_1 = {
    "free-free": (
        [4.7300, 7.8532, 10.9956, 14.1372, 17.2788, 20.4204],
        [1.0, 2.7565, 5.4039, 8.9330, 13.3443, 18.6379],
    ),
    "clamped-free": (
        [1.8751, 4.6941, 7.8548, 10.9955, 14.1372, 17.2788],
        [1.0, 6.2669, 17.5475, 34.3861, 56.8426, 84.9130],
    ),
}

ASYMPTOTE_OFFSET = {
    "free-free": 0.5,
    "clamped-free": -0.5,
    "clamped-clamped": 0.5,
    "pinned-pinned": 0.0,
    "clamped-pinned": 0.25,
}


def characteristic(bc: str, lam: np.ndarray) -> np.ndarray:
    """The spec's characteristic equations, written independently, divided by cosh."""
    lam = np.asarray(lam, dtype=float)
    if bc in ("free-free", "clamped-clamped"):
        return (np.cos(lam) * np.cosh(lam) - 1.0) / np.cosh(lam)
    if bc == "clamped-free":
        return (np.cos(lam) * np.cosh(lam) + 1.0) / np.cosh(lam)
    if bc == "pinned-pinned":
        return np.sin(lam)
    if bc == "clamped-pinned":
        return (np.sin(lam) * np.cosh(lam) - np.cos(lam) * np.sinh(lam)) / np.cosh(lam)
    raise AssertionError(bc)


@pytest.mark.parametrize("bc", sorted(TABLE_1))
@pytest.mark.parametrize("i", range(6))
def test_table_1_lambdas_to_every_printed_digit(bc, i):
    printed = TABLE_1[bc][0][i]
    assert round(float(lambdas(bc, 6)[i]), 4) == printed


@pytest.mark.parametrize("bc", sorted(TABLE_1))
@pytest.mark.parametrize("i", range(6))
def test_table_1_ratios_to_every_printed_digit(bc, i):
    printed = TABLE_1[bc][1][i]
    assert round(float(lambda_ratios(bc, 6)[i]), 4) == printed


def test_table_1_rounding_is_not_marginal():
    # 8.93295035 -> 8.9330 is the closest call in the table; make sure it is not
    # decided by the last bits of the root.
    r = lambda_ratios("free-free", 4)[3]
    assert abs(r - 8.93295) > 1e-7
    assert abs(r - 8.932950350) < 1e-8


# --------------------------------------------------------------------------------------
# Roots for every boundary condition, up to n = 200.


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
def test_roots_satisfy_characteristic_equation(bc):
    lam = lambdas(bc, 200)
    assert lam.dtype == np.float64 and lam.shape == (200,)
    assert np.all(np.abs(characteristic(bc, lam)) < 1e-12 * np.maximum(1.0, lam))
    # and each is a genuine sign change, not merely a small value
    d = 1e-9 * lam
    assert np.all(characteristic(bc, lam - d) * characteristic(bc, lam + d) < 0)


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
def test_no_root_missed_or_repeated(bc):
    lam = lambdas(bc, 200)
    start = 0.1 if bc == "clamped-free" else 1.0
    grid = np.arange(start, lam[-1] + 0.5, 1e-3)
    g = characteristic(bc, grid)
    changes = np.count_nonzero(np.sign(g[:-1]) != np.sign(g[1:]))
    assert changes == 200


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
def test_roots_increase_and_approach_asymptotes(bc):
    n = np.arange(1, 201)
    lam = lambdas(bc, 200)
    assert np.all(np.diff(lam) > 0)
    a = (n + ASYMPTOTE_OFFSET[bc]) * math.pi
    err = np.abs(lam - a)
    if bc == "pinned-pinned":
        bound = np.zeros_like(a)
    elif bc == "clamped-pinned":
        bound = np.exp(-2.0 * a)  # tan(a + d) = tanh -> d ~ -exp(-2a)
    else:
        bound = 2.0 * np.exp(-a)  # cos(a + d) = +-sech -> |d| ~ 2 exp(-a)
    assert np.all(err <= 1.02 * bound + 8 * EPS * a)
    assert np.all(err[20:] <= 8 * EPS * a[20:])  # indistinguishable from the asymptote
    assert np.all(np.abs(lam - a) < math.pi / 4)


def test_other_boundary_conditions_first_roots():
    assert round(float(lambdas("clamped-clamped", 1)[0]), 4) == 4.7300
    assert round(float(lambdas("clamped-pinned", 1)[0]), 4) == 3.9266
    n = np.arange(1, 201)
    np.testing.assert_allclose(lambdas("pinned-pinned", 200), n * math.pi, rtol=4 * EPS, atol=0)
    # clamped-clamped and free-free share their characteristic equation
    np.testing.assert_array_equal(lambdas("clamped-clamped", 50), lambdas("free-free", 50))


def test_pinned_ratios_are_squares():
    squares = np.arange(1, 11) ** 2
    np.testing.assert_allclose(lambda_ratios("pinned-pinned", 10), squares, rtol=1e-13)


def test_lambdas_prefix_consistent_and_cache_returns_copies():
    a = lambdas("free-free", 10)
    np.testing.assert_array_equal(lambdas("free-free", 3), a[:3])
    a[:] = -1.0
    assert lambdas("free-free", 10)[0] == pytest.approx(4.730040744862704, rel=1e-14)


def test_bc_names_are_forgiving_about_spelling():
    np.testing.assert_array_equal(lambdas("Clamped_Free", 3), lambdas("clamped-free", 3))


# --------------------------------------------------------------------------------------
# Frequencies: the acrylic worked example of spec 1.2.

ACRYLIC = dict(youngs_modulus_pa=3.2e9, density_kg_m3=1180.0, thickness_m=0.003)


def test_acrylic_bending_wave_constant():
    a = bending_wave_constant(3.2e9, 1180.0, 0.003)
    assert round(a, 2) == 1.43
    assert a == pytest.approx(math.sqrt(3.2e9 * 0.003**2 / 12 / 1180.0), rel=1e-15)


def test_acrylic_cantilever_15cm():
    f = bar_frequencies(**ACRYLIC, length_m=0.15, bc="clamped-free", count=6)
    assert round(float(f[0])) == 35
    assert f[0] == pytest.approx(35.469, abs=1e-3)


def test_acrylic_free_free_30cm():
    f = bar_frequencies(**ACRYLIC, length_m=0.30, bc="free-free", count=6)
    assert round(float(f[0])) == 56
    assert f[0] == pytest.approx(56.425, abs=1e-3)


def test_frequency_scaling_laws():
    base = bar_frequencies(**ACRYLIC, length_m=0.3, bc="free-free", count=8)
    np.testing.assert_allclose(base / base[0], lambda_ratios("free-free", 8), rtol=1e-14)
    half = bar_frequencies(**ACRYLIC, length_m=0.15, bc="free-free", count=8)
    np.testing.assert_allclose(half, 4 * base, rtol=1e-14)  # f ~ 1/L^2
    common = dict(length_m=0.3, bc="free-free", count=8)
    thick = bar_frequencies(**{**ACRYLIC, "thickness_m": 0.006}, **common)
    np.testing.assert_allclose(thick, 2 * base, rtol=1e-14)  # f ~ h
    stiff = bar_frequencies(**{**ACRYLIC, "youngs_modulus_pa": 12.8e9}, **common)
    np.testing.assert_allclose(stiff, 2 * base, rtol=1e-14)  # f ~ sqrt(E)


# --------------------------------------------------------------------------------------
# Mode shapes.

END_ORDERS = {"free": (2, 3), "clamped": (0, 1), "pinned": (0, 2)}
NON_PINNED = [bc for bc in BOUNDARY_CONDITIONS if bc != "pinned-pinned"]


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
@pytest.mark.parametrize("n", [1, 2, 3, 7, 30, 50])
def test_shape_boundary_conditions_hold(bc, n):
    lam = lambdas(bc, n)[-1]
    left, right = bc.split("-")
    for end, x in ((left, 0.0), (right, 1.0)):
        for m in END_ORDERS[end]:
            value = mode_shape(bc, n, x, derivative=m) / lam**m
            assert abs(value) < 1e-11, (end, x, m, value)
        # and the shape is not trivially zero there
        scale = max(abs(mode_shape(bc, n, x, derivative=m)) / lam**m for m in range(4))
        assert scale > 0.5


@pytest.mark.parametrize("bc", ["free-free", "clamped-free"])
def test_shape_boundary_conditions_by_finite_differences(bc):
    # free end: y'' = y''' = 0 from one-sided differences of the values alone
    h = 1e-3
    for n in (1, 2, 3):
        lam = lambdas(bc, n)[-1]
        x = 1.0 - h * np.arange(6)
        y = mode_shape(bc, n, x)[::-1]  # y(1 - 5h) ... y(1)
        d2 = (2 * y[5] - 5 * y[4] + 4 * y[3] - y[2]) / h**2
        d3 = (5 * y[5] - 18 * y[4] + 24 * y[3] - 14 * y[2] + 3 * y[1]) / (2 * h**3)
        assert abs(d2) / lam**2 < 1e-3
        assert abs(d3) / lam**3 < 1e-2
    if bc == "clamped-free":
        y0, y1 = mode_shape(bc, 1, [0.0, h])
        assert abs(y0) < 1e-14 and abs((y1 - y0) / h) < 1e-2


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
@pytest.mark.parametrize("n", [1, 5, 30])
def test_derivative_keyword_matches_finite_differences(bc, n):
    x = np.linspace(0.0, 1.0, 40001)
    dx = x[1] - x[0]
    lam = lambdas(bc, n)[-1]
    for m in (1, 2, 3):
        numeric = np.gradient(mode_shape(bc, n, x, derivative=m - 1), dx)
        exact = mode_shape(bc, n, x, derivative=m)
        inner = slice(10, -10)
        assert np.max(np.abs(numeric[inner] - exact[inner])) < 1e-4 * lam**m


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
def test_shapes_orthonormal_up_to_30(bc):
    x = np.linspace(0.0, 1.0, 40001)
    f = np.array([mode_shape(bc, n, x) for n in range(1, 31)])
    gram = np.trapezoid(f[:, None, :] * f[None, :, :], x, axis=-1)
    np.testing.assert_allclose(gram, np.eye(30), atol=2e-6)


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
def test_high_modes_stable_and_normalised(bc):
    x = np.linspace(0.0, 1.0, 80001)
    for n in (50, 100):
        f = mode_shape(bc, n, x)
        assert np.all(np.isfinite(f))
        assert np.trapezoid(f * f, x) == pytest.approx(1.0, abs=1e-6)
        assert np.max(np.abs(f)) < 2.0 + 1e-9


@pytest.mark.parametrize("bc", NON_PINNED)
def test_high_mode_interior_matches_asymptotic_form(bc):
    # Away from the ends every shape tends to sqrt(2) sin(lam x -+ pi/4); the naive
    # sinh/cosh form cannot reproduce this at n = 50 (it loses ~60 digits).
    n = 50
    lam = lambdas(bc, n)[-1]
    x = np.linspace(0.2, 0.8, 1001)
    expected = np.sin(lam * x) - np.cos(lam * x)
    if bc == "free-free":
        expected = -expected
    np.testing.assert_allclose(mode_shape(bc, n, x), expected, atol=1e-10)


def textbook_shape(bc, n, x):
    """Blevins-style textbook forms, only trustworthy for small n."""
    lam = lambdas(bc, n)[-1]
    xi = lam * x
    if bc == "free-free":
        s = (np.cosh(lam) - np.cos(lam)) / (np.sinh(lam) - np.sin(lam))
        return np.cosh(xi) + np.cos(xi) - s * (np.sinh(xi) + np.sin(xi))
    if bc == "clamped-free":
        s = (np.sinh(lam) - np.sin(lam)) / (np.cosh(lam) + np.cos(lam))
    elif bc == "clamped-clamped":
        s = (np.cosh(lam) - np.cos(lam)) / (np.sinh(lam) - np.sin(lam))
    elif bc == "clamped-pinned":
        s = (np.cosh(lam) - np.cos(lam)) / (np.sinh(lam) - np.sin(lam))
    else:
        return np.sqrt(2.0) * np.sin(n * np.pi * x)
    return np.cosh(xi) - np.cos(xi) - s * (np.sinh(xi) - np.sin(xi))


@pytest.mark.parametrize("bc", BOUNDARY_CONDITIONS)
@pytest.mark.parametrize("n", range(1, 6))
def test_shapes_match_textbook_forms_for_low_modes(bc, n):
    x = np.linspace(0.0, 1.0, 20001)
    ref = textbook_shape(bc, n, x)
    ref /= math.sqrt(np.trapezoid(ref * ref, x))  # same sign convention already
    np.testing.assert_allclose(mode_shape(bc, n, x), ref, atol=1e-6)


@pytest.mark.parametrize("n", range(1, 41))
def test_sign_convention_and_end_values(n):
    # free ends of a normalised free-free bar or cantilever have |f| = 2
    assert mode_shape("free-free", n, 0.0) == pytest.approx(2.0, abs=1e-9)
    assert mode_shape("free-free", n, 1.0) == pytest.approx(2.0 * (-1) ** (n + 1), abs=1e-9)
    assert mode_shape("clamped-free", n, 1.0) == pytest.approx(2.0 * (-1) ** (n + 1), abs=1e-9)
    for bc in ("clamped-free", "clamped-clamped", "clamped-pinned"):
        assert mode_shape(bc, n, 0.0, derivative=2) > 0
    assert mode_shape("pinned-pinned", n, 0.0, derivative=1) > 0


def test_pinned_shape_is_sqrt2_sine():
    x = np.linspace(0, 1, 101)
    for n in (1, 4, 50):
        expected = math.sqrt(2) * np.sin(n * math.pi * x)
        np.testing.assert_allclose(mode_shape("pinned-pinned", n, x), expected, atol=1e-13)


def test_mode_shape_keeps_input_shape():
    assert isinstance(mode_shape("free-free", 1, 0.25), float)
    assert mode_shape("free-free", 1, np.zeros((3, 4))).shape == (3, 4)
    assert mode_shape("free-free", 2, [0.1, 0.2]).shape == (2,)


def test_free_free_fundamental_nodes():
    # nodes of the first free-free mode at 0.2242 L and 0.7758 L (Fletcher & Rossing)
    x = np.array([0.2242, 0.7758])
    assert np.all(np.abs(mode_shape("free-free", 1, x)) < 2e-3)


# --------------------------------------------------------------------------------------
# Damping (spec 1.3).


def test_alpha_and_t60_from_q():
    assert alpha_from_q(440.0, 100.0) == pytest.approx(math.pi * 4.4, rel=1e-15)
    assert t60_from_q(100.0, 50.0) == pytest.approx(math.log(1000) * 50 / (math.pi * 100), rel=1e-15)
    assert t60_from_q(100.0, 50.0) == pytest.approx(1.09940, abs=1e-5)
    assert t60_from_alpha(math.log(1000.0)) == pytest.approx(1.0, rel=1e-15)
    assert alpha_from_t60(2.0) == pytest.approx(math.log(1000.0) / 2.0, rel=1e-15)


def test_t60_is_a_60_db_decay():
    f, q = np.array([55.0, 440.0, 3520.0]), np.array([50.0, 200.0, 800.0])
    alpha = alpha_from_q(f, q)
    t60 = t60_from_q(f, q)
    np.testing.assert_allclose(np.exp(-alpha * t60), 1e-3, rtol=1e-12)
    np.testing.assert_allclose(20 * np.log10(np.exp(-alpha * t60)), -60.0, rtol=1e-12)


def test_damping_round_trips():
    f = np.geomspace(20.0, 20000.0, 7)
    q = np.geomspace(50.0, 800.0, 7)
    np.testing.assert_allclose(q_from_t60(f, t60_from_q(f, q)), q, rtol=1e-13)
    alpha = alpha_from_q(f, q)
    np.testing.assert_allclose(alpha_from_t60(t60_from_alpha(alpha)), alpha, rtol=1e-13)
    np.testing.assert_allclose(t60_from_alpha(alpha_from_q(f, q)), t60_from_q(f, q), rtol=1e-13)


def test_damping_scalars_and_broadcasting():
    assert isinstance(alpha_from_q(100.0, 50.0), float)
    out = t60_from_q(np.array([100.0, 200.0]), 50.0)
    assert isinstance(out, np.ndarray) and out.shape == (2,)
    assert out[0] == pytest.approx(2 * out[1], rel=1e-15)


def test_damped_frequency_shift():
    expected = 100.0 * math.sqrt(1 - 1 / 10000)
    assert damped_frequency(100.0, 50.0) == pytest.approx(expected, rel=1e-15)
    q = np.array([50.0, 100.0, 800.0])
    shift = 1.0 - damped_frequency(1000.0, q) / 1000.0
    assert np.all(shift > 0) and np.all(shift < 1e-4)  # below 0.01 % for Q >= 50
    assert damped_frequency(1000.0, 1.0) == pytest.approx(1000.0 * math.sqrt(0.75), rel=1e-15)


# --------------------------------------------------------------------------------------
# Materials (spec 1.7).

MATERIAL_NAMES = {
    "steel", "stainless-steel", "aluminium", "brass", "acrylic", "polystyrene",
    "polycarbonate", "maple", "rosewood", "spruce", "bamboo", "glass", "padauk", "bubinga", "african-blackwood",
}


def test_materials_table_complete_and_sane():
    table = materials()
    assert set(table) == MATERIAL_NAMES
    for name, m in table.items():
        assert isinstance(m, Material) and m.name == name
        assert m.youngs_modulus_pa > 0 and m.density_kg_m3 > 0
        assert m.typical_q is None or m.typical_q > 0
        assert m.source.strip() and m.description.strip()
        # longitudinal wave speed sqrt(E/rho) of solids used for bars: ~1-6 km/s
        assert 1000.0 < math.sqrt(m.youngs_modulus_pa / m.density_kg_m3) < 6000.0


def test_acrylic_matches_worked_example():
    m = material("acrylic")
    assert m.youngs_modulus_pa == 3.2e9 and m.density_kg_m3 == 1180.0


def test_material_lookup():
    assert material("Stainless steel") is materials()["stainless-steel"]
    assert material("stainless_steel").density_kg_m3 > material("aluminium").density_kg_m3
    with pytest.raises(dataclasses.FrozenInstanceError):
        material("steel").density_kg_m3 = 1.0  # type: ignore[misc]
    t = materials()
    t.clear()
    assert len(materials()) == len(MATERIAL_NAMES)


def test_unknown_material():
    with pytest.raises(ParameterError, match=r"unknown material 'unobtainium'; available: .*steel"):
        material("unobtainium")


# --------------------------------------------------------------------------------------
# Bad input.

GOOD = dict(
    youngs_modulus_pa=3.2e9,
    density_kg_m3=1180.0,
    length_m=0.3,
    thickness_m=0.003,
    bc="free-free",
    count=4,
)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: lambdas("banana", 3), "bc"),
        (lambda: lambdas(None, 3), "bc"),
        (lambda: lambdas("free-free", 0), "count"),
        (lambda: lambdas("free-free", -2), "count"),
        (lambda: lambdas("free-free", 2.5), "count"),
        (lambda: lambdas("free-free", True), "count"),
        (lambda: lambda_ratios("free-free", 0), "count"),
        (lambda: bending_wave_constant(0.0, 1180.0, 0.003), "youngs_modulus_pa"),
        (lambda: bending_wave_constant(3.2e9, -1.0, 0.003), "density_kg_m3"),
        (lambda: bending_wave_constant(3.2e9, 1180.0, float("nan")), "thickness_m"),
        (lambda: bar_frequencies(**{**GOOD, "length_m": -1}), "length_m"),
        (lambda: bar_frequencies(**{**GOOD, "length_m": float("inf")}), "length_m"),
        (lambda: bar_frequencies(**{**GOOD, "youngs_modulus_pa": "stiff"}), "youngs_modulus_pa"),
        (lambda: bar_frequencies(**{**GOOD, "density_kg_m3": 0}), "density_kg_m3"),
        (lambda: bar_frequencies(**{**GOOD, "thickness_m": -0.1}), "thickness_m"),
        (lambda: bar_frequencies(**{**GOOD, "bc": "glued"}), "bc"),
        (lambda: bar_frequencies(**{**GOOD, "count": 0}), "count"),
        (lambda: mode_shape("free-free", 0, 0.5), "n"),
        (lambda: mode_shape("free-free", 1, 1.5), "x"),
        (lambda: mode_shape("free-free", 1, [0.2, -0.1]), "x"),
        (lambda: mode_shape("free-free", 1, 0.5, derivative=4), "derivative"),
        (lambda: mode_shape("nope", 1, 0.5), "bc"),
        (lambda: alpha_from_q(0.0, 100.0), "frequency_hz"),
        (lambda: alpha_from_q(440.0, [100.0, -1.0]), "q"),
        (lambda: t60_from_alpha(0.0), "alpha"),
        (lambda: t60_from_q(440.0, float("nan")), "q"),
        (lambda: q_from_t60(440.0, 0.0), "t60_s"),
        (lambda: alpha_from_t60(-3.0), "t60_s"),
        (lambda: damped_frequency(440.0, 0.5), "q"),
        (lambda: damped_frequency(-440.0, 50.0), "frequency_hz"),
    ],
)
def test_bad_input_names_the_parameter(call, name):
    with pytest.raises(ParameterError) as info:
        call()
    message = str(info.value)
    assert f"parameter {name} = " in message
    assert "allowed:" in message


def test_error_message_has_value_range_and_unit():
    with pytest.raises(ParameterError) as info:
        bar_frequencies(**{**GOOD, "length_m": -1})
    assert str(info.value) == "parameter length_m = -1 is out of range; allowed: > 0 m"
    with pytest.raises(ParameterError, match="allowed: one of free-free, clamped-free"):
        lambdas("banana", 1)
    expected = r"q = 0\.0 is out of range; allowed: > 0 dimensionless"
    with pytest.raises(ParameterError, match=expected):
        alpha_from_q(1.0, [1.0, 0.0])
