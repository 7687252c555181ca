"""The kalimba as a barsynth :class:`~barsynth.models.base.Model`: its setup and what it describes."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.linalg import eigh

from ..base import Mode, Model
from ..constraints import check_constraints
from ..rendering import check_sample_rate
from ..ruler.design import Setup, decay_rate, grid_of, point_row
from ..ruler.kernel import PAD
from ..ruler.model import describe_engine
from ..ruler.voice import BAR_FIELDS, EngineVoice
from .table import CONSTRAINTS, KALIMBA_TABLE, NOTES, KalimbaParams

TINE_MODES = 4
"""How many modes of the tine on its bridge :meth:`KalimbaModel.describe` gives (from the grid)."""
BRIDGE_FIELDS = ("edge_m", "edge_stiffness_n_m", "edge_height_m", "edge_two_sided")
"""The setup's fields of the bridge: a change moves the tine's rest and its modes."""
CARRIED_MODES = 2
"""A tine changed while it rings keeps its vibration in this many of its new lowest modes (the
fundamental and the first overtone: with 4 or 8 a softer bridge clicked, 1.7 x the step measure)."""


def kalimba_setup(p: KalimbaParams) -> Setup:
    """The engine's setup for the tine ``p`` (clamped at its back end, the bridge ``back_length_m``
    in front of the clamp, free at the tip); bad geometry refused in one line."""
    check_constraints(CONSTRAINTS, p)
    length = p.back_length_m + p.vibrating_length_m
    reach = p.pluck_position * p.vibrating_length_m
    return Setup(youngs_modulus_pa=p.youngs_modulus_pa, density_kg_m3=p.density_kg_m3, length_m=length,
                 thickness_m=p.thickness_m, width_m=p.width_m, clamped_back=True, points=p.points,
                 sigma0_per_s=p.sigma0_per_s, q=p.q, edge_m=p.back_length_m, desk_under=False,
                 contact_stiffness_n_m2=0.0, contact_damping_n_s_m2=0.0, contact_exponent=1.0,
                 edge_stiffness_n_m=p.bridge_stiffness_n_m, edge_damping_n_s_m=p.bridge_damping_n_s_m,
                 edge_height_m=p.bridge_height_mm / 1000.0, edge_two_sided=p.bridge == "pinned",
                 finger_m=None, finger_force_n=0.0, finger_stiffness_n_m=0.0, finger_damping_n_s_m=0.0,
                 pluck_m=p.back_length_m + reach, pluck_displacement_m=p.pluck_displacement_mm / 1000.0,
                 slide_m=0.0, slide_time_s=1.0, desk=None, desk_balance=0.0, level=10.0 ** (p.level_db / 20.0))


class KalimbaVoice(EngineVoice):
    """A kalimba tine on its bridge, pushed down near the tip and let go.

    Examples
    --------
    >>> voice = KalimbaVoice({"points": 40}, sample_rate=48000)
    >>> voice.trigger()
    >>> block = voice.process(256)
    >>> block.shape, bool(abs(block).max() > 0)
    ((256,), True)
    """

    def setup(self) -> Setup:
        return kalimba_setup(self._params)

    def _update(self, old: Any) -> None:
        """As the engine's, but a tine that keeps moving on a new bridge (softer, higher, pinned)
        moves about its new rest (the rest shifts; the motion does not jump)."""
        before, setup = self._rest, self._setup
        super()._update(old)
        kept = all(getattr(setup, f) == getattr(self._setup, f) for f in BAR_FIELDS)  # else: a new tine, at rest
        moved = any(getattr(setup, f) != getattr(self._setup, f) for f in BRIDGE_FIELDS)
        if kept and moved:
            # the vibration about the old rest, kept in the new tine's lowest modes (what it holds
            # beyond them is no mode of the new tine and would ring as a click)
            shapes = _tine_shapes(self._setup, CARRIED_MODES)
            mass = self._design.grid.mass
            for u in (self._bar.u, self._bar.u_prev):
                vibration = u[PAD:-PAD] - before
                u[PAD:-PAD] = self._rest + shapes @ (shapes.T @ (mass * vibration))

    def held_shape(self) -> np.ndarray:
        """The static shape (m, unpadded) with the pluck point pushed down by the displacement
        from where it rests (the bridge lifts the tine: its rest is not at the clamp's height)."""
        s = self._setup
        at = self._rows(s.pluck_m)
        return self._statics(self._contacts, held_at=at, held_m=float(at @ self._rest) - s.pluck_displacement_m)


def _bridge_row(s: Setup, grid) -> np.ndarray:
    """The bridge's interpolation row over the grid's moving nodes."""
    n = grid.mass.size
    x_padded = np.zeros(n + 2 * PAD)
    x_padded[PAD:-PAD] = grid.x_m
    return point_row(x_padded, n, s.edge_m)


def _tine_shapes(s: Setup, count: int) -> np.ndarray:
    """The lowest ``count`` mode shapes of the tine on its bridge (columns, mass-normalised)."""
    grid = grid_of(s)
    row = _bridge_row(s, grid)
    count = min(count, grid.mass.size)
    return eigh(grid.stiffness + s.edge_stiffness_n_m * np.outer(row, row), np.diag(grid.mass),
                subset_by_index=[0, count - 1])[1]


def tine_modes(s: Setup, sample_rate: float, count: int = TINE_MODES) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (Hz) and T60s (s) of the whole tine on the grid, clamped, on its bridge (a
    spring of the bridge's stiffness: a one-sided bridge as while the tine presses on it) and free,
    as the scheme plays them at ``sample_rate`` (its step lowers them, the higher ones more)."""
    grid = grid_of(s)
    n = grid.mass.size
    row = _bridge_row(s, grid)
    bridge = s.edge_stiffness_n_m * np.outer(row, row)
    k = 1.0 / sample_rate
    # The scheme's modes (undamped): the bar's stiffness at theta = 1/2, the bridge's force at the
    # mean of u+ and u- (the discrete gradient of its potential), so with s = sin(omega k / 2)
    # (K + Kb) phi = s^2 (4 M / k^2 + K + 2 Kb) phi.
    count = min(count, n)
    mu = eigh(grid.stiffness + bridge, 4.0 * np.diag(grid.mass) / k ** 2 + grid.stiffness + 2.0 * bridge,
              eigvals_only=True, subset_by_index=[0, count - 1])
    omega = 2.0 / k * np.arcsin(np.sqrt(np.clip(mu, 0.0, 1.0)))
    lam = eigh(grid.stiffness + bridge, np.diag(grid.mass), eigvals_only=True, subset_by_index=[0, count - 1])
    return omega / (2.0 * math.pi), math.log(1000.0) / decay_rate(s, np.sqrt(lam))


class KalimbaModel(Model):
    """A kalimba tine: the ruler's engine with a bridge and a clamp (see :mod:`barsynth.models.kalimba`)."""

    name = "kalimba"
    summary = "a finite-difference kalimba tine, clamped behind a bridge it presses on, plucked near the tip (spec 9.4)"
    table = KALIMBA_TABLE
    note_maps = NOTES
    constraints = CONSTRAINTS
    voice_class = KalimbaVoice

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        """The clamped-free modes of the vibrating length (bridge to tip: a rigid clamp at the
        bridge) and the modes of the whole tine on the grid (clamped at the back, on a bridge of
        its stiffness, free at the tip: the part behind the bridge lowers them), as the scheme
        plays them. Gains 1 / n^2."""
        p = self.resolve(parameters)
        s = kalimba_setup(p)
        rate = check_sample_rate(sample_rate)
        modes = describe_engine(s, [("clamped-free", p.vibrating_length_m)], rate)
        f, t60 = tine_modes(s, rate)
        for i, (fi, ti) in enumerate(zip(f, t60)):
            if fi < 0.5 * rate:
                modes.append(Mode("tine on bridge", float(fi), 1.0 / (i + 1) ** 2, float(ti)))
        return modes


MODEL = KalimbaModel()
