"""A thick bar on a grid: the two-field (Timoshenko) operator and its modes (spec 8.2).

Sources: S. Timoshenko, Phil. Mag. 41 (1921) (shear and rotary inertia); A. Chaigne and
V. Doutaut, JASA 101 (1997) (a Timoshenko xylophone bar in finite differences);
S. Bilbao, Numerical Sound Synthesis (Wiley 2009), ch. 7 (energy-based grids and ends).

The bar ``rho A w_tt = (kappa G A (w_x - theta))_x``, ``rho I theta_tt = (E I theta_x)_x +
kappa G A (w_x - theta)`` with thickness ``h(x)`` (a :class:`~barsynth.physics.profiles.Profile`)
is sampled on a staggered grid: the deflection ``w`` at ``points`` equally spaced nodes and the
rotation ``theta`` at the midpoints between them. The shear strain ``(w[i+1] - w[i]) / dx -
theta[i+1/2]`` lives at the midpoints, the curvature ``(theta[i+1/2] - theta[i-1/2]) / dx`` at
the nodes, so both are centred and the grid has no shear locking. The potential energy is the
midpoint sum of ``kappa G A gamma^2 / 2`` plus the trapezoid sum of ``E I c^2 / 2``; the kinetic
energy that of ``rho A w_t^2 / 2`` at the nodes plus ``rho I theta_t^2 / 2`` at the midpoints.
The ends follow from the energy as on the Euler–Bernoulli grid (:mod:`barsynth.physics.grid`):
a pinned or clamped end does not move; a clamped end's rotation is zero through a ghost
midpoint mirroring its neighbour with the opposite sign; a free or pinned end carries no
bending moment (no curvature term there); a free end's node carries half a cell of mass.

The unknowns are interleaved, ``w[0], theta[1/2], w[1], theta[3/2], ...``, so the mass is
diagonal and the stiffness ``K`` and the loss Laplacian ``L`` (acting on ``w`` only, as on the
Euler–Bernoulli grid) are pentadiagonal: the grid is a :class:`~barsynth.physics.grid.BarGrid`
in all but its layout, and :func:`~barsynth.physics.grid.grid_eigen` and the finite-difference
model's step solve it unchanged. Its modes come from :func:`two_field_eigen`, which keeps the
digits of thin bars that the symmetric standard form loses. Its error falls as ``dx^2``;
:func:`timoshenko_grid_modes` removes that term by Richardson extrapolation (two grids).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..checks import check_number, check_whole
from ..errors import ParameterError
from .grid import (
    MAX_POINTS,
    MIN_POINTS,
    _ends,
    check_grid_size,
    extrapolated_modes,
    interpolation,
    rigid_mode_count,
)
from .profiles import Profile

__all__ = ["TwoFieldGrid", "timoshenko_grid", "timoshenko_grid_modes", "two_field_eigen"]


@dataclass(frozen=True)
class TwoFieldGrid:
    """The staggered grid operator of one thick bar (see the module docstring).

    ``x_m``: positions of the deflection nodes that move (m); ``w_index``: where they sit in the
    interleaved vector of unknowns; ``mass``: the diagonal of ``M`` over all unknowns (kg for a
    deflection, kg m^2 for a rotation); ``stiffness`` and ``damping_laplacian``: ``K`` and ``L``
    as dense symmetric matrices over all unknowns.
    """

    bc: str
    length_m: float
    points: int
    x_m: np.ndarray
    w_index: np.ndarray
    mass: np.ndarray
    stiffness: np.ndarray
    damping_laplacian: np.ndarray

    def weights_at(self, position: float) -> tuple[np.ndarray, np.ndarray]:
        """Indices (in the vector of unknowns) and linear-interpolation weights of the deflection
        at ``position`` (fraction of the length); a fixed node gets no weight."""
        index, weight = interpolation(self.x_m / self.length_m, position, self.points)
        return self.w_index[index], weight

    def deflection(self, vector: np.ndarray) -> np.ndarray:
        """The deflections (rows ``w_index``) of a vector or of the columns of a matrix."""
        return vector[self.w_index]

    def rigid_motions(self) -> list[np.ndarray]:
        """The rigid-body motions of a free-free bar (translation, rotation about the centre of
        mass, each with its rotation field: 0 and 1), otherwise none."""
        if _ends(self.bc) != ("free", "free"):
            return []
        w_mass = self.mass[self.w_index]
        translation = np.zeros(self.mass.size)
        translation[self.w_index] = 1.0
        rotation = np.ones(self.mass.size)
        rotation[self.w_index] = self.x_m - np.sum(w_mass * self.x_m) / np.sum(w_mass)
        return [translation, rotation]


def timoshenko_grid(*, youngs_modulus_pa: float, density_kg_m3: float, shear_modulus_pa: float,
                    shear_coefficient: float, length_m: float, thickness_m: float, width_m: float, bc: str,
                    points: int, profile: Profile | None = None) -> TwoFieldGrid:
    """The staggered grid operator of a thick bar of thickness ``thickness_m x profile(x)`` on
    ``points`` deflection nodes (and ``points - 1`` rotations).

    Examples
    --------
    >>> grid = timoshenko_grid(youngs_modulus_pa=69e9, density_kg_m3=2700.0, shear_modulus_pa=26e9,
    ...                        shear_coefficient=0.85, length_m=0.3, thickness_m=0.01, width_m=0.04,
    ...                        bc="clamped-free", points=11)
    >>> grid.mass.size, grid.x_m.size  # 10 rotations and the 10 nodes that move
    (20, 10)
    """
    left, right = _ends(bc)
    points = check_whole("points", points, "nodes", minimum=MIN_POINTS, maximum=MAX_POINTS)
    positive = {"minimum": 0.0, "minimum_exclusive": True}
    e = check_number("youngs_modulus_pa", youngs_modulus_pa, "Pa", **positive)
    rho = check_number("density_kg_m3", density_kg_m3, "kg/m^3", **positive)
    g = check_number("shear_modulus_pa", shear_modulus_pa, "Pa", **positive)
    kappa = check_number("shear_coefficient", shear_coefficient, "", **positive, maximum=1.0)
    length_m, thickness_m = check_grid_size(length_m, thickness_m)
    width_m = check_number("width_m", width_m, "m", **positive)
    profile = profile or Profile()
    n = points
    dx = length_m / (n - 1)
    x = np.linspace(0.0, length_m, n)
    x_mid = x[:-1] + 0.5 * dx
    shape = dict(length_m=length_m, thickness_m=thickness_m)
    h = thickness_m * profile.relative_thickness(x / length_m, **shape)
    h_mid = thickness_m * profile.relative_thickness(x_mid / length_m, **shape)
    size = 2 * n - 1  # w[i] at 2 i, theta[i + 1/2] at 2 i + 1

    # shear strains at the midpoints, midpoint-rule weights kappa G A dx
    shear = np.zeros((n - 1, size))
    for i in range(n - 1):
        shear[i, 2 * i], shear[i, 2 * i + 2], shear[i, 2 * i + 1] = -1.0 / dx, 1.0 / dx, -1.0
    shear_weight = kappa * g * width_m * h_mid * dx
    # curvatures at the nodes (a clamped end's ghost rotation folded in), trapezoid weights E I dx
    rows, weights = [], []
    ei = e * width_m * h ** 3 / 12.0
    for i in range(n):
        end = left if i == 0 else right if i == n - 1 else None
        row = np.zeros(size)
        if end is None:
            row[2 * i - 1], row[2 * i + 1] = -1.0 / dx, 1.0 / dx
            weight = 1.0
        elif end == "clamped":  # ghost theta = -theta of the neighbouring midpoint: theta = 0 at the end
            row[1 if i == 0 else 2 * i - 1] = 2.0 / dx if i == 0 else -2.0 / dx
            weight = 0.5
        else:  # free or pinned: no moment at the end
            continue
        rows.append(row)
        weights.append(weight * ei[i] * dx)
    bend = np.array(rows)
    stiffness = shear.T @ (shear_weight[:, None] * shear) + bend.T @ (np.array(weights)[:, None] * bend)

    slope = np.zeros((n - 1, size))  # deflection slopes at the midpoints, for the loss Laplacian
    for i in range(n - 1):
        slope[i, 2 * i], slope[i, 2 * i + 2] = -1.0 / dx, 1.0 / dx
    laplacian = slope.T @ ((rho * width_m * h_mid * dx)[:, None] * slope)

    mass = np.zeros(size)
    mass[0::2] = rho * width_m * h * dx
    mass[1::2] = rho * width_m * h_mid ** 3 / 12.0 * dx
    for end, node in ((left, 0), (right, n - 1)):
        if end == "free":
            mass[2 * node] *= 0.5
    fixed = {0} if left != "free" else set()
    if right != "free":
        fixed.add(2 * (n - 1))
    keep = np.array([k for k in range(size) if k not in fixed])
    w_nodes = np.array([i for i in range(n) if 2 * i not in fixed])
    w_index = np.searchsorted(keep, 2 * w_nodes)
    return TwoFieldGrid(bc, float(length_m), n, x[w_nodes], w_index, mass[keep],
                        stiffness[np.ix_(keep, keep)], laplacian[np.ix_(keep, keep)])


def two_field_eigen(grid: TwoFieldGrid, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The grid's lowest ``count`` vibrating modes: angular frequencies (rad/s) and mass-normalised
    shapes (columns over all unknowns, ``v^T M v = 1``), rigid-body motions left out.

    Solved as the largest eigenvalues ``1 / w^2`` of ``M v = mu K v`` (dense LAPACK, Cholesky of
    ``K``): a thin bar's shear stiffness makes ``M^-1/2 K M^-1/2`` span ``(L / h)^4`` in scale, and
    its standard form lost the lowest modes' digits (a cantilever with h/L = 0.001 was 2.7e-4 off;
    this way 2e-7). A free-free bar's ``K`` is first shifted by ``s M`` with ``s`` near the
    first mode's ``omega^2`` (:func:`_first_mode_estimate`), so its rigid motions come out on top
    (``mu = 1 / s``) and are dropped: the solve's error in ``mu`` is about ``eps / s``, so a shift
    far below the first mode cost the higher modes their digits (``(2 pi 0.01 Hz)^2`` put a
    rosewood bar's eighth mode 1e-4 off) and one near it costs none. Should ``K + s M`` have no
    Cholesky factor all the same, the bar is solved on the complement of its rigid motions ``R``:
    with ``Q`` an orthonormal basis of the ``v`` with ``R^T M v = 0`` (from the QR of ``M R``),
    ``Q^T M Q y = mu Q^T K Q y``, ``v = Q y``.
    """
    from scipy.linalg import LinAlgError, eigh, qr

    skip = rigid_mode_count(grid.bc)
    size = grid.mass.size
    if count + skip > size:
        raise ParameterError(f"parameter count = {count} is out of range; allowed: 1 to {size - skip} modes "
                             f"for a grid of {grid.points} points")
    stiffness, shift = grid.stiffness, 0.0
    if skip:
        shift = _first_mode_estimate(grid)
        stiffness = stiffness + shift * np.diag(grid.mass)
    try:
        values, vectors = eigh(np.diag(grid.mass), stiffness, subset_by_index=(size - count - skip, size - 1))
        values, vectors = values[::-1][skip:], vectors[:, ::-1][:, skip:]
    except LinAlgError:
        if not skip:
            raise
        shift = 0.0
        basis = qr(np.array(grid.rigid_motions()).T * grid.mass[:, None])[0][:, skip:]  # M R's complement
        inner = size - skip
        values, vectors = eigh(basis.T @ np.diag(grid.mass) @ basis, basis.T @ grid.stiffness @ basis,
                               subset_by_index=(inner - count, inner - 1))
        values, vectors = values[::-1], basis @ vectors[:, ::-1]
    omega = np.sqrt(np.maximum(1.0 / values - shift, 0.0))
    norms = np.sqrt(np.einsum("in,i,in->n", vectors, grid.mass, vectors))
    return omega, vectors / norms


def _first_mode_estimate(grid: TwoFieldGrid) -> float:
    """An upper estimate of a free-free grid's lowest ``omega^2`` (rad^2/s^2), within a small
    factor of it: the Rayleigh quotient of ``w = cos(2 pi x / L)``, ``theta = w'`` with the rigid
    motions taken out."""
    x = np.zeros(grid.mass.size)
    x[grid.w_index] = grid.x_m / grid.length_m
    between = np.ones(grid.mass.size, dtype=bool)
    between[grid.w_index] = False
    x[between] = 0.5 * (x[np.flatnonzero(between) - 1] + x[np.flatnonzero(between) + 1])
    trial = np.where(between, -2.0 * math.pi / grid.length_m * np.sin(2.0 * math.pi * x), np.cos(2.0 * math.pi * x))
    for motion in grid.rigid_motions():
        trial -= motion * np.sum(grid.mass * motion * trial) / np.sum(grid.mass * motion * motion)
    return float(trial @ grid.stiffness @ trial / np.sum(grid.mass * trial * trial))


def timoshenko_grid_modes(*, youngs_modulus_pa: float, density_kg_m3: float, shear_modulus_pa: float,
                          shear_coefficient: float, length_m: float, thickness_m: float, width_m: float = 0.04,
                          bc: str, count: int, profile: Profile | None = None, points: int = 250,
                          extrapolate: bool = True) -> np.ndarray:
    """Mode frequencies (Hz) of a thick bar of any thickness profile, from the staggered grid.

    With ``extrapolate`` (default) the grid's ``dx^2`` error is removed by Richardson
    extrapolation from ``points`` and ``2 points - 1`` nodes.

    Examples
    --------
    >>> f = timoshenko_grid_modes(youngs_modulus_pa=20e9, density_kg_m3=1000.0, shear_modulus_pa=1.4e9,
    ...                           shear_coefficient=5 / 6, length_m=0.4, thickness_m=0.02, bc="free-free",
    ...                           count=3)
    >>> (f / f[0]).round(3).tolist()  # Euler–Bernoulli: 1, 2.757, 5.404
    [1.0, 2.599, 4.714]
    """
    bar = dict(youngs_modulus_pa=youngs_modulus_pa, density_kg_m3=density_kg_m3, shear_modulus_pa=shear_modulus_pa,
               shear_coefficient=shear_coefficient, length_m=length_m, thickness_m=thickness_m, width_m=width_m,
               bc=bc, profile=profile)
    return extrapolated_modes(lambda n: timoshenko_grid(points=n, **bar), count=count, points=points,
                              extrapolate=extrapolate)
