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
from ..exciters import (BOWED, PLUCK_REACH, PLUCKED, POSITIONS_ALONG, STRUCK, STRUCK_OR_PLUCKED, Bow, DrivePoint,
                        ForceQueue, Pluck, Strike, largest_deflection, mallet_contact_s)
from ..exciters.bow import BOW_GLIDE_S
from ..exciters.pluck import PLUCK_DOC
from ..exciters.strike import HARDEST_CONTACT_S, SOFTEST_CONTACT_S
from .base import resolve_parameters
from .rendering import check_seed, render_voice
from .rows import bar_size_parameters, level_parameter, material_parameter  # noqa: F401 (moved there)



mallet_parameters = Strike.parameters
bow_parameters = Bow.parameters


def mallet_force(p: Any, sample_rate: float) -> np.ndarray:
    """The force (N per sample) of the mallet bouncing off: the strike of the force-driven models."""
    return Strike(p).force(sample_rate)


def mallet_stiffness(p: Any) -> float:
    """The Hertzian contact stiffness (N/m^p) of the mallet ``p`` describes."""
    return Strike(p).stiffness


def pluck_force(p: Any, compliance_m_n: float, sample_rate: float,
                reach_m_n: float = 0.0) -> tuple[np.ndarray, float]:
    """A pluck as a force change: see :meth:`barsynth.exciters.Pluck.force`."""
    return Pluck(p).force(DrivePoint(compliance_m_n, reach_m_n), sample_rate)


def add_force(pending: np.ndarray, held: float, change: np.ndarray, change_held: float) -> tuple[np.ndarray, float]:
    """Add a force change to a force still to come: see :class:`barsynth.exciters.ForceQueue`."""
    queue = ForceQueue()
    queue.pending, queue.held = pending, held
    queue.add(change, change_held)
    return queue.pending, queue.held


class BowedBarVoice:
    """What the bar voices that can be bowed share: parameters, the bow's strokes and glides.

    A subclass sets ``model`` (its model object), and implements ``prepare``,
    ``reset`` (which must create ``self._bow``, a :class:`~barsynth.dsp.bow_stroke.BowControls`),
    ``trigger``, ``set_parameters`` and ``process``.
    """

    model: Any = None
    restarts_on_trigger = False
    can_release = True
    uses_seed = False

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
