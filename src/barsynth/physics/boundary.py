"""Boundary conditions of a uniform Euler–Bernoulli bar and their eigenvalues.

A bar of length ``L`` with a pair of end conditions vibrates in modes with
wavenumbers ``k_n = lambda_n / L``, where ``lambda_n`` is the n-th positive root of
the characteristic equation of the pair (spec 1.2; Fletcher & Rossing, *The
Physics of Musical Instruments*, 2nd ed., Springer 1998, ch. 2; Blevins, *Formulas
for Natural Frequency and Mode Shape*, 1979, table 8-1). The first six roots for
the free–free bar and the cantilever are printed in Selfridge et al., AES
Convention Paper 10553 (2022), Table 1; this module computes any number of them.

Each root is found by bracketed root finding (:func:`bracketed_root`: the Illinois
variant of regula falsi, guarded by bisection; no SciPy import, so start-up stays fast) on a
rescaled form of the equation that stays of order one for any ``lambda``:

====================  ==========================  ===========================  ===========
boundary conditions   characteristic equation     form solved                  asymptote
====================  ==========================  ===========================  ===========
free-free             cos λ cosh λ = 1 (λ > 0)    cos λ − sech λ = 0           (n + ½)π
clamped-free          cos λ cosh λ = −1           cos λ + sech λ = 0           (n − ½)π
clamped-clamped       cos λ cosh λ = 1            cos λ − sech λ = 0           (n + ½)π
pinned-pinned         sin λ = 0                   sin λ = 0                    nπ
clamped-pinned        tan λ = tanh λ              sin λ − cos λ tanh λ = 0     (n + ¼)π
====================  ==========================  ===========================  ===========

The n-th root lies within π/4 of its asymptote, and on that interval the rescaled
function changes sign exactly once, so ``[asymptote − π/4, asymptote + π/4]`` is a
valid bracket for every n. The first name of a pair is the end at ``x = 0``.
Free–free excludes the two rigid-body modes (λ = 0).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ..checks import check_choice, check_whole

__all__ = ["BOUNDARY_CONDITIONS", "lambda_ratios", "lambdas"]

BOUNDARY_CONDITIONS: tuple[str, ...] = (
    "free-free",
    "clamped-free",
    "clamped-clamped",
    "pinned-pinned",
    "clamped-pinned",
)

#: Largest number of roots one call may ask for (mode 100 000 of any real bar is
#: far above hearing; the limit only guards against runaway requests).
MAX_COUNT = 100_000

# Asymptote of root n is (n + offset) * pi.
_ASYMPTOTE_OFFSET = {
    "free-free": 0.5,
    "clamped-free": -0.5,
    "clamped-clamped": 0.5,
    "pinned-pinned": 0.0,
    "clamped-pinned": 0.25,
}


def _sech(lam: float) -> float:
    """1 / cosh(lam) without overflow for large lam."""
    e = math.exp(-abs(lam))
    return 2.0 * e / (1.0 + e * e)


def _cos_minus_sech(lam: float) -> float:
    return math.cos(lam) - _sech(lam)


def _cos_plus_sech(lam: float) -> float:
    return math.cos(lam) + _sech(lam)


def _tan_minus_tanh(lam: float) -> float:
    # (sin λ cosh λ − cos λ sinh λ) / cosh λ
    return math.sin(lam) - math.cos(lam) * math.tanh(lam)


_CHARACTERISTIC = {
    "free-free": _cos_minus_sech,
    "clamped-free": _cos_plus_sech,
    "clamped-clamped": _cos_minus_sech,
    "pinned-pinned": math.sin,
    "clamped-pinned": _tan_minus_tanh,
}


def _check_bc(bc: object) -> str:
    """The canonical name of a boundary-condition pair, or ParameterError."""
    return check_choice("bc", bc, BOUNDARY_CONDITIONS, normalize=_dashes)


def _dashes(name: str) -> str:
    return name.replace("_", "-").replace("–", "-")


def bracketed_root(func, lo: float, hi: float, *, max_iterations: int = 200) -> float:
    """A root of ``func`` inside ``[lo, hi]``, where ``func`` changes sign.

    Illinois regula falsi (superlinear), with a bisection step whenever an update
    would not shrink the bracket by half; stops when the bracket is a few ulps wide
    or ``func`` is exactly zero.
    """
    f_lo, f_hi = func(lo), func(hi)
    if f_lo == 0.0:
        return lo
    if f_hi == 0.0:
        return hi
    if (f_lo > 0.0) == (f_hi > 0.0):
        raise ValueError(f"no sign change of the function on [{lo}, {hi}]")
    side = 0
    for _ in range(max_iterations):
        width = hi - lo
        if width <= 4.0 * math.ulp(max(abs(lo), abs(hi))):
            break
        x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not lo < x < hi:
            x = 0.5 * (lo + hi)
        f_x = func(x)
        if f_x == 0.0:
            return x
        if (f_x > 0.0) == (f_lo > 0.0):
            lo, f_lo = x, f_x
            if side == -1:
                f_hi *= 0.5
            side = -1
        else:
            hi, f_hi = x, f_x
            if side == 1:
                f_lo *= 0.5
            side = 1
        if hi - lo > 0.5 * width:  # slow progress: bisect once
            mid = 0.5 * (lo + hi)
            f_mid = func(mid)
            if f_mid == 0.0:
                return mid
            if (f_mid > 0.0) == (f_lo > 0.0):
                lo, f_lo = mid, f_mid
            else:
                hi, f_hi = mid, f_mid
            side = 0
    return 0.5 * (lo + hi) if abs(f_lo) == abs(f_hi) else (lo if abs(f_lo) < abs(f_hi) else hi)


@lru_cache(maxsize=8192)
def _root(bc: str, n: int) -> float:
    """The n-th (1-based) positive root for the canonical pair ``bc``."""
    centre = (n + _ASYMPTOTE_OFFSET[bc]) * math.pi
    quarter = 0.25 * math.pi
    lo, hi = centre - quarter, centre + quarter
    return bracketed_root(_CHARACTERISTIC[bc], lo, hi)


@lru_cache(maxsize=128)
def _lambdas(bc: str, count: int) -> np.ndarray:
    out = np.array([_root(bc, n) for n in range(1, count + 1)], dtype=np.float64)
    out.flags.writeable = False
    return out


def lambdas(bc: str, count: int) -> np.ndarray:
    """First ``count`` eigenvalues ``lambda_n = k_n L`` of a uniform bar.

    Parameters
    ----------
    bc : str
        Boundary conditions, one of :data:`BOUNDARY_CONDITIONS` (the first name is
        the end at ``x = 0``).
    count : int
        Number of modes, 1 to :data:`MAX_COUNT`.

    Returns
    -------
    numpy.ndarray
        float64, shape ``(count,)``, strictly increasing, dimensionless.

    Raises
    ------
    ParameterError
        Unknown ``bc`` or ``count`` out of range.

    Examples
    --------
    >>> lambdas("clamped-free", 2).round(4)
    array([1.8751, 4.6941])
    """
    name = _check_bc(bc)
    n = check_whole("count", count, "", 1, MAX_COUNT, integral_floats=True)
    return _lambdas(name, n).copy()


def lambda_ratios(bc: str, count: int) -> np.ndarray:
    """Frequency ratios ``(lambda_n / lambda_1)**2`` of the first ``count`` modes.

    Parameters
    ----------
    bc : str
        Boundary conditions, one of :data:`BOUNDARY_CONDITIONS`.
    count : int
        Number of modes, 1 to :data:`MAX_COUNT`.

    Returns
    -------
    numpy.ndarray
        float64, shape ``(count,)``, dimensionless; the first entry is 1.

    Examples
    --------
    >>> lambda_ratios("free-free", 3).round(4)
    array([1.    , 2.7565, 5.4039])
    """
    lam = lambdas(bc, count)
    return (lam / lam[0]) ** 2
