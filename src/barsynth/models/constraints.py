"""Joint constraints a model's table declares (spec 11.4): settings each in range that the model
refuses together, as cheap predicates on the resolved record, checked before a voice is designed.

A model lists them as ``constraints`` next to its table (as it lists ``note_maps``). They are a
fast first filter for random draws (:mod:`barsynth.batch.sampler`), never the last word: the
model's own checks when its voice is designed stay authoritative (a declared constraint may
be looser than they are, never stricter).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..errors import ParameterError


@dataclass(frozen=True)
class Constraint:
    """``holds(p, sample_rate)`` is true for every settings ``p`` (the model's record) the model
    may accept at ``sample_rate`` Hz; ``reads``: the parameters it reads; ``text``: the rule in
    words (for the refusal and the docs)."""

    reads: tuple[str, ...]
    text: str
    holds: Callable[[Any, float], bool]

    def __call__(self, p: Any, sample_rate: float) -> None:
        """Raise a one-line :class:`ParameterError` where the constraint does not hold."""
        if not self.holds(p, sample_rate):
            shown = ", ".join(f"{name} = {getattr(p, name):g}" if isinstance(getattr(p, name), float)
                              else f"{name} = {getattr(p, name)}" for name in self.reads)
            raise ParameterError(f"parameters {shown} break a joint constraint; allowed: {self.text}")
