"""The ruler engine's voice: the design of :mod:`.design` stepped by :mod:`.kernel`.

It rests on its supports (the static shape under its weight and the finger) until triggered;
a trigger holds it down at the pluck point (the tip of a ruler) by the chosen displacement,
finds the static shape that takes (:mod:`.statics`), and lets go from there: a restart, as a
hand that bends the ruler again stops what rang.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...dsp.smoothing import (
    LEVEL_GLIDE_S,
    MULTIPLICATIVE,
    SMOOTHED_STATE,
    ramp_steps,
    start_ramp_now,
)
from ...errors import ParameterError
from ...jitstart import compiled_for
from ..base import Voice
from . import kernel as K
from .design import THETA, Design, Setup, design, desk_modes_for, point_row
from .desk import DESKS, desk_bank, desk_modes, reset_desk
from .statics import NoRest, _laws, static_shape
from .statics import _rows as _contact_rows

BAR_FIELDS = ("youngs_modulus_pa", "density_kg_m3", "length_m", "thickness_m", "width_m", "clamped_back", "points")
"""What makes the bar itself: a change of any starts another bar, at rest."""
CHUNK = 256
"""Samples per piece of the desk's bank (the kernel's scratch)."""


class EngineVoice(Voice):
    """A bar on its contacts (:mod:`barsynth.models.ruler.kernel`), for a model whose parameters
    become a :class:`~.design.Setup` through the class's ``setup`` (a ruler, a kalimba tine)."""

    restarts_on_trigger = True

    def setup(self) -> Setup:
        raise NotImplementedError

    def _prepare(self) -> None:
        self._setup = self.setup()
        self._design = design(self._setup, self.sample_rate)

    def _reset(self) -> None:
        self._allocate(self._design)

    def _desk_bank(self, s: Setup):
        """The desk's bank (a silent one-mode bank without a desk: the kernel's record is the same)."""
        if s.desk is None:
            return desk_bank(desk_modes(DESKS["wood"], max_hz=0.45 * self.sample_rate, max_count=1),
                             self.sample_rate)
        return desk_bank(desk_modes_for(s.desk, self.sample_rate), self.sample_rate)

    def _allocate(self, d: Design) -> None:
        """State for the design ``d``: the bar at rest on its supports."""
        s = self._setup
        size = d.scheme.bands.shape[1]
        self._bar = K.Bar(np.zeros(size), np.zeros(size), np.zeros(size), np.zeros(size), np.zeros(size),
                          np.zeros((3, size)))
        count = d.contacts["first"].size
        self._contacts = K.Contacts(**{name: value.copy() for name, value in d.contacts.items()},
                                    eta_plus=np.zeros(count), eta_prev=np.zeros(count), force=np.zeros(count),
                                    potential_force=np.zeros(count), slope=np.zeros(count),
                                    factored=np.full(count, np.nan), regime=np.zeros(count, dtype=np.int64))
        rate = self.sample_rate
        self._edge = K.Edge(d.x_padded, d.cell_low, d.cell_high, d.desk_nodes, d.edge_index, d.finger_index,
                            s.edge_m - s.finger_m if s.finger_m is not None else 0.0, s.contact_stiffness_n_m2, s.contact_damping_n_s_m2, d.radiation_scale, s.edge_m, s.slide_m,
                            max(1, int(round(s.slide_time_s * rate))), s.desk_under, np.zeros(1, K.EDGE_STATE))
        self._level = np.zeros(SMOOTHED_STATE)
        start_ramp_now(self._level, MULTIPLICATIVE, s.level, 0)
        self._output_state = np.zeros(1, K.OUTPUT_STATE)
        self._output = self._make_output(d, self._desk_bank(s))
        self._place(s.edge_m)
        self._rest = self._rest_shape()
        self._hold(self._rest)
        self._output = self._output._replace(rest_force_n=self._desk_load(self._rest))
        self._sounding = False  # at rest it stays at rest: nothing to step, exact silence

    def _desk_load(self, shape: np.ndarray) -> float:
        """The force (N) the bar at ``shape`` (still, unpadded) presses on the desk with."""
        c = self._contacts
        eta = c.sign * (_contact_rows(c, shape.size) @ shape - c.offset)
        return float(np.sum(np.where(c.on_desk, _laws(eta, c)[1], 0.0)))

    def _make_output(self, d: Design, bank: Any) -> K.Output:
        s = self._setup
        bar_gain, desk_gain = min(1.0, 2.0 * (1.0 - s.desk_balance)), min(1.0, 2.0 * s.desk_balance)
        if s.desk is None:
            desk_gain = 0.0
        self._run = None
        return K.Output(d.radiation.copy(), np.zeros(CHUNK), np.zeros(CHUNK), bank, bar_gain, desk_gain, 0.0,
                        self._level, self._output_state)

    def _edge_at(self, steps: int) -> float:
        """Where the slide has moved the edge (m) ``steps`` steps after the release (as the kernel moves it)."""
        s = self._setup
        if s.slide_m <= 0.0:
            return s.edge_m
        total = max(1, int(round(s.slide_time_s * self.sample_rate)))
        return s.edge_m + s.slide_m * (0.5 - 0.5 * math.cos(math.pi * min(steps, total) / total))

    def _place(self, x_edge: float) -> None:
        K.place_edge(self._edge, self._contacts, self._output, x_edge)

    def _rows(self, position_m: float) -> np.ndarray:
        return point_row(self._design.x_padded, self._design.grid.mass.size, position_m)

    def _statics(self, contacts: K.Contacts, **held: Any) -> np.ndarray:
        gravity = self._design.scheme.gravity[K.PAD:-K.PAD]
        try:
            return static_shape(self._design.grid.stiffness, gravity, contacts, **held)[0]
        except NoRest:
            raise ParameterError(self.no_rest_message()) from None

    def no_rest_message(self) -> str:
        """The one line that refuses settings under which the bar finds no static rest."""
        return ("the bar finds no rest on these supports; allowed: a firmer hold (a larger force or stiffness) "
                "or a smaller displacement")

    def _rest_shape(self) -> np.ndarray:
        """The bar at rest; the finger's surface set where it presses with its force there."""
        s, d, c = self._setup, self._design, self._contacts
        if d.finger_index < 0:
            return self._statics(c)
        stiffness = c.stiffness.copy()
        stiffness[d.finger_index] = 0.0
        at = self._rows(s.finger_m)
        rest = self._statics(c._replace(stiffness=stiffness), force_at=at, force_n=s.finger_force_n)
        c.offset[d.finger_index] = float(at @ rest) - s.finger_force_n / s.finger_stiffness_n_m
        return rest

    def _hold(self, shape: np.ndarray) -> None:
        """The bar still, at ``shape`` (unpadded)."""
        self._bar.u[K.PAD:-K.PAD] = shape
        self._bar.u_prev[K.PAD:-K.PAD] = shape

    def held_shape(self) -> np.ndarray:
        """The static shape (m, unpadded) with the pluck point held down by the displacement."""
        s = self._setup
        return self._statics(self._contacts, held_at=self._rows(s.pluck_m), held_m=-s.pluck_displacement_m)

    def trigger(self) -> None:
        """Bend the bar down at the pluck point and let go: it starts still, from that static shape.
        A restart: the desk falls silent and the solver starts afresh, so a note is the same
        whatever rang before (the studio cross-fades the old one out)."""
        s = self._setup
        self._edge.state["steps"] = 0
        reset_desk(self._output.desk)
        self._contacts.factored[:] = np.nan
        self._contacts.regime[:] = 0
        self._place(s.edge_m)
        self._hold(self.held_shape())
        self._sounding = True

    def _update(self, old: Any) -> None:
        """A new level glides there; any other change makes the design anew: the same bar keeps
        moving on its new supports, another bar (material, size, grid) starts at rest (the studio
        cross-fades either)."""
        new_setup = self.setup()
        changed = {f for f in old.__dataclass_fields__ if getattr(old, f) != getattr(self._params, f)}
        if changed <= {"level_db"}:
            self._setup = new_setup
            start_ramp_now(self._level, MULTIPLICATIVE, new_setup.level, ramp_steps(LEVEL_GLIDE_S, self.sample_rate))
            return
        new = design(new_setup, self.sample_rate)  # refuses before anything changes
        saved = dict(self.__dict__)  # the rest shape may still refuse: then nothing changed
        try:
            self._setup, self._design = new_setup, new
            self._allocate(new)
        except Exception:
            self.__dict__.clear()
            self.__dict__.update(saved)
            raise
        old_bar = tuple(getattr(saved["_setup"], name) for name in BAR_FIELDS)
        if old_bar == tuple(getattr(new_setup, name) for name in BAR_FIELDS):
            # the same bar: it keeps moving, the slide carries on where it was, the desk rings on
            self._bar.u[:], self._bar.u_prev[:] = saved["_bar"].u, saved["_bar"].u_prev
            self._sounding = saved["_sounding"]
            steps = int(saved["_edge"].state["steps"][0])
            self._edge.state["steps"] = steps
            self._place(self._edge_at(steps))
            if saved["_setup"].desk == new_setup.desk:
                self._output = self._output._replace(desk=saved["_output"].desk)

    def _render(self, out: np.ndarray) -> None:
        """The mixed pressure (Pa at 1 m) times the level (zeros while it rests untouched)."""
        if not self._sounding:
            out.fill(0.0)
            return
        run = self._run
        if run is None:
            run = self._run = compiled_for(K.process, out, self._design.scheme, self._bar, self._contacts, self._edge,
                                           self._output)
        run(out, self._design.scheme, self._bar, self._contacts, self._edge, self._output)

    # -- what the state holds --------------------------------------------------------------------
    def track_energy(self, on: bool = True) -> None:
        """Sum the energy the losses and the contacts' damping take from now on (J)."""
        self._output_state["track"] = on
        self._output_state["lost_losses_j"] = 0.0
        self._output_state["lost_contact_j"] = 0.0

    def energy_j(self) -> dict[str, float]:
        """The scheme's energy now (J): kinetic, the bar's potential, the contacts', the weight's
        (all between the last two steps, as the scheme keeps them), their total, and what the
        losses and the contacts' damping have taken since :meth:`track_energy`."""
        d, c = self._design, self._contacts
        u, u_prev = self._bar.u[K.PAD:-K.PAD], self._bar.u_prev[K.PAD:-K.PAD]
        rate = d.scheme.step_rate
        m, stiffness = d.grid.mass, d.grid.stiffness
        kinetic = 0.5 * float(np.sum(m * (u - u_prev) ** 2)) * rate ** 2
        bar = (0.25 * (1.0 - THETA) * float(u @ stiffness @ u + u_prev @ stiffness @ u_prev)
               + 0.5 * THETA * float(u_prev @ stiffness @ u))
        rows = _contact_rows(c, u.size)
        contact = 0.5 * sum(float(np.sum(_laws(c.sign * (rows @ w - c.offset), c)[0])) for w in (u, u_prev))
        weight = -0.5 * float(d.scheme.gravity[K.PAD:-K.PAD] @ (u + u_prev))
        state = self._output_state[0]
        return {"kinetic": kinetic, "bar": bar, "contact": contact, "weight": weight,
                "total": kinetic + bar + contact + weight, "lost_losses": float(state["lost_losses_j"]),
                "lost_contact": float(state["lost_contact_j"])}
