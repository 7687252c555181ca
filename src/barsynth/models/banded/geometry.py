"""The bar of ``tuning = geometry``: its modes and mode shapes from its material, size and profile.

Sources: the Euler–Bernoulli grid (:mod:`barsynth.physics.grid`) and the staggered Timoshenko
grid (:mod:`barsynth.physics.timoshenko_grid`; S. Timoshenko, Phil. Mag. 41, 1921; A. Chaigne
and V. Doutaut, JASA 101, 1997, who model a xylophone bar so), for a free-free bar of any
thickness profile (:class:`~barsynth.physics.profiles.Profile`): a banded bar rests on its
nodes, so both ends are free. The frequencies are Richardson-extrapolated from two grids
(``points`` and ``2 points - 1`` nodes, :func:`points_for`), as :func:`~barsynth.physics.grid.
grid_modes` does; the shapes are the finer grid's deflections (the deflection part of the
two-field eigenvectors), normalised like :func:`~barsynth.physics.mode_shape` and the tuned
bar's (:mod:`barsynth.physics.tuned_bar`): the whole mode, rotation included, has the bar's
mass as its modal mass (for a uniform thin bar, a mean square of 1), and each starts upward
from the ``x = 0`` end. Between nodes a shape is interpolated linearly.

A uniform Euler–Bernoulli bar needs no grid: the model takes its closed form (the very modes
and shapes of ``tuning = physics``, see :func:`closed_form`). A uniform Timoshenko bar's
frequencies are its closed form's (:func:`~barsynth.physics.timoshenko.timoshenko_frequencies`,
for a bar no thicker than long), its shapes the grid's.

A design takes 0.05 to 0.5 s (more for 24 modes): it is kept, in memory and on disk for the
program (:mod:`barsynth.designcache`), so a redesign for another setting finds it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from ...physics.profiles import Profile
from ..rows import profile_of, shear_of

SOURCES = ("barsynth.models.banded.geometry", "barsynth.physics.grid", "barsynth.physics.timoshenko",
           "barsynth.physics.timoshenko_grid", "barsynth.physics.profiles")
"""The code a design comes from (the on-disk cache's key covers it)."""


@dataclass(frozen=True)
class GeometryBar:
    """A free-free bar's modes: ``frequencies_hz`` (Hz), ``x`` (the grid's nodes, fractions of
    the length), ``shapes`` (each mode's deflection at the nodes, modes x nodes, normalised as
    the module docstring says) and ``mass_kg`` (the bar's mass)."""

    frequencies_hz: np.ndarray
    x: np.ndarray
    shapes: np.ndarray
    mass_kg: float

    def shapes_at(self, position: Any) -> np.ndarray:
        """Each mode's shape at ``position`` (a fraction of the length; an array of them gives
        modes x positions), linearly interpolated between the grid's nodes."""
        where = np.asarray(position, dtype=np.float64)
        return np.array([np.interp(where, self.x, shape) for shape in self.shapes])


def closed_form(p: Any) -> bool:
    """Whether ``p`` (``tuning = geometry``) is a uniform Euler–Bernoulli bar: the closed form's
    (``tuning = physics``'s) modes and shapes, no grid."""
    return p.theory == "euler-bernoulli" and (p.profile == "uniform" or (
        p.profile in ("parabolic", "circular") and p.undercut_depth == 0.0))


def points_for(count: int) -> int:
    """The coarser grid's nodes for ``count`` modes: at least 16 a wavelength of the highest (about
    ``2 / (count + 0.5)`` of the length) and no fewer than 161 (the finer has ``2 points - 1``)."""
    return max(161, 8 * (2 * count + 1) + 1)


def geometry_bar(p: Any) -> GeometryBar:
    """The free-free bar of the record ``p`` (the banded model's rows: material, size, ``theory``
    with its shear, profile, ``mode_count``), designed once and kept."""
    theory = p.theory
    shear_modulus_pa, shear_coefficient = shear_of(p) if theory == "timoshenko" else (0.0, 0.0)
    profile = profile_of(p)
    return _kept(theory, p.youngs_modulus_pa, p.density_kg_m3, shear_modulus_pa, shear_coefficient, p.length_m,
                 p.thickness_m, p.width_m, profile.kind, profile.depth, profile.width, profile.samples, p.mode_count)


@lru_cache(maxsize=64)
def _kept(*key: Any) -> GeometryBar:
    from ... import designcache

    inputs = [float.hex(float(v)) if isinstance(v, float) else v for v in key[:-2]]
    inputs += [[float.hex(float(v)) for v in key[-2]], key[-1]]
    return designcache.cached("geometrybar", inputs, SOURCES, lambda: _design(*key), _record, _from_record)


def _design(theory: str, youngs_modulus_pa: float, density_kg_m3: float, shear_modulus_pa: float,
            shear_coefficient: float, length_m: float, thickness_m: float, width_m: float, kind: str, depth: float,
            width: float, samples: tuple[float, ...], count: int) -> GeometryBar:
    from ...physics.grid import bar_grid, grid_eigen
    from ...physics.timoshenko_grid import timoshenko_grid

    bar = dict(youngs_modulus_pa=youngs_modulus_pa, density_kg_m3=density_kg_m3, length_m=length_m,
               thickness_m=thickness_m, width_m=width_m, bc="free-free",
               profile=Profile(kind, depth=depth, width=width, samples=samples))
    if theory == "timoshenko":
        thin_first = grid_eigen(bar_grid(points=MIN_POINTS_FOR_ESTIMATE, **bar), 1)[0][0]

        def solve(points: int):
            grid = timoshenko_grid(points=points, shear_modulus_pa=shear_modulus_pa,
                                   shear_coefficient=shear_coefficient, **bar)
            omega, vectors = _lowest_modes(grid, count, thin_first)
            return omega, grid.x_m / length_m, vectors[grid.w_index], grid.mass[grid.w_index]
    else:
        def solve(points: int):
            grid = bar_grid(points=points, **bar)
            omega, vectors = grid_eigen(grid, count)
            return omega, grid.x_m / length_m, vectors, grid.mass

    points = points_for(count)
    omega, x, deflections, masses = solve(2 * points - 1)
    uniform = kind == "uniform" or (kind in ("parabolic", "circular") and depth == 0.0)
    if theory == "timoshenko" and uniform and thickness_m <= length_m:  # the closed form's domain
        from ...physics.timoshenko import timoshenko_frequencies

        frequencies = timoshenko_frequencies(youngs_modulus_pa=youngs_modulus_pa, density_kg_m3=density_kg_m3,
                                             shear_modulus_pa=shear_modulus_pa, shear_coefficient=shear_coefficient,
                                             length_m=length_m, thickness_m=thickness_m, bc="free-free", count=count)
    else:
        frequencies = (4.0 * omega - solve(points)[0]) / 3.0 / (2.0 * math.pi)
    mass = float(np.sum(masses))
    shapes = (deflections * math.sqrt(mass)).T  # modes x nodes: modal mass = the bar's mass
    shapes *= np.where(shapes[:, :1] < 0.0, -1.0, 1.0)
    for array in (frequencies, x, shapes):
        array.flags.writeable = False
    return GeometryBar(frequencies, x, shapes, mass)


MIN_POINTS_FOR_ESTIMATE = 41
"""Nodes of the thin-bar grid whose first mode places the thick bar's shift (:func:`_lowest_modes`)."""


def _lowest_modes(grid, count: int, thin_first: float) -> tuple[np.ndarray, np.ndarray]:
    """The two-field grid's lowest ``count`` vibrating modes: angular frequencies (rad/s) and
    mass-normalised shapes (columns), its two rigid motions left out.

    :func:`~barsynth.physics.timoshenko_grid.two_field_eigen` solves the dense problem (1.2 to
    5 s for 24 modes on 785 nodes, measured); this is sparse shift-invert (ARPACK) about
    ``-thin_first^2 / 4``, a quarter of the thin (Euler–Bernoulli) bar's first mode below zero,
    where ``K + s M`` is safely definite and the rigid motions and the lowest modes are nearest:
    0.1 to 0.3 s, and the same modes within 6e-9 and shapes within 3e-11 for bars from a 19 cm
    steel glockenspiel bar to a 5 cm cube (measured; for a 3 m x 0.3 mm sheet both solvers' rounding
    is about 1e-5). It starts from a fixed vector, so a design is the same to the last bit every time."""
    from scipy.sparse import csc_matrix, diags
    from scipy.sparse.linalg import ArpackError, eigsh

    from ...physics.timoshenko_grid import two_field_eigen

    start = np.random.default_rng(0).standard_normal(grid.mass.size)  # ARPACK's own start is random: not this
    try:
        values, vectors = eigsh(csc_matrix(grid.stiffness), k=count + 2, M=diags(grid.mass).tocsc(),
                                sigma=-0.25 * thin_first ** 2, which="LM", v0=start)
    except ArpackError:  # (none seen: 65 random bars over the table's ranges agreed with the dense solver)
        return two_field_eigen(grid, count)
    order = np.argsort(values)[2:]  # the rigid motions (0) first
    values, vectors = values[order], vectors[:, order]
    norms = np.sqrt(np.einsum("in,i,in->n", vectors, grid.mass, vectors))
    return np.sqrt(np.maximum(values, 0.0)), vectors / norms


def _record(bar: GeometryBar) -> dict:
    from ...designcache import array_record

    return {"frequencies_hz": array_record(bar.frequencies_hz), "x": array_record(bar.x),
            "shapes": array_record(bar.shapes), "mass_kg": float.hex(bar.mass_kg)}


def _from_record(record: dict) -> GeometryBar:
    from ...designcache import array_from

    arrays = {name: array_from(record[name]) for name in ("frequencies_hz", "x", "shapes")}
    for array in arrays.values():
        array.flags.writeable = False
    if arrays["shapes"].shape != (arrays["frequencies_hz"].size, arrays["x"].size):
        raise ValueError("malformed geometry bar")
    return GeometryBar(**arrays, mass_kg=float.fromhex(record["mass_kg"]))
