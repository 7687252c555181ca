"""A bow: strokes of speed and pressure in sample time, and glides of its velocity and force.

Source: barsynth spec 3.1 (a bowed bar sustains while the bow moves and stops when it stops);
the friction itself is :mod:`barsynth.dsp.friction`, solved by each resonator with its step
(the coupled form only: the force depends on the bar's velocity under the bow).
"""

from __future__ import annotations

from typing import Any

from ..dsp.bow_stroke import FORCE, LIFT_DELAY_S, VELOCITY, BowControls
from ..parameters import Parameter
from .base import Exciter

BOW_GLIDE_S = 0.020  # a new bow speed or force is reached over this time
BOWED = {"excitation": ("bow",)}


class Bow(Exciter):
    """The bow of a voice at ``sample_rate`` Hz: :attr:`controls` holds its lines for the kernel."""

    name = "bow"
    coupled = True  # friction at the bow point, solved with the bar's step (banded, fd)

    def __init__(self, parameters: Any, sample_rate: float):
        self.sample_rate = sample_rate
        self._params = parameters
        self.controls = BowControls(velocity_m_s=parameters.bow_velocity_m_s, force_n=parameters.bow_force_n)

    @staticmethod
    def parameters(*, position: float = 0.0, velocity_m_s: float = 0.3, force_n: float = 3.0) -> list[Parameter]:
        return [
            Parameter("bow_position", "", 0.0, 1.0, position, "where the bow touches, as strike_position", when=BOWED),
            Parameter("bow_velocity_m_s", "m/s", 0.01, 3.0, velocity_m_s,
                      "bow speed: the steady amplitude follows it (glides over 20 ms when changed)", scale="log",
                      when=BOWED),
            Parameter("bow_force_n", "N", 0.01, 20.0, force_n,
                      "how hard the bow presses: more force sustains at higher speeds (glides over 20 ms)",
                      scale="log", when=BOWED),
            Parameter("bow_duration_s", "s", 0.01, 600.0, 1.5,
                      "how long a stroke moves the bow before it slows to rest (it then damps the bar for "
                      "0.5 s and is lifted)", scale="log", when=BOWED),
            Parameter("bow_ramp_ms", "ms", 1.0, 1000.0, 50.0,
                      "how long the bow takes to press and speed up, and to slow to rest", scale="log", when=BOWED),
        ]

    def _samples(self, seconds: float) -> int:
        return int(round(seconds * self.sample_rate))

    def start(self) -> None:
        """A stroke from now (carrying on from the present speed and pressure)."""
        p = self._params
        self.controls.start(duration=self._samples(p.bow_duration_s), ramp=self._samples(p.bow_ramp_ms * 1e-3),
                            lift_delay=self._samples(LIFT_DELAY_S))

    def stop(self) -> None:
        """The bow slows to rest now, damps the bar and is lifted (one not moving is left as it is)."""
        self.controls.stop(ramp=self._samples(self._params.bow_ramp_ms * 1e-3),
                           lift_delay=self._samples(LIFT_DELAY_S))

    def update(self, parameters: Any) -> None:
        """New parameters: a changed bow velocity or force glides there over ``BOW_GLIDE_S``."""
        old, self._params = self._params, parameters
        length = self._samples(BOW_GLIDE_S)
        if parameters.bow_velocity_m_s != old.bow_velocity_m_s:
            self.controls.glide(VELOCITY, parameters.bow_velocity_m_s, length)
        if parameters.bow_force_n != old.bow_force_n:
            self.controls.glide(FORCE, parameters.bow_force_n, length)

    @property
    def now(self) -> int:
        """The absolute sample index the bow's lines are read at next."""
        return self.controls.now

    @now.setter
    def now(self, index: int) -> None:
        self.controls.now = index

    @property
    def lines(self) -> Any:
        return self.controls.lines

    @property
    def lifted_at(self) -> int:
        return self.controls.lifted_at
