"""Presets: TOML data files, one folder per model, loaded through importlib.resources.

A preset file holds a ``[preset]`` table (``description``, and for physical
models a note of which length it uses) and a ``[parameters]`` table whose
names and values are checked against the model's parameter table.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from typing import Any

from ..errors import PresetError


def _folder(model: str):
    return resources.files(__name__).joinpath(model)


def preset_names(model: str) -> tuple[str, ...]:
    """Names of the presets shipped for ``model`` (sorted)."""
    folder = _folder(model)
    if not folder.is_dir():
        return ()
    return tuple(
        sorted(p.name[: -len(".toml")] for p in folder.iterdir() if p.name.endswith(".toml"))
    )


def load_preset(model: str, name: str) -> dict[str, Any]:
    """The raw preset document (``{"preset": {...}, "parameters": {...}}``)."""
    names = preset_names(model)
    if name not in names:
        raise PresetError(
            f"unknown preset {name!r} for model {model}; "
            f"available: {', '.join(names) if names else 'none'}"
        )
    text = _folder(model).joinpath(name + ".toml").read_text(encoding="utf-8")
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise PresetError(f"preset {model}/{name} is not valid TOML: {exc}") from None
    if not isinstance(doc.get("parameters"), dict):
        raise PresetError(f"preset {model}/{name} has no [parameters] table")
    doc.setdefault("preset", {})
    return doc


def preset_parameters(model: str, name: str) -> dict[str, Any]:
    """The ``[parameters]`` table of a preset (unvalidated; the model's table checks it)."""
    return dict(load_preset(model, name)["parameters"])
