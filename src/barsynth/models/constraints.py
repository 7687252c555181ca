"""Joint constraints a model's table declares (spec 11.4): settings each in range that the model
refuses together, as cheap rules on the resolved record, checked before a voice is designed.

A model lists them as ``constraints`` next to its table (as it lists ``note_maps``). They are a
fast first filter for random draws (:mod:`barsynth.batch.sampler`): a declared constraint may
be looser than the model's own checks, never stricter. Where the model's design checks the same
rule, it does so by calling the declared constraint (one copy of the rule and of its message).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from ..errors import ParameterError


@dataclass(frozen=True)
class Constraint:
    """A joint rule on a model's record.

    ``refusal(p, sample_rate)`` is None for every settings ``p`` (the model's record) the rule
    lets through at ``sample_rate`` Hz (None where no rule of the model reads the rate), else the
    one-line refusal (parameter, value, what is allowed, with units); ``reads``: the parameters
    it reads; ``text``: the rule in words (for the docs).
    """

    reads: tuple[str, ...]
    text: str
    refusal: Callable[[Any, float | None], str | None]

    def holds(self, p: Any, sample_rate: float | None = None) -> bool:
        """Whether ``p`` keeps the rule at ``sample_rate`` Hz."""
        return self.refusal(p, sample_rate) is None

    def __call__(self, p: Any, sample_rate: float | None = None) -> None:
        """Raise the one-line :class:`ParameterError` where ``p`` breaks the rule."""
        message = self.refusal(p, sample_rate)
        if message is not None:
            raise ParameterError(message)


def check_constraints(constraints: Iterable[Constraint], p: Any, sample_rate: float | None = None) -> None:
    """Raise the refusal of the first of ``constraints`` that ``p`` breaks at ``sample_rate`` Hz."""
    for constraint in constraints:
        constraint(p, sample_rate)


def constraints_markdown(models: Any) -> str:
    """A Markdown table of ``models``' declared constraints (docs/batch-sampler-notes.md is made
    with it)."""
    rows = ["| model | reads | allowed |", "|---|---|---|"]
    for model in models:
        if not model.constraints:
            rows.append(f"| {model.name} | - | (none declared) |")
        for constraint in model.constraints:
            reads = ", ".join(f"`{name}`" for name in constraint.reads)
            rows.append(f"| {model.name} | {reads} | {constraint.text} |")
    return "\n".join(rows) + "\n"


__all__ = ["Constraint", "check_constraints", "constraints_markdown"]
