"""Parameters shared by the bar models (banded, fd, ...): one definition each.

A model's table is built from these and its own; names, units, ranges and docs stay
the same in every model that has them. The mallet's hardness maps to a contact time
(Chaigne & Doutaut, JASA 101, 1997: felt to hard plastic); the bow's controls are
those of :mod:`barsynth.dsp.bow_stroke`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..dsp.bow_stroke import FORCE, LIFT_DELAY_S, VELOCITY, BowControls
from ..parameters import CHOICE, Parameter, Sets
from .base import resolve_parameters
from .rendering import check_seed, render_voice

SOFTEST_CONTACT_S = 0.010  # mallet_hardness 0: a soft yarn mallet at 1 m/s
HARDEST_CONTACT_S = 0.0002  # mallet_hardness 1: a hard plastic mallet at 1 m/s
BOW_GLIDE_S = 0.020  # a new bow speed or force is reached over this time


def bar_size_parameters(note: str = "", when: Any = ()) -> list[Parameter]:
    """Material and size of a rectangular bar; ``note`` prefixes each doc (e.g. when it applies)
    and ``when`` says when they act (see :class:`~barsynth.parameters.Parameter`)."""
    return [
        Parameter("youngs_modulus_pa", "Pa", 1e8, 4e11, 69e9, f"{note}Young's modulus E", scale="log", when=when),
        Parameter("density_kg_m3", "kg/m^3", 100.0, 22000.0, 2700.0, f"{note}density rho", scale="log", when=when),
        material_parameter(note, when),
        Parameter("length_m", "m", 0.02, 3.0, 0.30, f"{note}length of the bar", scale="log", when=when),
        Parameter("thickness_m", "m", 0.0003, 0.1, 0.01, f"{note}thickness h (bending direction)", scale="log",
                  when=when),
        Parameter("width_m", "m", 0.002, 0.5, 0.04, f"{note}width (sets the mass)", scale="log", when=when),
    ]


STRUCK = {"excitation": ("strike",)}
PLUCKED = {"excitation": ("pluck",)}
BOWED = {"excitation": ("bow",)}
STRUCK_OR_PLUCKED = {"excitation": ("strike", "pluck")}


def mallet_parameters() -> list[Parameter]:
    return [
        Parameter("mallet_hardness", "", 0.0, 1.0, 0.7,
                  "0 soft (10 ms contact at 1 m/s) to 1 hard (0.2 ms): harder = more high modes", when=STRUCK),
        Parameter("mallet_velocity_m_s", "m/s", 0.05, 10.0, 1.0, "how fast the mallet arrives", scale="log",
                  when=STRUCK),
        Parameter("mallet_mass_kg", "kg", 0.002, 0.5, 0.03, "mass of the mallet head", scale="log", when=STRUCK),
    ]


def mallet_contact_s(hardness: float) -> float:
    """The mallet's contact time at 1 m/s on a rigid surface (s), for a hardness 0 to 1."""
    return SOFTEST_CONTACT_S * (HARDEST_CONTACT_S / SOFTEST_CONTACT_S) ** hardness


def mallet_stiffness(p: Any) -> float:
    """The Hertzian contact stiffness (N/m^p) of the mallet ``p.mallet_hardness`` and ``p.mallet_mass_kg`` describe."""
    from ..dsp.mallet import hertz_stiffness

    return hertz_stiffness(mallet_contact_s(p.mallet_hardness), p.mallet_mass_kg)


def mallet_force(p: Any, sample_rate: float) -> np.ndarray:
    """The force (N per sample) of the mallet bouncing off: the strike of the force-driven models."""
    from ..dsp.mallet import mallet_pulse

    return mallet_pulse(mass_kg=p.mallet_mass_kg, velocity_m_s=p.mallet_velocity_m_s, stiffness=mallet_stiffness(p),
                        sample_rate=sample_rate)


PLUCK_REACH = 10.0
"""A pluck moves no point of the bar more than this many times ``pluck_displacement_mm``.
Near a clamped or pinned end (or at a node of every mode a model keeps) holding the strike
point out takes a force growing without bound, and the rest of the bar (a cantilever's
tip) would follow; there the force is capped so that the bar's largest deflection is
``PLUCK_REACH x pluck_displacement_mm``. Ordinary plucks never reach it (a cantilever
plucked at a tenth of its length from the clamp moves its tip 14.5 times as far, at a
seventh 10 times; a free-free bar's ends at most 2.6 times), so their sound is unchanged."""

PLUCK_DOC = ("how far the strike point is held out before a pluck's release (near a clamped or pinned end "
             f"less: no point of the bar is held out more than {PLUCK_REACH:g} times this)")


def pluck_force(p: Any, compliance_m_n: float, sample_rate: float,
                reach_m_n: float = 0.0) -> tuple[np.ndarray, float]:
    """A pluck as a force change: the ramp that lets go of the force holding the strike point
    ``p.pluck_displacement_mm`` out (over ``p.release_time_ms``), and the change that stays after it.

    ``compliance_m_n`` is the strike point's deflection per newton there, ``reach_m_n`` the bar's
    largest deflection per newton there (m/N): the force never moves any point more than
    :data:`PLUCK_REACH` x the displacement. A point that does not give (both 0) has nothing to pluck."""
    from ..dsp.mallet import release_ramp

    give = max(compliance_m_n, reach_m_n / PLUCK_REACH)
    force = p.pluck_displacement_mm * 1e-3 / give if give > 0.0 else 0.0
    if not math.isfinite(force):  # a give so small it underflows the division: no point moves measurably
        force = 0.0
    return release_ramp(-force, p.release_time_ms * 1e-3, sample_rate), -force


def largest_deflection(at_strike: np.ndarray, along: np.ndarray, stiffness: np.ndarray) -> float:
    """The bar's largest static deflection per newton at the strike point (m/N), from its modes:
    ``max_x |sum_n phi_n(x) phi_n(a) / k_n|`` for the shapes ``at_strike`` (``phi_n(a)``, one per
    mode), ``along`` (``phi_n(x)``, modes x positions) and modal stiffnesses ``k_n = m w_n^2``."""
    if along.size == 0:
        return 0.0
    return float(np.max(np.abs((at_strike / stiffness) @ along)))


POSITIONS_ALONG = np.linspace(0.0, 1.0, 201)  # where a bar's largest deflection is looked for


def add_force(pending: np.ndarray, held: float, change: np.ndarray, change_held: float) -> tuple[np.ndarray, float]:
    """Add a force change to a force still to come (``pending`` per sample, then ``held``):
    ``change`` per sample, then ``change_held`` for good. Returns the new ``(pending, held)``."""
    size = max(pending.size, change.size)
    total = np.full(size, held)
    total[:pending.size] = pending
    total[:change.size] += change
    total[change.size:] += change_held
    return total, held + change_held


def bow_parameters(*, position: float = 0.0, velocity_m_s: float = 0.3, force_n: float = 3.0) -> list[Parameter]:
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


def level_parameter() -> Parameter:
    return Parameter("level_db", "dB", -60.0, 40.0, 0.0, "output gain re the pick-up velocity in m/s")


class BowedBarVoice:
    """What the bar voices that can be bowed share: parameters, the bow's strokes and glides.

    A subclass sets ``model`` (its model object), and implements ``prepare``,
    ``reset`` (which must create ``self._bow``, a :class:`~barsynth.dsp.bow_stroke.BowControls`),
    ``trigger``, ``set_parameters`` and ``process``.
    """

    model: Any = None

    def __init__(self, parameters: Any = None, *, sample_rate: float = 48000.0, seed: int | None = 0):
        self._params = resolve_parameters(self.model, parameters)
        check_seed(seed)  # the models are deterministic; the seed is accepted for the common interface
        self.prepare(sample_rate)

    @property
    def parameters(self) -> Any:
        return self._params

    def _samples(self, seconds: float) -> int:
        return int(round(seconds * self.sample_rate))

    def _new_bow(self) -> Any:
        return BowControls(velocity_m_s=self._params.bow_velocity_m_s, force_n=self._params.bow_force_n)

    def _start_stroke(self) -> None:
        p = self._params
        self._bow.start(duration=self._samples(p.bow_duration_s), ramp=self._samples(p.bow_ramp_ms * 1e-3),
                        lift_delay=self._samples(LIFT_DELAY_S))

    def release(self) -> None:
        """Stop a bow stroke now: the bow slows to rest, damps the bar, and is lifted.
        (A bow that is not moving, a strike or a pluck is left as it is.)"""
        self._bow.stop(ramp=self._samples(self._params.bow_ramp_ms * 1e-3), lift_delay=self._samples(LIFT_DELAY_S))

    def _glide_bow(self, old: Any, new: Any) -> None:
        """A changed bow velocity or force glides there over ``BOW_GLIDE_S``."""
        length = self._samples(BOW_GLIDE_S)
        if new.bow_velocity_m_s != old.bow_velocity_m_s:
            self._bow.glide(VELOCITY, new.bow_velocity_m_s, length)
        if new.bow_force_n != old.bow_force_n:
            self._bow.glide(FORCE, new.bow_force_n, length)


class BarModel:
    """The model shell the bar models share: ``voice`` and ``render`` from ``voice_class``."""

    voice_class: Any = None

    def voice(self, parameters: Any = None, *, sample_rate: float = 48000.0, seed: int | None = 0) -> Any:
        return self.voice_class(parameters, sample_rate=sample_rate, seed=seed)

    def render(self, parameters: Any = None, *, duration_s: float = 2.0, sample_rate: float = 48000.0,
               seed: int | None = 0, normalize: bool = True, dtype: Any = np.float32) -> np.ndarray:
        """One strike, bow stroke or pluck, offline (peak at -1 dBFS unless ``normalize`` is false)."""
        return render_voice(self.voice(parameters, sample_rate=sample_rate, seed=seed), duration_s,
                            normalize=normalize, dtype=dtype)


def material_parameter(note: str = "", when: Any = ()) -> Parameter:
    """``material``: a name from the materials table that sets ``youngs_modulus_pa`` and
    ``density_kg_m3`` (``custom``: those two as given)."""
    from ..physics.materials import material, materials

    def lookup(name: str) -> tuple[float, float]:
        m = material(name)
        return m.youngs_modulus_pa, m.density_kg_m3

    return Parameter("material", "", None, None, "custom",
                     f"{note}a material from the materials table (barsynth materials): sets youngs_modulus_pa "
                     "and density_kg_m3; custom keeps those as given",
                     kind=CHOICE, choices=("custom", *materials()), when=when,
                     sets=Sets(("youngs_modulus_pa", "density_kg_m3"), lookup))
