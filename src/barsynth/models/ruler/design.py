"""The ruler engine's design: a :class:`Setup` (the bar, its contacts, the sound) and a sample rate
in, the kernel's records out (no state); the static shapes it starts from are :mod:`.statics`'s.

The same engine plays the ruler on a desk (:mod:`barsynth.models.ruler`) and the kalimba's tine
on its bridge (:mod:`barsynth.models.kalimba`): a bar on the grid of
:mod:`barsynth.physics.grid` (free at both ends, or clamped at the back), and contacts that
meet it at a node or between two: the desk under it up to the edge (a penalty per metre,
:data:`EDGE_LENGTH_M` more at the edge itself), a finger pressing from above, a bridge from below.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ...physics.grid import BarGrid, bar_grid
from . import kernel as K
from .desk import DESKS, DeskModes, desk_modes

GRAVITY_M_S2 = 9.81
AIR_DENSITY_KG_M3 = 1.2
LISTENER_M = 1.0
"""The radiated pressure is taken at this distance (m), as a small source's (a monopole's)."""
EDGE_LENGTH_M = 0.01
"""The desk's edge presses as this much desk (m) concentrated at the edge: its stiffness is the
desk's per-metre stiffness x this (a rounded corner bears on about a centimetre)."""
THETA = 0.5
"""The theta scheme's implicitness: 0.5, stable at any step and without numerical loss."""
DESK_MODE_COUNT = 100
"""The desk's lowest modes that sound (a 1 mm steel top has 100 below about 450 Hz, wood below 4 kHz)."""
DESK_CONTACT_XY = (0.37, 0.15)
"""Where the ruler meets the desk top, as fractions of its length and depth (off its middle, so the
modes with a nodal line there are not all silent)."""
LOWEST_DESK_HZ = 20.0
"""Desk modes below this (Hz) are left out: inaudible, and they would ring on for a minute."""
MIN_NODES_BEYOND = 6
"""The vibrating part (beyond the edge or bridge) must span at least this many grid cells (each
model's setup refuses less, naming its own parameters)."""


@dataclass(frozen=True, kw_only=True)
class Setup:
    """What the engine simulates, in engine terms (positions in m from the bar's back end)."""

    youngs_modulus_pa: float
    density_kg_m3: float
    length_m: float
    thickness_m: float
    width_m: float
    clamped_back: bool
    """The back end is clamped (a kalimba tine); otherwise free (a ruler)."""
    points: int
    sigma0_per_s: float
    q: float
    """The material's Q: a loss growing with frequency (sigma1 = c / (2 Q), the same Q for every mode)."""
    edge_m: float
    """The desk's edge (a ruler) or the bridge (a tine)."""
    desk_under: bool
    """The desk lies under the bar from its back end to the edge."""
    contact_stiffness_n_m2: float
    contact_damping_n_s_m2: float
    contact_exponent: float
    edge_stiffness_n_m: float
    edge_damping_n_s_m: float
    edge_height_m: float
    """The edge's (bridge's) top above the desk plane (m)."""
    edge_two_sided: bool
    """The edge holds the bar both ways (a pinned bridge)."""
    finger_m: float | None
    finger_force_n: float
    finger_stiffness_n_m: float
    finger_damping_n_s_m: float
    pluck_m: float
    """Where the hand holds the bar down before it lets go (m)."""
    pluck_displacement_m: float
    slide_m: float
    slide_time_s: float
    desk: str | None
    """The desk's name (:data:`barsynth.models.ruler.desk.DESKS`) whose modes sound; None: no desk sound."""
    desk_balance: float
    """0: only the bar's sound, 1: only the desk's, 0.5: both at their own levels."""
    level: float


def desk_modes_for(name: str, sample_rate: float) -> DeskModes:
    """The modes of the desk ``name`` that sound at ``sample_rate`` Hz (see :data:`DESK_MODE_COUNT`)."""
    found = desk_modes(DESKS[name], max_hz=0.45 * sample_rate, max_count=DESK_MODE_COUNT,
                       contact_xy=DESK_CONTACT_XY)
    audible = found.frequency_hz >= LOWEST_DESK_HZ
    return DeskModes(*(field[audible] for field in found))


def sigma1_of(s: Setup) -> float:
    """The frequency-dependent loss (m^2/s) that gives every mode of the uniform bar the Q ``s.q``:
    a mode's ``sigma = sigma1 beta^2 = sigma1 omega / c``, ``c = sqrt(E I / (rho A))``."""
    c = math.sqrt(s.youngs_modulus_pa * s.thickness_m ** 2 / (12.0 * s.density_kg_m3))
    return c / (2.0 * s.q)


def decay_rate(s: Setup, omega: np.ndarray) -> np.ndarray:
    """The decay rate (1/s) of a mode of angular frequency ``omega`` (rad/s): ``sigma0 + omega /
    (2 Q)`` (:func:`sigma1_of`'s loss is ``omega / (2 Q)`` for every mode of the uniform bar)."""
    return s.sigma0_per_s + omega / (2.0 * s.q)


def point_row(x_padded: np.ndarray, n: int, position_m: float) -> np.ndarray:
    """The interpolation row of the point ``position_m`` over the ``n`` moving nodes (unpadded):
    a unit force there, and the reading of a displacement there."""
    q, w0, w1 = interpolation_at(x_padded, n, position_m)
    row = np.zeros(n + 2 * K.PAD)
    row[q] += w0
    row[q + 1] += w1
    return row[K.PAD:K.PAD + n]


def grid_of(s: Setup) -> BarGrid:
    return bar_grid(youngs_modulus_pa=s.youngs_modulus_pa, density_kg_m3=s.density_kg_m3, length_m=s.length_m,
                    thickness_m=s.thickness_m, width_m=s.width_m,
                    bc="clamped-free" if s.clamped_back else "free-free", points=s.points)


class Design(NamedTuple):
    """Everything a voice needs for a setup at a rate, none of it state."""

    grid: BarGrid
    scheme: K.Scheme
    contacts: dict
    """The :class:`~.kernel.Contacts` fields that are data (arrays), before the state's scratch."""
    edge_index: int
    finger_index: int
    desk_nodes: np.ndarray
    radiation: np.ndarray
    cell_low: np.ndarray
    cell_high: np.ndarray
    x_padded: np.ndarray
    radiation_scale: float
    """Pressure at 1 m per node acceleration per metre of cell (Pa / (m/s^2 m))."""


def design(s: Setup, sample_rate: float) -> Design:
    """The scheme and the contacts for ``s`` at ``sample_rate`` Hz, the edge at its start (the
    model's setup has refused a vibrating part under :data:`MIN_NODES_BEYOND` cells, naming its own
    parameters)."""
    grid = grid_of(s)
    n = grid.mass.size
    k = 1.0 / sample_rate
    m, stiff, lap = grid.mass, grid.stiffness, grid.damping_laplacian
    damping = 2.0 * s.sigma0_per_s * np.diag(m) + 2.0 * sigma1_of(s) * lap
    a = np.diag(m) / k ** 2 + 0.5 * (1.0 - THETA) * stiff + damping / (2.0 * k)
    b = 2.0 * np.diag(m) / k ** 2 - THETA * stiff
    c = damping / k
    bands = np.zeros((8, n + 2 * K.PAD))
    for row, (matrix, offset) in enumerate(((b, 0), (b, -1), (b, 1), (b, -2), (b, 2), (c, 0), (c, -1), (c, 1))):
        for i in range(n):
            j = i + offset
            if 0 <= j < n:
                bands[row, K.PAD + i] = matrix[i, j]
    system = np.zeros((3, n + 2 * K.PAD))
    for row in range(3):
        system[row, K.PAD:K.PAD + n - row] = np.diagonal(a, row)
    gravity = np.zeros(n + 2 * K.PAD)
    gravity[K.PAD:-K.PAD] = -GRAVITY_M_S2 * m

    x = grid.x_m
    dx = s.length_m / (s.points - 1)
    x_padded = np.zeros(n + 2 * K.PAD)
    x_padded[K.PAD:-K.PAD] = x
    low = np.zeros_like(x_padded)
    high = np.zeros_like(x_padded)
    low[K.PAD:-K.PAD] = np.maximum(x - 0.5 * dx, 0.0)
    high[K.PAD:-K.PAD] = np.minimum(x + 0.5 * dx, s.length_m)

    rows: list[tuple] = []  # first, w0, w1, stiffness, damping, offset, sign, exponent, two_sided, on_desk
    desk_nodes = np.full(n + 2 * K.PAD, -1, dtype=np.int64)
    if s.desk_under:
        for i in range(n):
            desk_nodes[K.PAD + i] = len(rows)
            rows.append((K.PAD + i, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0, s.contact_exponent, False, True))
    edge_index = len(rows)
    rows.append((K.PAD, 1.0, 0.0, s.edge_stiffness_n_m, s.edge_damping_n_s_m, s.edge_height_m, -1.0,
                 s.contact_exponent if not s.edge_two_sided else 1.0, s.edge_two_sided, s.desk_under))
    finger_index = -1
    if s.finger_m is not None:
        finger_index = len(rows)
        q, w0, w1 = interpolation_at(x_padded, n, s.finger_m)
        rows.append((q, w0, w1, s.finger_stiffness_n_m, s.finger_damping_n_s_m, 0.0, 1.0, 1.0, False, False))
    columns = list(zip(*rows))
    contacts = {
        "first": np.array(columns[0], dtype=np.int64), "w0": np.array(columns[1], dtype=np.float64),
        "w1": np.array(columns[2], dtype=np.float64), "stiffness": np.array(columns[3], dtype=np.float64),
        "damping": np.array(columns[4], dtype=np.float64), "offset": np.array(columns[5], dtype=np.float64),
        "sign": np.array(columns[6], dtype=np.float64), "exponent": np.array(columns[7], dtype=np.float64),
        "two_sided": np.array(columns[8], dtype=np.bool_), "on_desk": np.array(columns[9], dtype=np.bool_)}
    linear = bool(np.all(contacts["exponent"] == 1.0))
    radiation_scale = AIR_DENSITY_KG_M3 * s.width_m / (4.0 * math.pi * LISTENER_M)
    scheme = K.Scheme(bands, system, gravity, float(sample_rate), linear)
    return Design(grid, scheme, contacts, edge_index, finger_index, desk_nodes, np.zeros(n + 2 * K.PAD), low,
                  high, x_padded, radiation_scale)


def interpolation_at(x_padded: np.ndarray, n: int, position_m: float) -> tuple[int, float, float]:
    """The padded index of the node at or before ``position_m`` and the two linear weights."""
    x = x_padded[K.PAD:K.PAD + n]
    i = int(np.searchsorted(x, position_m, side="right")) - 1
    i = min(max(i, 0), n - 2)
    w1 = float(np.clip((position_m - x[i]) / (x[i + 1] - x[i]), 0.0, 1.0))
    return K.PAD + i, 1.0 - w1, w1
