"""What every exciter offers: one interface, shared by the resonators it drives.

An exciter (strike, pluck, bow) drives a resonator (banded loops, an all-pass waveguide, a
finite-difference grid) at one point, as Faust's ``strikeModel : marimbaModel``. It is made
for a voice, ``Kind(settings, sample_rate)`` (``settings``: the model's resolved record, of
which it reads only its own rows), and offers one or both of two forms, declared on its class:

- ``in_advance``: :meth:`Exciter.force`, a force known before it acts (N per sample from the
  trigger, then a force held for good), given the resonator at the exciter's point
  (:class:`DrivePoint`). The resonator adds it to a :class:`ForceQueue` it plays out (banded
  and all-pass: the strike's pulse off a rigid bar, the pluck's release).
- ``coupled``: :meth:`Exciter.coupling`, the record the resonator's kernel solves with its own
  step, because the force depends on the bar's motion (fd: the mallet, a
  :class:`~barsynth.exciters.strike.MalletContact`, and the point held out, a
  :class:`~barsynth.exciters.pluck.PluckHold`; banded and fd: the bow's
  :class:`~barsynth.dsp.bow_stroke.BowControls`).
- ``direct``: :meth:`Exciter.direct_sound`, samples heard at the output from the trigger on,
  besides what the resonator makes of its force (banded: a recorded attack, the knock of
  commuted synthesis, :class:`~barsynth.exciters.sample.Sample`). A resonator that offers such
  an exciter adds them to its output (times its output level).

An exciter may refuse settings it cannot use (:meth:`Exciter.check`: a recorded attack longer
than allowed at its rate), so a voice can refuse them before it changes anything.

Its life follows the voice's: :meth:`~Exciter.start` (a trigger: a bow stroke starts),
:meth:`~Exciter.release` (let go: a bow slows to rest), :meth:`~Exciter.update` (new
settings: a bow glides to them) and :attr:`~Exciter.driven_until`. A strike or a pluck, all
in its force or its record, keeps the defaults (nothing to start, release or glide).

A new exciter is one class: its name and summary (the ``excitation`` choice and its words),
its rows (:meth:`Exciter.parameters`), its forms; registered in
:data:`barsynth.exciters.EXCITERS` and listed in a model's ``exciters``. The defaults and the
check that a declared form is there come from here:

>>> class Tap(Exciter):
...     name, summary, in_advance = "tap", "a unit impulse", True
...     def force(self, drive):
...         return Force(np.array([self.sample_rate]), 0.0)  # 1 N s in one sample
>>> tap = Tap(None, 48000.0)
>>> queue = ForceQueue()
>>> queue.add(*tap.force(StaticPoint()))
>>> queue.pending, tap.driven_until
(array([48000.]), 0)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Generic, NamedTuple, Protocol, TypeVar

import numpy as np

from ..parameters import Parameter

S = TypeVar("S")
"""The settings an exciter reads: a Protocol of its rows (a model's record fits it)."""
E = TypeVar("E", bound="Exciter[Any]")


class DrivePoint(Protocol):
    """The resonator at the exciter's point: its static deflection there per newton pushed there
    (``compliance_m_n``) and the largest deflection anywhere on it per newton pushed there
    (``reach_m_n``), both m/N (0 at a point that does not give). Only what needs them reads
    them (a pluck), so a resonator may work them out when first read."""

    @property
    def compliance_m_n(self) -> float: ...

    @property
    def reach_m_n(self) -> float: ...


@dataclass(frozen=True)
class StaticPoint:
    """A :class:`DrivePoint` of two numbers (m/N); ``StaticPoint()``: a point that does not give."""

    compliance_m_n: float = 0.0
    reach_m_n: float = 0.0


class Force(NamedTuple):
    """An in-advance force: N per sample from the trigger on (``per_sample_n``), then ``held_n``
    (N) for good. ``queue.add(*force)`` plays it."""

    per_sample_n: np.ndarray
    held_n: float


class Exciter(Generic[S]):
    """One way to excite a bar, for one voice at ``sample_rate`` Hz (see the module docstring).

    A subclass declares ``name``, ``summary``, ``in_advance`` and/or ``coupled``, and implements
    the forms it declares (checked when the class is made)."""

    name: ClassVar[str] = ""
    """The ``excitation`` value that selects it."""
    summary: ClassVar[str] = ""
    """What a trigger does, in a few words (``a mallet``): the ``excitation`` row's doc."""
    in_advance: ClassVar[bool] = False
    """It offers :meth:`force`: a force known in advance."""
    coupled: ClassVar[bool] = False
    """It offers :meth:`coupling`: a contact the resonator solves with its own step."""
    direct: ClassVar[bool] = False
    """It offers :meth:`direct_sound`: samples heard at the output from the trigger on."""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if (cls.force is not Exciter.force) != cls.in_advance:
            raise TypeError(f"exciter {cls.__name__}: force() must be implemented exactly when in_advance is declared")
        if (cls.coupling is not Exciter.coupling) != cls.coupled:
            raise TypeError(f"exciter {cls.__name__}: coupling() must be implemented exactly when coupled is declared")
        if (cls.direct_sound is not Exciter.direct_sound) != cls.direct:
            raise TypeError(f"exciter {cls.__name__}: direct_sound() must be implemented exactly when direct is "
                            "declared")

    def __init__(self, settings: S, sample_rate: float):
        self.settings = settings
        self.sample_rate = sample_rate

    @staticmethod
    def parameters() -> list[Parameter]:
        """The rows it adds to a model's table."""
        return []

    @classmethod
    def check(cls, settings: S, sample_rate: float) -> None:
        """Refuse (:class:`~barsynth.errors.ParameterError`, one line naming the row) settings it
        could not use at ``sample_rate``, changing nothing; by default it takes any."""

    # -- its forms ------------------------------------------------------------------------------
    def force(self, drive: DrivePoint) -> Force:
        """The in-advance form: the force of a trigger now, at a point of the resonator ``drive``."""
        raise NotImplementedError(f"exciter {self.name} offers no force known in advance")

    def coupling(self) -> Any:
        """The coupled form: the record the resonator's kernel solves with its step."""
        raise NotImplementedError(f"exciter {self.name} offers no coupled form")

    def direct_sound(self) -> np.ndarray:
        """The direct form: the samples of a trigger now heard at the output from the trigger on
        (in the resonator's output units, before its level)."""
        raise NotImplementedError(f"exciter {self.name} offers no direct sound")

    # -- its life in a voice ----------------------------------------------------------------------
    def start(self) -> None:
        """A trigger: its own course starts now (a bow stroke). Nothing to start by default: a
        strike's or a pluck's trigger is all in its force or its record."""

    def release(self) -> None:
        """Let go (a bow slows to rest and is lifted); nothing by default."""

    def update(self, settings: S) -> None:
        """New settings (already validated): the next force or coupling reads them; a bow glides."""
        self.settings = settings

    @property
    def driven_until(self) -> int:
        """The sample index (from the voice's reset) from which it drives nothing any more: a bow
        until it is lifted; 0 for one whose force is over once given."""
        return 0


class ExciterSet:
    """One exciter of each kind a model offers, for one voice: ``exciters[p.excitation]`` is
    the one a trigger uses; they all follow the voice's changes, releases and life."""

    def __init__(self, kinds: tuple[type[Exciter[Any]], ...], settings: Any, sample_rate: float):
        self._by_name = {kind.name: kind(settings, sample_rate) for kind in kinds}

    def __getitem__(self, name: str) -> Exciter[Any]:
        """The exciter of ``excitation`` value ``name``."""
        return self._by_name[name]

    def of(self, kind: type[E]) -> E:
        """The exciter of class ``kind`` (one the model offers)."""
        exciter = self._by_name[kind.name]
        assert isinstance(exciter, kind)
        return exciter

    @staticmethod
    def check(kinds: tuple[type[Exciter[Any]], ...], settings: Any, sample_rate: float) -> None:
        """Refuse settings one of ``kinds`` could not use (:meth:`Exciter.check`), changing nothing."""
        for kind in kinds:
            kind.check(settings, sample_rate)

    def update(self, settings: Any) -> None:
        """New settings for every exciter (the voice's changed record; :meth:`check` them first)."""
        for exciter in self._by_name.values():
            exciter.update(settings)

    def release(self) -> None:
        """Let go of every exciter (only a moving bow does anything)."""
        for exciter in self._by_name.values():
            exciter.release()

    @property
    def driven_until(self) -> int:
        """The sample index from which none of them drives the resonator."""
        return max((exciter.driven_until for exciter in self._by_name.values()), default=0)


class ForceQueue:
    """A force still to come at one point: per sample (``pending``), then ``held`` for good.

    >>> queue = ForceQueue()
    >>> queue.add(np.array([1.0, 2.0]), 0.5)
    >>> queue.pending, queue.held
    (array([1., 2.]), 0.5)
    >>> queue.advance(1); queue.pending
    array([2.])
    """

    def __init__(self) -> None:
        self.clear()

    def clear(self) -> None:
        self.pending = np.zeros(0)
        self.held = 0.0

    def add(self, change: np.ndarray, change_held: float = 0.0) -> None:
        """Add ``change`` (N per sample from now), then ``change_held`` (N) for good."""
        size = max(self.pending.size, change.size)
        total = np.full(size, self.held)
        total[:self.pending.size] = self.pending
        total[:change.size] += change
        total[change.size:] += change_held
        self.pending, self.held = total, self.held + change_held

    def advance(self, num_samples: int) -> None:
        """``num_samples`` of it have been played."""
        self.pending = self.pending[num_samples:]

    def from_sample(self, start: int) -> np.ndarray:
        """What is pending from sample ``start`` of the present block."""
        return self.pending[start:] if start < self.pending.size else self.pending[:0]
