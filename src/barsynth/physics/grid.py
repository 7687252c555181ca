"""A bar on a grid: the finite-difference operator, and the modes it has (spec 1.6, 3.3).

Sources: S. Bilbao, Numerical Sound Synthesis (Wiley 2009), ch. 7 (the bar on a grid,
energy-based boundary conditions); A. Chaigne and V. Doutaut, JASA 101 (1997)
(non-uniform bars by finite differences). The bar ``rho A(x) y_tt + (E I(x) y_xx)_xx = 0``
of spec 1.1 with thickness ``h(x)`` (a :class:`~barsynth.physics.profiles.Profile`)
is sampled at ``points`` equally spaced nodes. Its potential energy is the trapezoid
sum of ``E I c^2 / 2`` over the curvatures ``c_l = (u[l-1] - 2 u[l] + u[l+1]) / dx^2``
and its kinetic energy that of ``rho A u_t^2 / 2``; the equations of motion are

    M u_tt = -K u - (2 sigma0 M + 2 sigma1 L) u_t + f,     K = D2^T W D2,  L = D1^T V D1

with ``M`` diagonal (kg), ``K`` pentadiagonal (N/m) and ``L`` tridiagonal (kg/m^2 times
m^2: the grid form of ``-rho A d^2/dx^2``). The boundary conditions of spec 1.2 come
from the energy: a pinned or clamped end does not move; a clamped end also has a ghost
node mirroring its neighbour (no slope) and keeps its curvature in the sum; a free or
pinned end carries no bending moment (no curvature term at the end); a free end's node
moves and carries half a cell of mass.

The modes are the generalised eigenproblem ``K v = w^2 M v``, solved as the symmetric
banded problem ``M^-1/2 K M^-1/2``. Its error falls as ``dx^2``; :func:`grid_modes`
can remove that term by Richardson extrapolation (two grids), which reproduces spec
1.2's closed form to better than 1e-6 for a uniform bar.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..checks import check_number, check_whole, show_value
from ..errors import ParameterError
from .boundary import BOUNDARY_CONDITIONS
from .profiles import Profile

MIN_POINTS = 8
MAX_POINTS = 1000
"""Beyond this the eigenvalues' rounding (the operator's condition grows as points^4) costs
more than the finer grid gains."""
MAX_EXTRAPOLATED_POINTS = 300
GRID_LENGTH_M = (1e-4, 1e3)
"""The lengths a grid is built for (m): far outside them its matrices leave the float range."""


def check_grid_size(length_m: float, thickness_m: float) -> tuple[float, float]:
    """``length_m`` within :data:`GRID_LENGTH_M` and ``thickness_m`` above 0 and at most
    :data:`GRID_LENGTH_M`'s top, as one-line :class:`ParameterError` s."""
    length_m = check_number("length_m", length_m, "m", minimum=GRID_LENGTH_M[0], maximum=GRID_LENGTH_M[1])
    thickness_m = check_number("thickness_m", thickness_m, "m", minimum=0.0, minimum_exclusive=True,
                               maximum=GRID_LENGTH_M[1])
    return length_m, thickness_m


def _ends(bc: str) -> tuple[str, str]:
    if bc not in BOUNDARY_CONDITIONS:
        raise ParameterError(f"parameter bc = {show_value(bc)} is unknown; allowed: one of {', '.join(BOUNDARY_CONDITIONS)}")
    left, right = bc.split("-")
    return left, right


def rigid_mode_count(bc: str) -> int:
    """How many zero-frequency (rigid-body) motions a bar with these ends has."""
    return 2 if _ends(bc) == ("free", "free") else 0


@dataclass(frozen=True)
class BarGrid:
    """The grid operator of one bar (see the module docstring).

    ``x_m``: positions of the nodes that move (m); ``mass``: ``M``'s diagonal (kg);
    ``stiffness`` and ``damping_laplacian``: ``K`` and ``L`` as dense symmetric
    matrices over the moving nodes.
    """

    bc: str
    length_m: float
    points: int
    x_m: np.ndarray
    mass: np.ndarray
    stiffness: np.ndarray
    damping_laplacian: np.ndarray

    def weights_at(self, position: float) -> tuple[np.ndarray, np.ndarray]:
        """Node indices and linear-interpolation weights of a point ``position``
        (fraction of the length) among the moving nodes; a fixed node gets no weight."""
        return interpolation(self.x_m / self.length_m, position, self.points)


def interpolation(fractions: np.ndarray, position: float, points: int) -> tuple[np.ndarray, np.ndarray]:
    """The (at most two) moving nodes around ``position`` and their weights."""
    spot = position * (points - 1)
    left = min(int(math.floor(spot)), points - 2)
    frac = spot - left
    nodes = np.round(fractions * (points - 1)).astype(np.int64)
    index, weight = [], []
    for node, w in ((left, 1.0 - frac), (left + 1, frac)):
        found = np.flatnonzero(nodes == node)
        if found.size and w > 0.0:
            index.append(int(found[0]))
            weight.append(w)
    return np.array(index, dtype=np.int64), np.array(weight)


def _upper_bands(matrix: np.ndarray, width: int) -> np.ndarray:
    n = matrix.shape[0]
    bands = np.zeros((width + 1, n))
    for k in range(width + 1):
        bands[width - k, k:] = np.diagonal(matrix, k)
    return bands


def bar_grid(*, youngs_modulus_pa: float, density_kg_m3: float, length_m: float, thickness_m: float,
             width_m: float, bc: str, points: int, profile: Profile | None = None) -> BarGrid:
    """The grid operator of a bar of thickness ``thickness_m x profile(x)`` on ``points`` nodes.

    Examples
    --------
    >>> grid = bar_grid(youngs_modulus_pa=69e9, density_kg_m3=2700.0, length_m=0.3, thickness_m=0.01,
    ...                 width_m=0.04, bc="clamped-free", points=11)
    >>> grid.mass.size, round(float(grid.mass.sum()), 5)  # the clamped node does not move
    (10, 0.3078)
    """
    left, right = _ends(bc)
    points = check_whole("points", points, "nodes", minimum=MIN_POINTS, maximum=MAX_POINTS)
    youngs_modulus_pa = check_number("youngs_modulus_pa", youngs_modulus_pa, "Pa", minimum=0.0, minimum_exclusive=True)
    density_kg_m3 = check_number("density_kg_m3", density_kg_m3, "kg/m^3", minimum=0.0, minimum_exclusive=True)
    length_m, thickness_m = check_grid_size(length_m, thickness_m)
    width_m = check_number("width_m", width_m, "m", minimum=0.0, minimum_exclusive=True)
    profile = profile or Profile()
    n = points
    dx = length_m / (n - 1)
    x = np.linspace(0.0, length_m, n)
    h = thickness_m * profile.relative_thickness(x / length_m, length_m=length_m, thickness_m=thickness_m)
    h_mid = thickness_m * profile.relative_thickness((x[:-1] + 0.5 * dx) / length_m, length_m=length_m,
                                                      thickness_m=thickness_m)
    rho_a, rho_a_mid = density_kg_m3 * width_m * h, density_kg_m3 * width_m * h_mid
    ei = youngs_modulus_pa * width_m * h ** 3 / 12.0
    # curvature rows over all n nodes (the ghost of a clamped end folded in), with trapezoid weights
    rows, weights = [], []
    for l in range(n):
        end = left if l == 0 else right if l == n - 1 else None
        row = np.zeros(n)
        if end is None:
            row[l - 1:l + 2] = 1.0, -2.0, 1.0
            weight = 1.0
        elif end == "clamped":  # ghost u[-1] = u[1]
            row[l] = -2.0
            row[1 if l == 0 else n - 2] = 2.0
            weight = 0.5
        else:  # free or pinned: no moment at the end
            continue
        rows.append(row / dx ** 2)
        weights.append(weight * ei[l] * dx)
    d2 = np.array(rows)
    stiffness = d2.T @ (np.array(weights)[:, None] * d2)
    d1 = (np.eye(n, k=1) - np.eye(n))[:-1] / dx  # slopes at the midpoints
    laplacian = d1.T @ ((rho_a_mid * dx)[:, None] * d1)
    mass = rho_a * dx
    for end, node in ((left, 0), (right, n - 1)):
        if end == "free":
            mass[node] *= 0.5
    moving = np.array([not ((l == 0 and left != "free") or (l == n - 1 and right != "free")) for l in range(n)])
    keep = np.flatnonzero(moving)
    return BarGrid(bc, float(length_m), n, x[keep], mass[keep], stiffness[np.ix_(keep, keep)],
                   laplacian[np.ix_(keep, keep)])


def grid_eigen(grid: BarGrid, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The grid's lowest ``count`` vibrating modes: angular frequencies (rad/s) and
    mass-normalised shapes (columns, ``v^T M v = 1``), rigid-body motions left out."""
    from scipy.linalg import eig_banded

    if not isinstance(grid, BarGrid):  # the two-field (Timoshenko) grid has its own solver
        from .timoshenko_grid import two_field_eigen

        return two_field_eigen(grid, count)
    skip = rigid_mode_count(grid.bc)
    size = grid.mass.size
    if count + skip > size:
        raise ParameterError(f"parameter count = {count} is out of range; allowed: 1 to {size - skip} modes "
                             f"for a grid of {grid.points} points")
    bands, scale = _symmetric_bands(grid)
    values, vectors = eig_banded(bands, select="i", select_range=(skip, skip + count - 1))
    omega = np.sqrt(np.maximum(values, 0.0))
    return omega, vectors * scale[:, None]


def highest_frequency(grid: BarGrid) -> float:
    """The grid's highest angular frequency (rad/s): what a time step must resolve.

    NumPy's dense ``eigvalsh`` (all eigenvalues, O(n^3): under 1 ms for the default 100 nodes,
    about 15 ms for 400) rather than SciPy's banded solver: every design checks stability,
    and importing scipy.linalg for it took 0.15-0.25 s of a plain render. The two agree to
    2e-16 relative; only the stability check and its message use the value.
    """
    symmetric, _ = _symmetric(grid)
    top = np.linalg.eigvalsh(symmetric)[-1]
    return math.sqrt(max(float(top), 0.0))


def highest_frequency_banded(grid: BarGrid) -> float:
    """:func:`highest_frequency` by LAPACK's banded solver for the top eigenvalue alone (SciPy's
    ``eigvals_banded``): about ten times faster for 300 nodes, the same to 1e-15 relative. For
    checks made many times (the fd model's declared stability constraint, batch draws)."""
    from scipy.linalg import eigvals_banded

    bands, _ = _symmetric_bands(grid)
    n = bands.shape[1]
    top = eigvals_banded(bands, select="i", select_range=(n - 1, n - 1))[0]
    return math.sqrt(max(float(top), 0.0))


def _symmetric(grid: BarGrid) -> tuple[np.ndarray, np.ndarray]:
    """``M^-1/2 K M^-1/2`` (dense) and ``M^-1/2``'s diagonal."""
    scale = 1.0 / np.sqrt(grid.mass)
    return grid.stiffness * scale[:, None] * scale[None, :], scale


def _symmetric_bands(grid: BarGrid) -> tuple[np.ndarray, np.ndarray]:
    """``M^-1/2 K M^-1/2`` in LAPACK upper banded storage (rows: the 2nd and 1st super-diagonals
    and the diagonal), and ``M^-1/2``'s diagonal."""
    symmetric, scale = _symmetric(grid)
    return _upper_bands(symmetric, 2), scale


def grid_modes(*, youngs_modulus_pa: float, density_kg_m3: float, length_m: float, thickness_m: float,
               width_m: float = 0.04, bc: str, count: int, profile: Profile | None = None, points: int = 250,
               extrapolate: bool = True) -> np.ndarray:
    """Mode frequencies (Hz) of a bar of any thickness profile, from the grid operator.

    With ``extrapolate`` (default) the grid's ``dx^2`` error is removed by Richardson
    extrapolation from ``points`` and ``2 points - 1`` nodes.

    Examples
    --------
    >>> f = grid_modes(youngs_modulus_pa=69e9, density_kg_m3=2700.0, length_m=0.3, thickness_m=0.01,
    ...                bc="free-free", count=3)
    >>> (f / f[0]).round(4).tolist()
    [1.0, 2.7565, 5.4039]
    """
    bar = dict(youngs_modulus_pa=youngs_modulus_pa, density_kg_m3=density_kg_m3, length_m=length_m,
               thickness_m=thickness_m, width_m=width_m, bc=bc, profile=profile)
    return extrapolated_modes(lambda n: bar_grid(points=n, **bar), count=count, points=points,
                              extrapolate=extrapolate)


def extrapolated_modes(make_grid, *, count: int, points: int, extrapolate: bool) -> np.ndarray:
    """Mode frequencies (Hz) of the grid ``make_grid(points)`` (either kind: :func:`grid_eigen`
    solves both), with ``extrapolate`` the ``dx^2`` error removed by Richardson extrapolation
    from ``points`` and ``2 points - 1`` nodes."""
    count = check_whole("count", count, "modes", minimum=1)
    if extrapolate and not MIN_POINTS <= points <= MAX_EXTRAPOLATED_POINTS:
        raise ParameterError(f"parameter points = {show_value(points)} is out of range; allowed: {MIN_POINTS} to "
                             f"{MAX_EXTRAPOLATED_POINTS} with extrapolation (the finer grid doubles them)")
    coarse = grid_eigen(make_grid(points), count)[0] / (2.0 * math.pi)
    if not extrapolate:
        return coarse
    fine = grid_eigen(make_grid(2 * points - 1), count)[0] / (2.0 * math.pi)
    return (4.0 * fine - coarse) / 3.0
