"""Presets: TOML data files, one folder per model, loaded through importlib.resources.

A preset file holds a ``[preset]`` table (``description``, and for physical
models a note of which length it uses) and a ``[parameters]`` table whose
names and values are checked against the model's parameter table.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from typing import Any

from ..checks import show_text

from ..errors import BarsynthError, PresetError


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
            f"unknown preset {show_text(repr(name))} for model {model}; "
            f"available: {', '.join(names) if names else 'none'}"
        )
    return _document(_folder(model).joinpath(name + ".toml").read_text(encoding="utf-8"), f"preset {model}/{name}")


def _document(text: str, what: str) -> dict[str, Any]:
    """A preset's TOML: valid, with a ``[parameters]`` table and a ``[preset]`` table (maybe empty)."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise PresetError(f"{what} is not valid TOML: {exc}") from None
    if not isinstance(doc.get("parameters"), dict):
        raise PresetError(f"{what} has no [parameters] table")
    if not isinstance(doc.setdefault("preset", {}), dict):
        raise PresetError(f"{what} has a [preset] that is not a table")
    return doc


def preset_parameters(model: str, name: str) -> dict[str, Any]:
    """The ``[parameters]`` table of a preset (unvalidated; the model's table checks it)."""
    return dict(load_preset(model, name)["parameters"])


def preset_file_parameters(model: str, path: Any) -> dict[str, Any]:
    """The ``[parameters]`` table of a preset file of one's own (as ``barsynth studio`` saves
    them), unvalidated; a file whose ``[preset] model`` names another model is refused."""
    from pathlib import Path

    from ..checks import check_input_file, show_text

    shown = repr(show_text(path))
    try:
        check_input_file(path, "preset file")  # a FIFO would hang the read, a device never end
    except BarsynthError as exc:
        raise PresetError(str(exc)) from None
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise PresetError(f"cannot read preset file {shown}: {getattr(exc, 'strerror', None) or exc}") from None
    doc = _document(text, f"preset file {shown}")
    named = doc["preset"].get("model", model)
    if named != model:
        raise PresetError(f"preset file {shown} is for model {show_text(repr(named))}, not {model!r}")
    return dict(doc["parameters"])
