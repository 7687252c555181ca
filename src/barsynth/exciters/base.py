"""What every exciter shares: the force it hands a resonator, and the point it drives.

An exciter (strike, pluck, bow) drives a resonator (banded loops, an all-pass waveguide, a
finite-difference grid) at one point, as Faust's ``strikeModel : marimbaModel``. It offers
one or both of two forms, declared on its class:

- ``in_advance``: a force known before it acts (``force(...)``: N per sample, then a force
  held for good); the resonator adds it to a :class:`ForceQueue` it plays out (banded and
  all-pass: strike and pluck);
- ``coupled``: a contact solved with the resonator's own step, because the force depends on
  the bar's motion: the exciter gives the record the resonator's kernel solves (the fd
  mallet: :meth:`~barsynth.exciters.Strike.contact`; every bow: the :class:`~barsynth.exciters.Bow`'s
  lines). A pluck's coupled form is the bar held out by :meth:`~barsynth.exciters.Pluck.hold_force_n`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..parameters import Parameter


@dataclass(frozen=True)
class DrivePoint:
    """The resonator at the exciter's point: its static deflection there per newton pushed
    there (``compliance_m_n``) and the largest deflection anywhere on it per newton pushed
    there (``reach_m_n``), both m/N (0 at a point that does not give)."""

    compliance_m_n: float = 0.0
    reach_m_n: float = 0.0


class Exciter:
    """One way to excite a bar: its parameter rows and its forces (see the module docstring)."""

    name: ClassVar[str] = ""
    """The ``excitation`` value that selects it."""
    in_advance: ClassVar[bool] = False
    """It offers a force known in advance (``force``)."""
    coupled: ClassVar[bool] = False
    """It offers a contact the resonator solves with its own step."""

    @staticmethod
    def parameters() -> list[Parameter]:
        """The rows it adds to a model's table."""
        return []


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
