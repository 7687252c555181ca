"""A strike: a Hertzian mallet (mass, velocity, hardness as a contact time).

Source: A. Chaigne and V. Doutaut, "Numerical simulations of xylophones. I", JASA 101 (1997):
the mallet is a mass on a contact spring ``F = k d^p``; its hardness maps to a contact time
from a soft yarn mallet (10 ms at 1 m/s) to hard plastic (0.2 ms).

Two forms: :meth:`Strike.force`, the pulse of the mallet bouncing off a rigid bar (banded,
all-pass), and :meth:`Strike.contact`, the mallet itself, solved with the bar's step (fd).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..dsp.mallet import HERTZ_EXPONENT, hertz_stiffness, mallet_pulse
from ..parameters import Parameter
from .base import Exciter

SOFTEST_CONTACT_S = 0.010  # mallet_hardness 0: a soft yarn mallet at 1 m/s
HARDEST_CONTACT_S = 0.0002  # mallet_hardness 1: a hard plastic mallet at 1 m/s
STRUCK = {"excitation": ("strike",)}


def mallet_contact_s(hardness: float) -> float:
    """The mallet's contact time at 1 m/s on a rigid surface (s), for a hardness 0 to 1."""
    return SOFTEST_CONTACT_S * (HARDEST_CONTACT_S / SOFTEST_CONTACT_S) ** hardness


@dataclass(frozen=True)
class MalletContact:
    """The mallet as the resonator's kernel solves it: mass (kg), contact stiffness (N/m^p),
    exponent p and the velocity it arrives with (m/s)."""

    mass_kg: float
    stiffness: float
    exponent: float
    velocity_m_s: float


class Strike(Exciter):
    """A mallet strike, from a model's ``mallet_*`` parameters."""

    name = "strike"
    in_advance = True  # the mallet's pulse off a rigid bar (banded, all-pass)
    coupled = True  # the mallet itself, solved with the bar's step (fd)

    def __init__(self, parameters: Any):
        self.mass_kg = parameters.mallet_mass_kg
        self.velocity_m_s = parameters.mallet_velocity_m_s
        self.stiffness = hertz_stiffness(mallet_contact_s(parameters.mallet_hardness), self.mass_kg)

    @staticmethod
    def parameters() -> list[Parameter]:
        return [
            Parameter("mallet_hardness", "", 0.0, 1.0, 0.7,
                      "0 soft (10 ms contact at 1 m/s) to 1 hard (0.2 ms): harder = more high modes", when=STRUCK),
            Parameter("mallet_velocity_m_s", "m/s", 0.05, 10.0, 1.0, "how fast the mallet arrives", scale="log",
                      when=STRUCK),
            Parameter("mallet_mass_kg", "kg", 0.002, 0.5, 0.03, "mass of the mallet head", scale="log",
                      when=STRUCK),
        ]

    def force(self, sample_rate: float) -> np.ndarray:
        """The force (N per sample) of the mallet bouncing off: the uncoupled form."""
        return mallet_pulse(mass_kg=self.mass_kg, velocity_m_s=self.velocity_m_s, stiffness=self.stiffness,
                            sample_rate=sample_rate)

    def contact(self) -> MalletContact:
        """The mallet for a resonator that solves the contact with its own step: the coupled form."""
        return MalletContact(self.mass_kg, self.stiffness, HERTZ_EXPONENT, self.velocity_m_s)
