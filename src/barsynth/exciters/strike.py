"""A strike: a Hertzian mallet (mass, velocity, hardness as a contact time).

Source: A. Chaigne and V. Doutaut, "Numerical simulations of xylophones. I", JASA 101 (1997):
the mallet is a mass on a contact spring ``F = k d^p``; its hardness maps to a contact time
from a soft yarn mallet (10 ms at 1 m/s) to hard plastic (0.2 ms).

Two forms: :meth:`Strike.force`, the pulse of the mallet bouncing off a rigid bar (banded,
all-pass), and :meth:`Strike.coupling`, the mallet itself (a :class:`MalletContact`), solved
with the bar's step (fd).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from ..dsp.mallet import HERTZ_EXPONENT, hertz_stiffness, mallet_pulse
from ..parameters import Parameter
from .base import DrivePoint, Exciter, Force

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


class StrikeSettings(Protocol):
    """What a strike reads from a model's record: its rows (:meth:`Strike.parameters`)."""

    @property
    def mallet_hardness(self) -> float: ...

    @property
    def mallet_velocity_m_s(self) -> float: ...

    @property
    def mallet_mass_kg(self) -> float: ...


class Strike(Exciter[StrikeSettings]):
    """A mallet strike, from a model's ``mallet_*`` parameters."""

    name = "strike"
    summary = "a mallet"
    in_advance = True  # the mallet's pulse off a rigid bar (banded, all-pass)
    coupled = True  # the mallet itself, solved with the bar's step (fd)

    @staticmethod
    def parameters(*, also: tuple[str, ...] = ()) -> list[Parameter]:
        """Its rows; ``also``: other excitations that read the mallet's velocity and mass (a
        recorded attack's ideal impulse, :class:`~barsynth.exciters.sample.Sample`)."""
        moving = {"excitation": ("strike", *also)}
        return [
            Parameter("mallet_hardness", "", 0.0, 1.0, 0.7,
                      "0 soft (10 ms contact at 1 m/s) to 1 hard (0.2 ms): harder = more high modes", when=STRUCK),
            Parameter("mallet_velocity_m_s", "m/s", 0.05, 10.0, 1.0, "how fast the mallet arrives", scale="log",
                      when=moving),
            Parameter("mallet_mass_kg", "kg", 0.002, 0.5, 0.03, "mass of the mallet head", scale="log",
                      when=moving),
        ]

    def coupling(self) -> MalletContact:
        """The mallet for a resonator that solves the contact with its own step: the coupled form."""
        s = self.settings
        stiffness = hertz_stiffness(mallet_contact_s(s.mallet_hardness), s.mallet_mass_kg)
        return MalletContact(s.mallet_mass_kg, stiffness, HERTZ_EXPONENT, s.mallet_velocity_m_s)

    def force(self, drive: DrivePoint) -> Force:
        """The force (N per sample) of the mallet bouncing off a rigid bar, nothing held after it:
        the in-advance form (``drive`` is not read: a rigid bar does not give)."""
        mallet = self.coupling()
        return Force(mallet_pulse(mass_kg=mallet.mass_kg, velocity_m_s=mallet.velocity_m_s,
                                  stiffness=mallet.stiffness, sample_rate=self.sample_rate, p=mallet.exponent), 0.0)
