"""What every synthesis model offers, and the registry that finds them by name.

A model is a small object with a parameter table, ``describe`` (the modes it will
synthesise), ``voice`` (a streaming voice with prepare / reset / process / trigger)
and ``render`` (offline, the same samples as the voice). The CLI and the web
layer only ever talk to this interface.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any, Protocol

import numpy as np

from ..errors import ModelError, ParameterError
from ..checks import show_value
from ..parameters import ParameterTable


@dataclass(frozen=True)
class Mode:
    """One synthesised partial: its group, frequency (Hz), relative gain and T60 (s)."""

    group: str
    frequency_hz: float
    gain: float
    t60_s: float

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


class Voice(Protocol):
    """A streaming voice (JUCE-style life cycle)."""

    sample_rate: float

    def prepare(self, sample_rate: float, max_block: int | None = None) -> None: ...

    def reset(self) -> None: ...

    def trigger(self) -> None: ...

    def set_parameters(self, **values: Any) -> None: ...

    def process(self, num_samples: int) -> np.ndarray: ...


class Model(Protocol):
    """The interface the CLI and web layers rely on."""

    name: str
    summary: str
    table: ParameterTable

    def describe(self, parameters: Any, *, sample_rate: float) -> list[Mode]: ...

    def voice(self, parameters: Any = None, *, sample_rate: float, seed: int | None = 0) -> Voice: ...

    def render(
        self,
        parameters: Any = None,
        *,
        duration_s: float,
        sample_rate: float,
        seed: int | None = 0,
        normalize: bool = True,
    ) -> np.ndarray: ...


# name -> "module:attribute"; imported on first use so `import barsynth` stays fast.
_MODEL_PATHS: dict[str, str] = {
    "twang": "barsynth.models.twang:MODEL",
    "farnell": "barsynth.models.farnell:MODEL",
    "banded": "barsynth.models.banded:MODEL",
    "allpass": "barsynth.models.allpass:MODEL",
    "fd": "barsynth.models.fd:MODEL",
}


def model_names() -> tuple[str, ...]:
    """Names of every model barsynth offers."""
    return tuple(_MODEL_PATHS)


def get_model(name: str) -> Model:
    """The model called ``name`` (raises :class:`ModelError` for an unknown name)."""
    try:
        path = _MODEL_PATHS[name]
    except KeyError:
        raise ModelError(
            f"unknown model {show_value(name)}; available: {', '.join(model_names())}"
        ) from None
    module_name, attr = path.split(":")
    return getattr(importlib.import_module(module_name), attr)


def resolve_parameters(model: Model, parameters: Any) -> Any:
    """Accept None, a mapping of overrides, or the model's own dataclass."""
    if parameters is None:
        return model.table.resolve()
    if isinstance(parameters, Mapping):
        return model.table.resolve(parameters)
    if isinstance(parameters, model.table.dataclass):
        return parameters
    raise ParameterError(
        f"parameter parameters = {show_value(parameters)} is not allowed; allowed: None, a mapping "
        f"of parameter names to values, or {model.table.dataclass.__name__}"
    )
