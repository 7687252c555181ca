"""Closed-form frequencies of a uniform thick (Timoshenko) bar, from its characteristic equation.

Sources: S. Timoshenko, Phil. Mag. 41 (1921) (shear and rotary inertia); T. C. Huang, J. Appl.
Mech. 28 (1961) 579 (the frequency equations for the classical end conditions, both regimes);
G. R. Cowper, J. Appl. Mech. 33 (1966) 335 (the shear coefficient of a rectangle). Spec 8.2.

With ``ξ = x / L``, ``W = w / L``, ``ψ = θ``, the slenderness ``r² = I / (A L²) = h² / (12 L²)``,
``s² = r² E / (κ G)`` and the frequency ``b² = ρ A L⁴ ω² / (E I)`` (Huang's notation; ``b = λ²`` of
Euler–Bernoulli), a harmonic motion obeys ``W'' − ψ' + b² s² W = 0`` and ``s² ψ'' + (W' − ψ) +
b² r² s² ψ = 0``. A wave ``exp(k ξ)`` needs ``k⁴ + b² (r² + s²) k² − b² (1 − b² r² s²) = 0``: one pair
``k = ± i β`` is always oscillatory, the other ``k = ± α`` decays (a near field) below the cut-off
``b_c = 1 / (r s)``, i.e. ``ω_c = sqrt(κ G A / (ρ I))``, and oscillates (``α² < 0``) above it, where
the second spectrum begins. The four waves and the two end conditions (clamped ``W = ψ = 0``,
pinned ``W = ψ' = 0``, free ``ψ' = 0`` and shear ``W' − ψ = 0``) give a 4 × 4 matrix ``M(b)`` whose
determinant vanishes at the modes.

Each pair ``k² = μ`` is written with ``C = cosh(k ξ)`` and ``S = sinh(k ξ) / k`` (``cos`` and
``sin / q`` when ``μ = −q² < 0``), which are entire in ``μ``, so the matrix is smooth through the
cut-off (where ``α = 0`` and the naive ``exp(± α ξ)`` pair degenerates): ``(W, ψ) = (C, D S)`` and
``(μ S / D, C)``, ``D = μ + b² s²``, the shear strain of each written out (``−b² s² S`` and
``−b² s² C / D``) so a thin bar's tiny shear costs no digits. A large decaying pair is written in
the bounded basis ``exp(−α ξ)``, ``exp(−α (1 − ξ))`` instead (as :mod:`~barsynth.physics.modes` does
for Euler–Bernoulli); the change of basis has a positive determinant, so the sign of ``det M`` is
the same in both. Each column is scaled by its largest end value (of all four quantities at both
ends, which never all vanish) and each row by its largest entry: positive factors, signs kept.

The roots are bracketed on a scan that advances each oscillatory wavenumber (``β``, and ``|α|``
above the cut-off) by at most π/8 per step. Each family of waves (its roots lie about π apart in
its wavenumber) then has at most one root in a step, so a step holds at most two: one shows as a sign change, two (a first- and a second-spectrum
mode that nearly coincide) as a dip of the signed determinant below zero inside the step, found by
golden-section search; a dip that just touches zero is a double root. Roots are refined by the
Illinois variant of regula falsi, all at once. A symmetric bar (both ends alike) is solved as its
half with the middle guided (``ψ = 0``, no shear: the symmetric modes) and pinned (the
antisymmetric ones), so a symmetric and an antisymmetric mode at one frequency never meet in one
determinant. The free–free bar's two rigid-body modes (``b = 0``) are left out, as in
:func:`~barsynth.physics.bar_frequencies`. A pinned–pinned bar has, besides its flexural modes, a
mode exactly at the cut-off (a uniform rotation of the sections with no deflection); it is listed.
"""

from __future__ import annotations

import math

import numpy as np

from ..checks import check_number, check_whole
from ..errors import ParameterError
from .boundary import _check_bc

__all__ = ["shear_coefficient", "timoshenko_frequencies"]

#: Largest number of modes one call may ask for.
MAX_COUNT = 2000

_STEP = math.pi / 8.0  # scan step of each oscillatory wavenumber
_EXPONENTIAL_ABOVE = 1.0  # a decaying pair with alpha above this uses the bounded exponential basis
# rows of (W, psi, psi', shear) that vanish at an end; "guided" is the middle of a symmetric mode
_END_ROWS = {"clamped": (0, 1), "pinned": (0, 2), "free": (2, 3), "guided": (1, 3)}


def shear_coefficient(poisson_ratio: float) -> float:
    """Shear coefficient ``κ = 10 (1 + ν) / (12 + 11 ν)`` of a rectangular section (Cowper 1966).

    Parameters
    ----------
    poisson_ratio : float
        Poisson's ratio ``ν``, above −1 to 0.5 (dimensionless).

    Returns
    -------
    float
        ``κ``, dimensionless (0.8333 at ``ν = 0``, 0.8509 at ``ν = 0.33``).

    Examples
    --------
    >>> round(shear_coefficient(0.33), 4)
    0.8509
    """
    nu = check_number("poisson_ratio", poisson_ratio, "", minimum=-1.0, maximum=0.5, minimum_exclusive=True)
    return 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)


def isotropic_shear_modulus(youngs_modulus_pa: float, poisson_ratio: float) -> float:
    """Shear modulus ``G = E / (2 (1 + ν))`` of an isotropic solid (Pa)."""
    return youngs_modulus_pa / (2.0 * (1.0 + poisson_ratio))


SHEAR_COEFFICIENT_RANGE = (0.5, 1.0)
"""The shear coefficients barsynth's options and parameter tables take (Cowper's rectangle: 0.83-0.87)."""


def _wavenumbers(b: np.ndarray, r2: float, s2: float) -> tuple[np.ndarray, ...]:
    """``(μ_β, D_β, μ_α, D_α)`` at frequencies ``b``: ``μ = k²`` of each pair, ``D = μ + b² s²``,
    each without cancellation (``μ_β = −β² < 0``, ``D_β < 0 < D_α``)."""
    b2 = b * b
    x = b2 * (r2 - s2)
    root = np.hypot(x, 2.0 * b)
    beta2 = 0.5 * (b2 * (r2 + s2) + root)
    # beta^2 - b^2 s^2 = (root + x) / 2 and alpha^2 + b^2 s^2 = (root - x) / 2, written so neither cancels
    with np.errstate(divide="ignore", invalid="ignore"):
        plus = np.where(x >= 0.0, 0.5 * (root + x), 2.0 * b2 / (root - x))
        minus = np.where(x <= 0.0, 0.5 * (root - x), 2.0 * b2 / (root + x))
    alpha2 = b2 * (1.0 - b2 * r2 * s2) / beta2
    return -beta2, -plus, alpha2, minus


def _cs_at_one(mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``C(1)`` and ``S(1)`` of a pair with ``k² = μ`` (entire in ``μ``)."""
    q = np.sqrt(np.abs(mu))
    h = np.minimum(q, 1.0)  # the hyperbolic form serves only alpha <= 1 (larger ones take the exponentials)
    c = np.where(mu < 0.0, np.cos(q), np.cosh(h))
    small = q < 1e-4
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(mu < 0.0, np.sin(q) / q, np.sinh(h) / h)
    s = np.where(small, 1.0 + mu / 6.0, s)
    return c, s


def _entire_columns(mu: np.ndarray, d: np.ndarray, out: np.ndarray, first: int) -> None:
    """Columns ``first`` and ``first + 1`` (the solutions ``(C, D S)`` and ``(μ S / D, C)``) of the
    end values ``out[end, quantity, column, :]``, quantities ``(W, ψ, ψ', shear / (b² s²))``."""
    c1, s1 = _cs_at_one(mu)
    a, b = first, first + 1
    out[0, 0, a], out[0, 1, a], out[0, 2, a], out[0, 3, a] = 1.0, 0.0, d, 0.0  # at ξ = 0: C = 1, S = 0
    out[0, 0, b], out[0, 1, b], out[0, 2, b], out[0, 3, b] = 0.0, 1.0, 0.0, -1.0 / d
    out[1, 0, a], out[1, 1, a], out[1, 2, a], out[1, 3, a] = c1, d * s1, d * c1, -s1
    out[1, 0, b], out[1, 1, b], out[1, 2, b], out[1, 3, b] = mu * s1 / d, c1, mu * s1, -c1 / d


def _matrices(b: np.ndarray, r2: float, s2: float, left: str, right: str) -> np.ndarray:
    """The scaled 4 × 4 boundary matrices ``M(b)``, shape ``(len(b), 4, 4)``."""
    mu_b, d_b, mu_a, d_a = _wavenumbers(b, r2, s2)
    values = np.empty((2, 4, 4, b.size))  # end, quantity, column, frequency
    _entire_columns(mu_b, d_b, values, 0)
    _entire_columns(mu_a, d_a, values, 2)
    big = mu_a > _EXPONENTIAL_ABOVE**2
    if np.any(big):
        alpha, d = np.sqrt(mu_a[big]), d_a[big]
        decay = np.exp(-alpha)
        for end, (e1, e2) in enumerate(((1.0, decay), (decay, 1.0))):
            for quantity, (v1, v2) in enumerate(((e1, e2), (-d / alpha * e1, d / alpha * e2), (d * e1, d * e2),
                                                 (e1 / alpha, -e2 / alpha))):
                values[end, quantity, 2, big] = v1
                values[end, quantity, 3, big] = v2
    # each column (a solution) scaled by its largest end value, of all four quantities at both ends:
    # that never vanishes (a solution with all of them zero at an end is zero), where its largest entry
    # in the rows kept does when the solution alone meets one end's conditions (a root)
    values /= np.abs(values).max(axis=(0, 1))
    m = np.concatenate([values[0, _END_ROWS[left]], values[1, _END_ROWS[right]]]).transpose(2, 0, 1)
    m /= np.abs(m).max(axis=2, keepdims=True)  # rows: no row vanishes (the columns are a basis)
    return m


def _b_of_wavenumber(q: np.ndarray, r2: float, s2: float, upper: bool) -> np.ndarray:
    """The frequencies ``b`` at which an oscillatory wavenumber equals ``q``: the lower (flexural,
    ``β = q``) or the upper (second spectrum, ``|α| = q``) root of the dispersion relation."""
    q2 = q * q
    p = (r2 + s2) * q2 + 1.0
    disc = np.sqrt(np.maximum(p * p - 4.0 * r2 * s2 * q2 * q2, 0.0))
    b2 = (p + disc) / (2.0 * r2 * s2) if upper else 2.0 * q2 * q2 / (p + disc)
    return np.sqrt(b2)


def _refine(lo: np.ndarray, hi: np.ndarray, det, max_iterations: int = 200) -> np.ndarray:
    """Roots of ``det`` inside the brackets ``[lo, hi]`` (a sign change in each), all at once:
    the Illinois variant of regula falsi with a bisection step whenever a bracket fails to halve,
    until each bracket is a few ulps wide."""
    lo, hi = lo.copy(), hi.copy()
    f_lo, f_hi = det(lo), det(hi)
    side = np.zeros(lo.size)
    for iteration in range(max_iterations):
        open_ = (hi - lo > 4.0 * np.spacing(hi)) & (f_lo != 0.0) & (f_hi != 0.0)
        if not open_.any():
            break
        with np.errstate(divide="ignore", invalid="ignore"):
            x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        bisect = ~((x > lo) & (x < hi)) | (iteration % 4 == 3)
        x = np.where(bisect, 0.5 * (lo + hi), x)
        x = np.where(open_, x, lo)
        f_x = det(x)
        low = (np.sign(f_x) == np.sign(f_lo)) & open_
        high = ~low & open_
        # Illinois: halve the stale end's value when the same end moves twice
        f_hi = np.where(low & (side == -1), 0.5 * f_hi, f_hi)
        f_lo = np.where(high & (side == 1), 0.5 * f_lo, f_lo)
        lo, f_lo = np.where(low, x, lo), np.where(low, f_x, f_lo)
        hi, f_hi = np.where(high, x, hi), np.where(high, f_x, f_hi)
        side = np.where(low, -1.0, np.where(high, 1.0, side))
        side = np.where(bisect, 0.0, side)
    return np.where(np.abs(f_lo) <= np.abs(f_hi), lo, hi)


def _golden_minima(func, lo: np.ndarray, hi: np.ndarray, iterations: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Locations and values of the minima of ``func`` on the intervals ``[lo, hi]``, all at once
    (golden-section search, each interval shrunk ``0.618**iterations`` times)."""
    ratio = 0.5 * (math.sqrt(5.0) - 1.0)
    a, b = lo.copy(), hi.copy()
    c, d = b - ratio * (b - a), a + ratio * (b - a)
    f_c, f_d = func(c), func(d)
    for _ in range(iterations):
        left = f_c < f_d  # the minimum is in [a, d]
        b = np.where(left, d, b)
        a = np.where(left, a, c)
        c_new = np.where(left, b - ratio * (b - a), d)
        d_new = np.where(left, c, a + ratio * (b - a))
        f_known = np.where(left, f_c, f_d)
        x = np.where(left, c_new, d_new)
        f_x = func(x)
        f_c, f_d = np.where(left, f_x, f_known), np.where(left, f_known, f_x)
        c, d = c_new, d_new
    first = f_c < f_d
    return np.where(first, c, d), np.where(first, f_c, f_d)


def _roots(r2: float, s2: float, left: str, right: str, count: int) -> np.ndarray:
    """The lowest ``count`` roots ``b > 0`` of ``det M(b) = 0``."""

    def det(values: np.ndarray) -> np.ndarray:
        return np.linalg.det(_matrices(values, r2, s2, left, right))

    top = (count + 2) * math.pi
    while True:
        q = np.arange(0.25, top / _STEP + 1.0) * _STEP
        limit = _b_of_wavenumber(np.array([top]), r2, s2, upper=False)[0]
        grid = [_b_of_wavenumber(q, r2, s2, upper=False)]
        b_cut = 1.0 / math.sqrt(r2 * s2)
        if b_cut < limit:
            upper = _b_of_wavenumber(np.concatenate([[0.0], q]), r2, s2, upper=True)
            grid.append(upper[upper <= limit])
        b = np.unique(np.concatenate(grid))
        f = det(b)
        for _ in range(4):  # a point exactly on a root (the pinned bar's cut-off mode) moves off it a little,
            zero = f == 0.0  # so the steps on both sides keep their signs
            if not zero.any():
                break
            b[zero] *= 1.0 - 1e-9
            f[zero] = det(b[zero])
        sign = np.sign(f)
        roots = [b[sign == 0.0]]
        change = sign[:-1] * sign[1:] < 0.0
        lo, hi = [b[:-1][change]], [b[1:][change]]
        # each family of waves has at most one root in a step, so a step holds at most two; two show
        # no sign change but a dip of the determinant through zero between its ends
        same = np.flatnonzero(sign[:-1] * sign[1:] > 0.0)
        same = same[same > 0]  # not the first step, next to the free bar's rigid modes (a double root at b = 0)
        if same.size:
            side = sign[same]
            where, value = _golden_minima(lambda x, side=side: side * det(x), b[same], b[same + 1])
            dip = value < 0.0
            lo += [b[same][dip], where[dip]]
            hi += [where[dip], b[same + 1][dip]]
            width = b[same + 1] - b[same]
            inside = (where - b[same] > 1e-6 * width) & (b[same + 1] - where > 1e-6 * width)  # not an end's root
            double = (value >= 0.0) & (value < 1e-12) & inside  # two modes at one frequency
            roots += [where[double], where[double]]
        lo, hi = np.concatenate(lo), np.concatenate(hi)
        if lo.size:
            roots.append(_refine(lo, hi, det))
        found = np.sort(np.concatenate(roots))
        if found.size >= count:
            return found[:count]
        top *= 2.0


def _bar_roots(r2: float, s2: float, left: str, right: str, count: int) -> np.ndarray:
    """The lowest ``count`` roots ``b`` of a bar; a symmetric bar's as those of its half with the
    middle guided (symmetric modes) and pinned (antisymmetric ones), so that a symmetric and an
    antisymmetric mode that nearly coincide are never looked for in one determinant."""
    if left != right:
        return _roots(r2, s2, left, right, count)
    # the half is half as long: r^2 and s^2 four times, b a quarter
    halves = [_roots(4.0 * r2, 4.0 * s2, left, middle, count) for middle in ("guided", "pinned")]
    return 4.0 * np.sort(np.concatenate(halves))[:count]


def timoshenko_frequencies(
    *,
    youngs_modulus_pa: float,
    density_kg_m3: float,
    shear_modulus_pa: float,
    shear_coefficient: float,
    length_m: float,
    thickness_m: float,
    bc: str,
    count: int,
) -> np.ndarray:
    """Mode frequencies of a uniform rectangular Timoshenko bar (Hz), from its characteristic equation.

    The width cancels. Damping is not included. As the bar gets thin the frequencies approach
    :func:`~barsynth.physics.bar_frequencies` (relative difference of order ``(λ_n h / L)²``).

    Parameters
    ----------
    youngs_modulus_pa : float
        Young's modulus ``E`` in Pa, > 0.
    density_kg_m3 : float
        Density ``ρ`` in kg/m³, > 0.
    shear_modulus_pa : float
        Shear modulus ``G`` in Pa, > 0 (along the grain for wood).
    shear_coefficient : float
        Timoshenko's shear coefficient ``κ``, above 0 to 1 (dimensionless; see :func:`shear_coefficient`).
    length_m : float
        Length ``L`` in m, > 0.
    thickness_m : float
        Thickness ``h`` in m (in the bending direction), above 0 to ``length_m``.
    bc : str
        Boundary conditions, one of :data:`~barsynth.physics.BOUNDARY_CONDITIONS` (the first name is
        the end at ``x = 0``).
    count : int
        Number of modes, 1 to :data:`MAX_COUNT`.

    Returns
    -------
    numpy.ndarray
        float64, shape ``(count,)``, in Hz, non-decreasing (rigid-body modes left out).

    Raises
    ------
    ParameterError
        A parameter out of range, or an unknown ``bc``.

    Examples
    --------
    >>> f = timoshenko_frequencies(youngs_modulus_pa=20e9, density_kg_m3=1000.0, shear_modulus_pa=1.4e9,
    ...                            shear_coefficient=5 / 6, length_m=0.4, thickness_m=0.02,
    ...                            bc="free-free", count=3)
    >>> (f / f[0]).round(3).tolist()  # Euler–Bernoulli: 1, 2.757, 5.404
    [1.0, 2.599, 4.714]
    """
    positive = {"minimum": 0.0, "minimum_exclusive": True}
    e = check_number("youngs_modulus_pa", youngs_modulus_pa, "Pa", **positive)
    rho = check_number("density_kg_m3", density_kg_m3, "kg/m³", **positive)
    g = check_number("shear_modulus_pa", shear_modulus_pa, "Pa", **positive)
    kappa = check_number("shear_coefficient", shear_coefficient, "", **positive, maximum=1.0)
    length = check_number("length_m", length_m, "m", **positive)
    thickness = check_number("thickness_m", thickness_m, "m", **positive, maximum=length)
    name = _check_bc(bc)
    n = check_whole("count", count, "modes", 1, MAX_COUNT, integral_floats=True)
    ratio = e / (kappa * g)
    try:  # (for extreme sizes h^2 and L^2 alone leave the float range: one line, below)
        r2 = thickness**2 / (12.0 * length**2)
    except (OverflowError, ZeroDivisionError):
        r2 = math.nan
    s2 = r2 * ratio
    if not (math.isfinite(ratio) and ratio > 0.0 and r2 > 0.0 and s2 > 0.0 and r2 * s2 > 0.0):
        raise ParameterError(
            f"parameters youngs_modulus_pa = {youngs_modulus_pa!r}, shear_modulus_pa = {shear_modulus_pa!r}, "
            f"thickness_m = {thickness_m!r}, length_m = {length_m!r} are out of float range; allowed: "
            "E / (kappa G) and (h / L)^4 E / (kappa G) positive normal floats")
    left, right = name.split("-")
    b = _bar_roots(r2, s2, left, right, n)
    try:
        scale = math.sqrt(e / rho) * thickness / (math.sqrt(12.0) * length**2) / (2.0 * math.pi)
    except (OverflowError, ZeroDivisionError):
        scale = math.nan
    if not (math.isfinite(scale) and scale > 0.0):
        raise ParameterError(f"parameter length_m = {length_m!r} is out of range for thickness_m = {thickness_m!r}; "
                             "allowed: sizes whose frequencies are finite positive floats (m)")
    freqs = b * scale
    if not np.all(np.isfinite(freqs) & (freqs > 0.0)):
        raise ParameterError(
            f"parameters youngs_modulus_pa = {youngs_modulus_pa!r}, density_kg_m3 = {density_kg_m3!r}, "
            f"length_m = {length_m!r}, thickness_m = {thickness_m!r} give frequencies that are not finite "
            "positive numbers; allowed: values whose frequencies stay within float range (Hz)")
    return freqs
