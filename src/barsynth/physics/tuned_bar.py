"""A free-free bar whose modes fall at given ratios: a thickness profile fitted to them.

Source: the grid operator of :mod:`barsynth.physics.grid` (S. Bilbao, Numerical Sound
Synthesis, Wiley 2009, ch. 7; A. Chaigne and V. Doutaut, JASA 101 (1997)), for a free-free
bar of uniform width whose thickness ``h(x)`` is symmetric about its middle and piecewise
linear between equally spaced control points from the middle to the ends, each from
:data:`~barsynth.physics.profiles.THINNEST` to 1 of the full thickness. That is how tuned bars
are made: a marimba or xylophone bar is thinned under its middle until its modes sit at
1 : 4 : 10 or 1 : 3 : 6 (T. D. Rossing, Science of Percussion Instruments, 2000, ch. 5).

:func:`tune_bar` fits the control points by least squares on the modes' log-frequency ratios
(SciPy's bounded trust-region solver), with each eigenvalue's exact derivative,
``d(w_n^2) = v_n^T (dK - w_n^2 dM) v_n`` for mass-normalised ``v_n``, and a small pull towards
the uniform bar (:data:`PULL`) that picks the least-cut bar among those that fit. The ratios
alone fix the shapes: the bar's length, thickness, material and width only scale its
frequencies, so they are left at 1.

The modes it gives are those of the grid (:func:`points_for` nodes, at least 16 a wavelength
of the highest mode): ``TunedBar.fits`` when every mode lies within :data:`TOLERANCE_CENTS` of
its ratio. The family is wide: 1 : 4 : 10 (thinned under the middle), 1 : 2 : 3 (thinned
near the ends), even 1 : 1.02 : 3 (two halves joined by a thin middle). Not every set is a
bar's: two modes closer than any such bar can bring them (1 : 1.001 : 5) or spread further than
a bar 2 % thick in places can reach (1 : 100) are not; :func:`tune_bar` then returns the nearest
bar it found, with ``fits`` false and its errors in cents. A fit takes 0.01 to 0.25 s for up to
12 modes that fit, 0.8 s for 24, and up to 2 s (:data:`MAX_EVALUATIONS`) for 24 that do not
(measured); it is kept, so a redesign for another setting finds it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .profiles import THINNEST

TOLERANCE_CENTS = 1.0
"""A bar fits the ratios when every mode lies this close to its ratio (cents)."""
PULL = 1e-4
"""Weight of the pull of each control point towards the full thickness (in the units of the
residuals, natural-log frequency ratios: 1e-4 is 0.17 cent), which picks the least-cut bar
among those that fit (fewer ratios than control points leave many)."""
MAX_EVALUATIONS = 200
"""The most eigen-solves one fit may take (about 0.5 ms each for 4 modes, 9 ms for 24)."""
RIGID_MODES = 2
"""A free-free bar's two rigid-body motions (zero frequency), which the fit skips."""


def points_for(count: int) -> int:
    """Grid nodes for a bar of ``count`` modes: at least 16 a wavelength of the highest (its
    wavelength is about 2 / (count + 0.5) of the length), and no fewer than 161."""
    return max(161, 8 * (2 * count + 1) + 1)


def controls_for(count: int) -> int:
    """Control points of the profile (middle to end) for ``count`` modes: two more than the
    ``count - 1`` ratios a fit must meet, and at least 4."""
    return max(4, count + 2)


@dataclass(frozen=True)
class TunedBar:
    """A free-free bar fitted to mode ratios (see the module docstring).

    ``target``: the ratios asked for, increasing, each over the lowest; ``ratios``: the bar's
    (its modes over its first); ``cents``: each mode's error; ``controls``: the relative
    thickness at the control points, from the middle to an end; ``x``: the grid's nodes
    (fractions of the length); ``shapes``: each mode's shape at the nodes (modes x nodes),
    normalised so that its mass-weighted mean square is 1 (for a uniform bar, the mean square:
    :func:`~barsynth.physics.mode_shape`'s normalisation) and positive at ``x = 0``.
    """

    target: np.ndarray
    ratios: np.ndarray
    cents: np.ndarray
    controls: np.ndarray
    x: np.ndarray
    shapes: np.ndarray

    @property
    def fits(self) -> bool:
        """Whether every mode lies within :data:`TOLERANCE_CENTS` of its ratio."""
        return bool(np.all(np.abs(self.cents) <= TOLERANCE_CENTS))

    def thickness(self, x) -> np.ndarray:
        """The relative thickness at positions ``x`` (fractions of the length)."""
        where = np.asarray(x, dtype=np.float64)
        return (_profile_matrix(where.ravel(), self.controls.size) @ self.controls).reshape(where.shape)

    def shapes_at(self, position) -> np.ndarray:
        """Each mode's shape at ``position`` (a fraction of the length; an array of them gives
        modes x positions), linearly interpolated between the grid's nodes."""
        where = np.asarray(position, dtype=np.float64)
        return np.array([np.interp(where, self.x, shape) for shape in self.shapes])


def _profile_matrix(x: np.ndarray, controls: int) -> np.ndarray:
    """The matrix A (positions x controls) with ``h(x) = A c``: linear interpolation between
    control points at distances ``0, 0.5 / (controls - 1), ..., 0.5`` from the middle."""
    distance = np.abs(np.asarray(x, dtype=np.float64).ravel() - 0.5) * (2.0 * (controls - 1))  # in spacings
    left = np.minimum(np.floor(distance).astype(np.int64), controls - 2)
    frac = distance - left
    a = np.zeros((distance.size, controls))
    rows = np.arange(distance.size)
    a[rows, left] = 1.0 - frac
    a[rows, left + 1] = frac
    return a


class _Bar:
    """The free-free grid bar of relative thickness ``h`` at ``n`` nodes (length, material,
    width and full thickness 1): its mass and stiffness (:mod:`.grid`'s operator, built
    banded), its modes and their derivatives by ``h``."""

    def __init__(self, points: int):
        self.n = points
        self.dx = 1.0 / (points - 1)
        self.end_half = np.ones(points)
        self.end_half[[0, -1]] = 0.5  # a free end's node carries half a cell

    def solve(self, h: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
        """The lowest ``count`` vibrating modes: eigenvalues ``w^2`` and mass-normalised shapes
        (nodes x modes)."""
        from scipy.linalg import eig_banded

        dx = self.dx
        mass = h * dx * self.end_half
        weight = np.zeros(self.n)  # each node's bending stiffness E I dx / dx^4 (no moment at a free end)
        weight[1:-1] = h[1:-1] ** 3 / dx ** 3
        # K = sum_l weight_l r_l r_l^T, r_l = (1, -2, 1) at nodes l-1, l, l+1
        diagonal = 4.0 * weight
        diagonal[:-1] += weight[1:]
        diagonal[1:] += weight[:-1]
        first = -2.0 * (weight[:-1] + weight[1:])
        second = weight[1:-1]
        scale = 1.0 / np.sqrt(mass)
        bands = np.zeros((3, self.n))
        bands[2] = diagonal * scale * scale
        bands[1, 1:] = first * scale[:-1] * scale[1:]
        bands[0, 2:] = second * scale[:-2] * scale[2:]
        values, vectors = eig_banded(bands, select="i", select_range=(RIGID_MODES, RIGID_MODES + count - 1))
        self.mass, self.weight = mass, weight
        return values, vectors * scale[:, None]

    def gradient(self, h: np.ndarray, values: np.ndarray, shapes: np.ndarray) -> np.ndarray:
        """``d(w_n^2) / dh_i`` (modes x nodes) at the last :meth:`solve`."""
        curvature = np.zeros_like(shapes)
        curvature[1:-1] = shapes[:-2] - 2.0 * shapes[1:-1] + shapes[2:]
        stiff = 3.0 * (self.weight / np.where(h > 0.0, h, 1.0))[:, None] * curvature ** 2
        heavy = (self.mass / h)[:, None] * shapes ** 2
        return (stiff - values[None, :] * heavy).T


def _fit(target: np.ndarray) -> TunedBar:
    from scipy.optimize import least_squares

    count = target.size
    bar = _Bar(points_for(count))
    x = np.linspace(0.0, 1.0, bar.n)
    controls = controls_for(count)
    a = _profile_matrix(x, controls)
    goal = np.log(target[1:])
    last: dict[str, np.ndarray] = {}

    def modes(c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if "c" not in last or not np.array_equal(last["c"], c):
            h = a @ c
            values, shapes = bar.solve(h, count)
            last.update(c=c.copy(), h=h, values=values, shapes=shapes,
                        gradient=bar.gradient(h, values, shapes))
        return last["h"], last["values"], last["shapes"]

    def residuals(c: np.ndarray) -> np.ndarray:
        _, values, _ = modes(c)
        return np.concatenate([0.5 * np.log(values[1:] / values[0]) - goal, PULL * (c - 1.0)])

    def jacobian(c: np.ndarray) -> np.ndarray:
        _, values, _ = modes(c)
        relative = last["gradient"] / values[:, None]  # d log(w_n^2) / dh
        rows = 0.5 * (relative[1:] - relative[0]) @ a
        return np.vstack([rows, PULL * np.eye(controls)])

    start = np.full(controls, 0.5)  # room to thin or (relatively) thicken anywhere
    found = least_squares(residuals, start, jac=jacobian, bounds=(THINNEST, 1.0), method="trf",
                          max_nfev=MAX_EVALUATIONS, xtol=1e-12, ftol=1e-12, gtol=1e-12)
    c = found.x
    _, values, shapes = modes(c)
    omega = np.sqrt(np.maximum(values, 0.0))
    ratios = omega / omega[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        cents = 1200.0 * np.log2(ratios / target)
    total_mass = float(np.sum(bar.mass))
    shapes = (shapes * math.sqrt(total_mass)).T  # modes x nodes, mass-weighted mean square 1
    shapes *= np.where(shapes[:, :1] < 0.0, -1.0, 1.0)
    for array in (ratios, cents, c, x, shapes):
        array.flags.writeable = False
    return TunedBar(target, ratios, np.nan_to_num(cents, nan=math.inf), c, x, shapes)


def normalised(ratios) -> tuple[float, ...]:
    """``ratios`` increasing, each over the lowest, rounded to 9 significant digits (a
    millionth of a cent): the key a fit is kept by."""
    values = np.sort(np.asarray(ratios, dtype=np.float64))
    if values.size == 0 or not np.all(np.isfinite(values)) or values[0] <= 0.0:
        raise ValueError(f"mode ratios must be finite and positive, not {list(ratios)!r}")
    return tuple(float(f"{r:.9g}") for r in values / values[0])


@lru_cache(maxsize=64)
def _tuned(key: tuple[float, ...]) -> TunedBar:
    from .. import designcache

    return designcache.cached("tunedbar", [float.hex(r) for r in key], SOURCES,
                              lambda: _fit(np.array(key)), _record, _from_record)


SOURCES = ("barsynth.physics.tuned_bar", "barsynth.physics.profiles")
"""The code a fit comes from (the on-disk cache's key covers it: :mod:`barsynth.designcache`)."""


def tune_bar(ratios) -> TunedBar:
    """The free-free bar (of a symmetric thickness profile) whose modes fall nearest ``ratios``
    (any order and scale: only their ratios to the lowest count). Fitted once per set of ratios
    (:func:`normalised`) and kept (in memory, and on disk for the program:
    :mod:`barsynth.designcache`).

    Examples
    --------
    >>> marimba = tune_bar([1.0, 4.0, 10.0])
    >>> marimba.fits, marimba.ratios.round(3).tolist()
    (True, [1.0, 4.0, 10.0])
    >>> float(marimba.thickness(0.5)) < float(marimba.thickness(0.0))  # thinned under its middle
    True
    >>> tune_bar([1.0, 1.001, 5.0]).fits  # two modes 1.7 cents apart: no bar's
    False
    """
    return _tuned(normalised(ratios))


def _record(bar: TunedBar) -> dict:
    from ..designcache import array_record

    return {name: array_record(getattr(bar, name)) for name in ("target", "ratios", "cents", "controls", "x",
                                                                 "shapes")}


def _from_record(record: dict) -> TunedBar:
    from ..designcache import array_from

    arrays = {name: array_from(record[name]) for name in ("target", "ratios", "cents", "controls", "x", "shapes")}
    for array in arrays.values():
        array.flags.writeable = False
    if arrays["shapes"].shape != (arrays["target"].size, arrays["x"].size):
        raise ValueError("malformed tuned bar")
    return TunedBar(**arrays)
