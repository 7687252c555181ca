"""Farnell's twang's parameter table and its typed record."""

from __future__ import annotations

from dataclasses import dataclass

from ...parameters import BOOL, Parameter, ParameterTable
from ..notemap import ControlCurve, NoteMap, VelocityCurve


@dataclass(frozen=True, kw_only=True)
class FarnellParams:
    """Resolved parameters of Farnell's twang (units and ranges: :data:`FARNELL_TABLE`)."""

    frequency_hz: float = 426.0
    vibrato_depth_hz: float = 6.0
    anchor: bool = False
    level_db: float = 0.0


FARNELL_TABLE = ParameterTable(
    "farnell",
    [
        Parameter("frequency_hz", "Hz", 20.0, 800.0, 426.0,
                  "pitch f: the free bands sit at f x (1, 2.7565, ...), the drive at f/4", scale="log"),
        Parameter("vibrato_depth_hz", "Hz", 1.0, 6.0, 6.0,
                  "depth of the free-running 5 Hz vibrato added to f"),
        Parameter("anchor", "", None, None, False,
                  "the listening test's anchor: the drive phasor replaced by a cosine", kind=BOOL),
        Parameter("level_db", "dB", -60.0, 12.0, 0.0,
                  "output level re the patch's own (x4 after the 90 Hz high-pass)"),
    ],
    record=FarnellParams,
)

NOTES = (NoteMap("frequency_hz", "frequency", "free-bar", {None: VelocityCurve("level_db", -40.0, 0.0, 0.5)},
                 controls={1: ControlCurve("vibrato_depth_hz", 1.0, 6.0)}),)
"""A note is the patch's frequency; velocity the level (dB); CC 1 (the modulation wheel) the
vibrato's depth."""
