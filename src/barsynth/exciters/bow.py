"""A bow: strokes of speed and pressure in sample time, and glides of its velocity and force.

Source: barsynth spec 3.1 (a bowed bar sustains while the bow moves and stops when it stops);
the friction itself is :mod:`barsynth.dsp.friction`, solved by each resonator with its step
(the coupled form only: the force depends on the bar's velocity under the bow). Its record is
the stroke's :class:`~barsynth.dsp.bow_stroke.BowControls` (lines in absolute sample time:
why they are not :mod:`barsynth.dsp.smoothing` ramps is said there).
"""

from __future__ import annotations

from typing import Protocol

from ..dsp.bow_stroke import FORCE, LIFT_DELAY_S, VELOCITY, BowControls
from ..dsp.smoothing import ramp_steps
from ..parameters import Parameter
from .base import Exciter

BOW_GLIDE_S = 0.020  # a new bow speed or force is reached over this time
BOWED = {"excitation": ("bow",)}


class BowSettings(Protocol):
    """What a bow reads from a model's record: its rows (:meth:`Bow.parameters`) but the
    position, which the resonator reads."""

    @property
    def bow_velocity_m_s(self) -> float: ...

    @property
    def bow_force_n(self) -> float: ...

    @property
    def bow_duration_s(self) -> float: ...

    @property
    def bow_ramp_ms(self) -> float: ...


class Bow(Exciter[BowSettings]):
    """The bow of a voice at ``sample_rate`` Hz: its record (:meth:`coupling`) holds its lines for
    the kernel, which the voice reads from sample ``now`` on and advances."""

    name = "bow"
    summary = "a bow stroke"
    coupled = True  # friction at the bow point, solved with the bar's step (banded, fd)

    def __init__(self, settings: BowSettings, sample_rate: float):
        super().__init__(settings, sample_rate)
        self.controls = BowControls(velocity_m_s=settings.bow_velocity_m_s, force_n=settings.bow_force_n)

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

    def coupling(self) -> BowControls:
        """The bow's speed, pressure, velocity and force lines, read by the resonator's kernel at
        ``controls.now`` and after (the voice advances ``now``): the coupled form."""
        return self.controls

    def _samples(self, seconds: float) -> int:
        return int(round(seconds * self.sample_rate))

    def start(self) -> None:
        """A stroke from now (carrying on from the present speed and pressure)."""
        s = self.settings
        self.controls.start(duration=self._samples(s.bow_duration_s), ramp=self._samples(s.bow_ramp_ms * 1e-3),
                            lift_delay=self._samples(LIFT_DELAY_S))

    def release(self) -> None:
        """The bow slows to rest now, damps the bar and is lifted (one not moving is left as it is)."""
        self.controls.stop(ramp=self._samples(self.settings.bow_ramp_ms * 1e-3),
                           lift_delay=self._samples(LIFT_DELAY_S))

    def update(self, settings: BowSettings) -> None:
        """New settings: a changed bow velocity or force glides there over ``BOW_GLIDE_S``."""
        old, self.settings = self.settings, settings
        steps = ramp_steps(BOW_GLIDE_S, self.sample_rate)
        if settings.bow_velocity_m_s != old.bow_velocity_m_s:
            self.controls.glide(VELOCITY, settings.bow_velocity_m_s, steps)
        if settings.bow_force_n != old.bow_force_n:
            self.controls.glide(FORCE, settings.bow_force_n, steps)

    @property
    def driven_until(self) -> int:
        """The sample index at which the bow is lifted (until another stroke)."""
        return self.controls.lifted_at
