"""A recorded attack: the excitation of commuted synthesis.

Sources: J. O. Smith, "Physical modeling using digital waveguides", Computer Music Journal 16(4)
(1992), and M. Karjalainen, V. Välimäki and Z. Jánosi, "Towards high-quality sound synthesis
of the guitar and string instruments", Proc. ICMC 1993 (commuted synthesis): the strike and
everything linear between it and the ear commute, so a short recording can stand for them.

Here the attack is what a bank of narrow resonators cannot make: the knock of a strike (a
recording minus its resynthesised partials over its first 50 to 100 ms, say). A trigger does
two things. The resonator is struck by an ideal impulse, ``2 mallet_mass_kg
mallet_velocity_m_s`` (N s) in one sample, the momentum an infinitely hard mallet gives
back (:meth:`Sample.force`): every mode starts at the level its own gains and the positions
give it, not coloured by a contact's spectrum. And the attack, resampled once to the voice's
rate (:func:`barsynth.dsp.resample.resample`: same duration), is heard directly from the
trigger on (:meth:`Sample.direct_sound`): ``attack_samples`` x ``attack_level_db`` x
``mallet_velocity_m_s / (1 m/s)``, in the resonator's output units (banded: m/s at the pick-up)
and then, like the resonator's own output, times the voice's level.

A recorded attack carries what the recording had at its pitch (a fit's attack: the recording
less the modes as the model plays them, so partials whose phases differ leave sines at their
frequencies). ``attack_pitch_hz`` (0: off) says which pitch that was: the attack is then played
transposed by ``frequency_hz / attack_pitch_hz`` (faster and shorter above it), as a sampler
transposes a sample, so a preset played at another pitch has no onset at the old one.

Its rows: ``attack_samples`` (data: at most :data:`MAX_ATTACK_S` at ``attack_rate_hz``),
``attack_rate_hz`` (data), ``attack_pitch_hz`` and ``attack_level_db``; it reads the model's
``frequency_hz`` and the mallet's velocity and mass,
which are the :class:`~barsynth.exciters.strike.Strike`'s rows (``Strike.parameters(also=
("sample",))`` makes them act for it too).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Protocol

import numpy as np

from ..dsp.resample import resample
from ..errors import ParameterError
from ..parameters import FLOATS, INT, Parameter
from .base import DrivePoint, Exciter, Force

SAMPLED = {"excitation": ("sample",)}
MAX_ATTACK_S = 0.1
"""The longest attack (s) at its own rate."""
ATTACK_RATES_HZ = (8000, 192000)
"""The rates an attack may be recorded at (Hz), as the voices' own."""
MAX_ATTACK_SAMPLES = int(round(MAX_ATTACK_S * ATTACK_RATES_HZ[1]))
"""The most samples an attack may have (0.1 s at 192 kHz)."""
REFERENCE_VELOCITY_M_S = 1.0
"""The mallet velocity at which the attack is heard at ``attack_level_db``."""
DEFAULT_RATE_HZ = 48000


def _click() -> tuple[float, ...]:
    """The default attack: a 1 ms click at 48 kHz, the derivative of a Gaussian 0.1 ms wide
    (peak 1, no DC: symmetric pairs of opposite sign), to 6 decimals."""
    k = np.arange(48)
    t = (k - 23.5) / (1e-4 * DEFAULT_RATE_HZ)
    click = -t * np.exp(-0.5 * t * t)
    click /= np.max(np.abs(click))
    return tuple(round(float(v), 6) + 0.0 for v in click)


DEFAULT_ATTACK = _click()


class SampleSettings(Protocol):
    """What a recorded attack reads from a model's record: its rows (:meth:`Sample.parameters`)
    and the mallet's velocity and mass (the strike's rows)."""

    @property
    def attack_samples(self) -> tuple[float, ...]: ...

    @property
    def attack_rate_hz(self) -> int: ...

    @property
    def attack_level_db(self) -> float: ...

    @property
    def attack_pitch_hz(self) -> float: ...

    @property
    def frequency_hz(self) -> float: ...

    @property
    def mallet_velocity_m_s(self) -> float: ...

    @property
    def mallet_mass_kg(self) -> float: ...


def _heard_at(settings: SampleSettings, sample_rate: float) -> np.ndarray:
    """The attack at ``sample_rate``, transposed by ``frequency_hz / attack_pitch_hz`` when
    ``attack_pitch_hz`` is set: recorded at ``attack_rate_hz``, it is resampled to the rate
    that, played at ``sample_rate``, runs that many times faster (whole Hz: within 0.04 cent at
    the usual rates, and :func:`~barsynth.dsp.resample.resample`'s ratio within 0.1 %)."""
    to_hz = float(sample_rate)
    if settings.attack_pitch_hz > 0.0:
        to_hz = max(1.0, round(to_hz * settings.attack_pitch_hz / settings.frequency_hz))
    return _at_rate(settings.attack_samples, settings.attack_rate_hz, to_hz)


@lru_cache(maxsize=8)
def _at_rate(samples: tuple[float, ...], from_hz: int, to_hz: float) -> np.ndarray:
    heard = resample(np.array(samples, dtype=np.float64), from_hz, to_hz)
    heard.flags.writeable = False
    return heard


class Sample(Exciter[SampleSettings]):
    """A recorded attack (commuted synthesis): an ideal impulse into the resonator and the attack
    heard directly (see the module docstring)."""

    name = "sample"
    summary = "a recorded attack"
    in_advance = True  # the ideal impulse, played out by the resonator (banded)
    direct = True  # the attack, added to its output

    def __init__(self, settings: SampleSettings, sample_rate: float):
        self.check(settings, sample_rate)
        super().__init__(settings, sample_rate)
        self._attack = _heard_at(settings, sample_rate)

    @staticmethod
    def parameters() -> list[Parameter]:
        return [
            Parameter("attack_samples", "", -1.0, 1.0, DEFAULT_ATTACK,
                      f"the recorded attack, as samples at attack_rate_hz (full scale 1.0, at most "
                      f"{MAX_ATTACK_S:g} s): heard from the trigger on at attack_level_db; by default a 1 ms "
                      "click", kind=FLOATS, max_items=MAX_ATTACK_SAMPLES, when=SAMPLED, data=True),
            Parameter("attack_rate_hz", "Hz", *ATTACK_RATES_HZ, DEFAULT_RATE_HZ,
                      "the sample rate attack_samples were recorded at (resampled to the voice's)", kind=INT,
                      when=SAMPLED, data=True),
            Parameter("attack_pitch_hz", "Hz", 0.0, 20000.0, 0.0,
                      "the pitch attack_samples were recorded at: played transposed by frequency_hz / "
                      "attack_pitch_hz, as a sampler does (0: as recorded, at every pitch)", when=SAMPLED),
            Parameter("attack_level_db", "dB", -120.0, 40.0, -20.0,
                      "level of the attack: full scale heard as this many dB re 1 m/s at the pick-up, at a "
                      "mallet velocity of 1 m/s (it scales with the velocity)", when=SAMPLED),
        ]

    @classmethod
    def check(cls, settings: SampleSettings, sample_rate: float) -> None:
        """Refuse an attack longer than :data:`MAX_ATTACK_S` at its rate (one line naming it)."""
        count, rate = len(settings.attack_samples), settings.attack_rate_hz
        most = int(round(MAX_ATTACK_S * rate))
        if count > most:
            raise ParameterError(f"parameter attack_samples has {count} values at attack_rate_hz = {rate} "
                                 f"({count / rate:.6g} s); allowed: at most {MAX_ATTACK_S:g} s of samples "
                                 f"({most} at {rate} Hz)")

    def update(self, settings: SampleSettings) -> None:
        """New settings (checked): a new attack, rate or transposition is resampled now, not at
        the trigger."""
        old, self.settings = self.settings, settings
        if (settings.attack_samples is not old.attack_samples or settings.attack_rate_hz != old.attack_rate_hz
                or settings.attack_pitch_hz != old.attack_pitch_hz
                or (settings.attack_pitch_hz > 0.0 and settings.frequency_hz != old.frequency_hz)):
            self._attack = _heard_at(settings, self.sample_rate)

    @property
    def attack(self) -> np.ndarray:
        """The attack at the voice's rate (read-only; full scale 1.0)."""
        return self._attack

    def force(self, drive: DrivePoint) -> Force:
        """The ideal impulse, ``2 m v`` N s in the trigger's sample (``drive`` is not read)."""
        s = self.settings
        impulse_n_s = 2.0 * s.mallet_mass_kg * s.mallet_velocity_m_s
        return Force(np.array([impulse_n_s * self.sample_rate]), 0.0)

    def direct_sound(self) -> np.ndarray:
        """The attack as heard from the trigger on: at ``attack_level_db``, times the mallet
        velocity over 1 m/s."""
        s = self.settings
        gain = 10.0 ** (s.attack_level_db / 20.0) * s.mallet_velocity_m_s / REFERENCE_VELOCITY_M_S
        return self._attack * gain
