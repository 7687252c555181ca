"""What a note does to a model: the declarations each model's table carries (spec 10.1).

Each model declares, next to its parameter table, a tuple of :class:`NoteMap` (the first whose
``when`` holds for the settings is used): the parameter a note's pitch moves and by which law,
the parameter each excitation's velocity drives and its curve, and the parameters MIDI control
changes move. The logic that plays a note from them is :mod:`barsynth.playing.notes`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class VelocityCurve:
    """``parameter = low + (high - low) * v^gamma`` for a velocity fraction ``v`` (0 to 1);
    with ``per`` that times the (new) value of the parameter ``per`` times ``factor`` (a twang's
    tip is bent by a fraction of its overhang, in mm)."""

    parameter: str
    low: float
    high: float
    gamma: float = 1.0
    per: str | None = None
    factor: float = 1.0

    def value(self, fraction: float, settings: Any = None) -> float:
        base = self.low + (self.high - self.low) * fraction ** self.gamma
        return base if self.per is None else base * getattr(settings, self.per) * self.factor


@dataclass(frozen=True)
class ControlCurve:
    """A MIDI control change (value 0-127) moving ``parameter`` linearly from ``low`` to ``high``,
    on settings where ``when`` holds (elsewhere the control is ignored, as MIDI devices ignore
    controllers they do not have)."""

    parameter: str
    low: float
    high: float
    when: dict[str, Any] = field(default_factory=dict)

    def value(self, control_value: int) -> float:
        return self.low + (self.high - self.low) * control_value / 127.0


@dataclass(frozen=True)
class NoteMap:
    """What a note does to a model (see the module docstring and :mod:`barsynth.playing.notes`)."""

    pitch: str
    """The parameter the pitch moves."""
    law: str
    """``frequency`` (the parameter is the pitch) or ``length`` (f ~ 1 / L^2, refined on ``describe``)."""
    group: str | None = None
    """The ``describe`` group whose lowest mode is the pitch (None: the lowest mode described)."""
    velocity: dict[str | None, VelocityCurve] = field(default_factory=dict)
    """Per ``excitation`` (None for a model that has none), the velocity's curve."""
    when: dict[str, str] = field(default_factory=dict)
    """Settings under which this map holds (a banded bar tuned by ratios moves its frequency)."""
    controls: dict[int, ControlCurve] = field(default_factory=dict)
    """MIDI control number (CC 1, the modulation wheel, ...) -> the parameter it moves."""


EXCITER_VELOCITIES: dict[str | None, VelocityCurve] = {
    "strike": VelocityCurve("mallet_velocity_m_s", 0.2, 4.0),
    "pluck": VelocityCurve("pluck_displacement_mm", 0.05, 3.0),
    "bow": VelocityCurve("bow_force_n", 0.5, 8.0),
}
"""What velocity drives per exciter on the bars that take them (banded, fd, allpass)."""
