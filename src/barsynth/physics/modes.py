"""Frequencies and mode shapes of a uniform Euler–Bernoulli bar.

A thin uniform bar of Young's modulus ``E``, density ``rho`` and rectangular
section of thickness ``h`` obeys ``y_tt + (E K²/rho) y_xxxx = 0`` with
``K = h / sqrt(12)``; its mode n has angular frequency
``w_n = sqrt(E K²/rho) lambda_n² / L²`` (spec 1.1–1.2; Fletcher & Rossing, *The
Physics of Musical Instruments*, 2nd ed., Springer 1998, ch. 2).

Mode shapes are written in the bounded basis

    f(x) = a cos(λx) + b sin(λx) + c exp(−λx) + d exp(−λ(1 − x)),   0 ≤ x ≤ 1,

the standard rewrite of ``A sin + B cos + C sinh + D cosh`` in which every term
is at most one in size, so the shapes stay accurate for any mode number (the
naive sinh/cosh difference loses all digits beyond n ≈ 10). ``(a, b, c, d)`` is
the null vector of the 4 × 4 boundary-condition matrix in this basis, normalised
with its exact Gram matrix so that ∫₀¹ f_n(x)² dx = 1. For n ≤ ~10 the shapes
agree with the textbook forms (Blevins, *Formulas for Natural Frequency and Mode
Shape*, 1979, table 8-1), e.g. ``cosh − cos − σ(sinh − sin)`` for the cantilever.

Sign convention: the first derivative of ``f_n`` that does not vanish at
``x = 0`` is positive, i.e. every shape starts upward from the ``x = 0`` end
(free end: ``f_n(0) > 0``; pinned: ``f_n'(0) > 0``; clamped: ``f_n''(0) > 0``).
This is the sign of the textbook forms and of ``sqrt(2) sin(nπx)``.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ..errors import ParameterError
from ..checks import check_array, check_number, check_whole
from .boundary import MAX_COUNT, _check_bc, _root, lambdas

__all__ = ["bar_frequencies", "bending_wave_constant", "mode_shape"]

# Derivative orders that vanish at an end of each kind.
_END_ORDERS = {"free": (2, 3), "clamped": (0, 1), "pinned": (0, 2)}


def bending_wave_constant(
    youngs_modulus_pa: float, density_kg_m3: float, thickness_m: float
) -> float:
    """Bending constant ``sqrt(E K² / rho)`` of a rectangular bar, ``K = h / sqrt(12)``.

    It is ``w / k²`` for bending waves (spec 1.4's ``a``), so ``w_n = a k_n²``.

    Parameters
    ----------
    youngs_modulus_pa : float
        Young's modulus ``E`` in Pa, > 0.
    density_kg_m3 : float
        Density ``rho`` in kg/m³, > 0.
    thickness_m : float
        Thickness ``h`` in m (in the bending direction), > 0.

    Returns
    -------
    float
        ``sqrt(E K²/rho)`` in m²/s.

    Examples
    --------
    >>> round(bending_wave_constant(3.2e9, 1180.0, 0.003), 2)  # acrylic ruler
    1.43
    """
    positive = {"minimum": 0.0, "minimum_exclusive": True}
    e = check_number("youngs_modulus_pa", youngs_modulus_pa, "Pa", **positive)
    rho = check_number("density_kg_m3", density_kg_m3, "kg/m³", **positive)
    h = check_number("thickness_m", thickness_m, "m", **positive)
    return math.sqrt(e / rho) * h / math.sqrt(12.0)


def bar_frequencies(
    *,
    youngs_modulus_pa: float,
    density_kg_m3: float,
    length_m: float,
    thickness_m: float,
    bc: str,
    count: int,
) -> np.ndarray:
    """Modal frequencies ``f_n = sqrt(E K²/rho) lambda_n² / (2π L²)`` of a uniform bar.

    Damping is not included (see :func:`barsynth.physics.damped_frequency`).

    Parameters
    ----------
    youngs_modulus_pa : float
        Young's modulus in Pa, > 0.
    density_kg_m3 : float
        Density in kg/m³, > 0.
    length_m : float
        Vibrating length ``L`` in m, > 0.
    thickness_m : float
        Thickness ``h`` in m, > 0.
    bc : str
        Boundary conditions, one of :data:`BOUNDARY_CONDITIONS`.
    count : int
        Number of modes, >= 1.

    Returns
    -------
    numpy.ndarray
        float64, shape ``(count,)``, in Hz, increasing.

    Examples
    --------
    >>> bar_frequencies(youngs_modulus_pa=3.2e9, density_kg_m3=1180.0, length_m=0.15,
    ...                 thickness_m=0.003, bc="clamped-free", count=2).round(1)
    array([ 35.5, 222.3])
    """
    length = check_number("length_m", length_m, "m", minimum=0.0, minimum_exclusive=True)
    lam = lambdas(bc, count)
    try:
        a = bending_wave_constant(youngs_modulus_pa, density_kg_m3, thickness_m)
        with np.errstate(over="ignore", under="ignore", divide="ignore", invalid="ignore"):
            freqs = a * lam**2 / (2.0 * math.pi * length**2)
    except OverflowError:
        freqs = np.full(lam.shape, math.inf)
    if not np.all(np.isfinite(freqs) & (freqs > 0.0)):
        raise ParameterError(
            f"parameters youngs_modulus_pa = {youngs_modulus_pa!r}, density_kg_m3 = "
            f"{density_kg_m3!r}, length_m = {length_m!r}, thickness_m = {thickness_m!r} give "
            "frequencies that are not finite positive numbers; allowed: values whose "
            "frequencies sqrt(E/rho) h / sqrt(12) lambda^2 / (2 pi L^2) stay within float range (Hz)"
        )
    return freqs


def _basis(xi: np.ndarray, lam: float, order: int) -> np.ndarray:
    """The four bounded basis functions differentiated ``order`` times in ξ = λx.

    Shape ``(4,) + xi.shape``: cos ξ, sin ξ, exp(−ξ), exp(ξ − λ).
    """
    shift = 0.5 * math.pi * order
    return np.stack(
        [
            np.cos(xi + shift),
            np.sin(xi + shift),
            (-1.0) ** order * np.exp(-xi),
            np.exp(xi - lam),
        ]
    )


def _gram(lam: float) -> np.ndarray:
    """Exact ∫₀^λ φ_i(ξ) φ_j(ξ) dξ of the bounded basis."""
    s, c, e = math.sin(lam), math.cos(lam), math.exp(-lam)
    g = np.empty((4, 4))
    g[0, 0] = 0.5 * lam + 0.5 * s * c
    g[1, 1] = 0.5 * lam - 0.5 * s * c
    g[0, 1] = 0.5 * s * s
    g[2, 2] = g[3, 3] = 0.5 * (1.0 - e * e)
    g[2, 3] = lam * e
    g[0, 2] = 0.5 * (1.0 + e * (s - c))
    g[1, 2] = 0.5 * (1.0 - e * (s + c))
    g[0, 3] = 0.5 * (c + s - e)
    g[1, 3] = 0.5 * (s - c + e)
    iu = np.triu_indices(4, 1)
    g[(iu[1], iu[0])] = g[iu]
    return g


@lru_cache(maxsize=4096)
def _shape_coefficients(bc: str, n: int) -> tuple[float, np.ndarray]:
    """``(lambda_n, (a, b, c, d))`` of the normalised, sign-fixed shape of mode n."""
    if bc == "pinned-pinned":
        coef = np.array([0.0, math.sqrt(2.0), 0.0, 0.0])
        coef.flags.writeable = False
        return n * math.pi, coef
    lam = _root(bc, n)
    left, right = bc.split("-")
    ends = np.array([0.0, lam])
    rows = [_basis(ends[:1], lam, m)[:, 0] for m in _END_ORDERS[left]]
    rows += [_basis(ends[1:], lam, m)[:, 0] for m in _END_ORDERS[right]]
    _, _, vt = np.linalg.svd(np.array(rows))
    coef = vt[-1]
    coef = coef / math.sqrt(coef @ _gram(lam) @ coef / lam)
    start = np.array([_basis(ends[:1], lam, m)[:, 0] @ coef for m in range(4)])
    first = int(np.argmax(np.abs(start) > 1e-6 * np.abs(start).max()))
    if start[first] < 0.0:
        coef = -coef
    coef.flags.writeable = False
    return lam, coef


def mode_shape(bc: str, n: int, x, *, derivative: int = 0):
    """Shape ``f_n(x)`` of mode ``n`` of a uniform bar, with ∫₀¹ f_n² dx = 1.

    Numerically stable for any ``n`` (see the module notes for the form used and
    the sign convention: every shape starts upward from the ``x = 0`` end).

    Parameters
    ----------
    bc : str
        Boundary conditions, one of :data:`BOUNDARY_CONDITIONS` (the first name is
        the end at ``x = 0``).
    n : int
        Mode number, 1-based.
    x : float or array_like
        Positions as a fraction of the length, 0 to 1 (dimensionless).
    derivative : int, optional
        Order of the derivative with respect to ``x`` (0 to 3). Divide by
        ``L**derivative`` for the derivative per metre.

    Returns
    -------
    numpy.ndarray or numpy.float64
        float64 of the shape of ``x`` (a scalar for scalar ``x``), dimensionless.

    Examples
    --------
    >>> round(float(mode_shape("pinned-pinned", 1, 0.5)), 6)
    1.414214
    >>> round(float(mode_shape("clamped-free", 1, 1.0)), 6)  # tip of a cantilever
    2.0
    """
    name = _check_bc(bc)
    mode = check_whole("n", n, "", 1, MAX_COUNT, integral_floats=True)
    order = check_whole("derivative", derivative, "", 0, 3, integral_floats=True)
    pos = check_array("x", x, "(fraction of length)", minimum=0.0, maximum=1.0)
    lam, coef = _shape_coefficients(name, mode)
    out = np.tensordot(coef, _basis(lam * pos, lam, order), axes=1) * lam**order
    return out[()] if out.ndim == 0 else out


def travelling_wave_shape(bc: str, n: int, x):
    """The part of ``mode_shape(bc, n, x)`` carried by travelling waves (``a cos + b sin``), without
    the near fields that die away from the ends: the shape a waveguide model gives the mode (its
    clamped ends move, its free ends read half).

    Examples
    --------
    >>> round(float(travelling_wave_shape("clamped-free", 1, 0.0)), 6) != 0.0  # a clamped end moves
    True
    >>> round(float(travelling_wave_shape("pinned-pinned", 1, 0.5)), 6)  # no near field at all
    1.414214
    """
    name = _check_bc(bc)
    mode = check_whole("n", n, "", 1, MAX_COUNT, integral_floats=True)
    pos = check_array("x", x, "(fraction of length)", minimum=0.0, maximum=1.0)
    lam, coef = _shape_coefficients(name, mode)
    out = coef[0] * np.cos(lam * pos) + coef[1] * np.sin(lam * pos)
    return out[()] if out.ndim == 0 else out
