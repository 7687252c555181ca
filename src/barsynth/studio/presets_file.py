"""Write a model's settings as a preset file (TOML), the same shape as the shipped presets."""

from __future__ import annotations

import json
import math
from typing import Any


def toml_value(value: Any) -> str:
    """One TOML value: bool, whole number, finite float (``repr``: read back exactly), array or basic string."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"{value!r} cannot be written to a preset")
        return repr(value)
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return json.dumps(str(value), ensure_ascii=False).replace("\x7f", "\\u007f")  # a TOML basic string (no DEL)


def preset_toml(parameters: dict[str, Any], *, description: str, source: str = "made in barsynth studio",
                model: str | None = None) -> str:
    """The text of a preset file: ``[preset]`` (description, source, model) and ``[parameters]``.
    ``barsynth render MODEL --preset FILE.toml`` reads it back.

    Examples
    --------
    >>> print(preset_toml({"q": 300.0, "mode_ratios": (1.0, 4.0), "shape": "bar"}, description="mine"), end="")
    [preset]
    description = "mine"
    source = "made in barsynth studio"
    <BLANKLINE>
    [parameters]
    q = 300.0
    mode_ratios = [1.0, 4.0]
    shape = "bar"
    """
    lines = ["[preset]", f"description = {toml_value(description)}", f"source = {toml_value(source)}"]
    if model is not None:
        lines.append(f"model = {toml_value(model)}")
    lines += ["", "[parameters]"]
    lines += [f"{name} = {toml_value(value)}" for name, value in parameters.items()]
    return "\n".join(lines) + "\n"
