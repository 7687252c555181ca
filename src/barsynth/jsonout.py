"""Numbers for JSON output: what the CLI and the studio send where JSON has no number (inf, NaN).

Imports only the standard library (a NumPy value is recognised without importing NumPy), so the
command line's quick commands stay quick.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["json_number", "json_ready"]


def json_number(value: float) -> float | None:
    """``value`` as a float, or None where JSON has no number for it (infinite or NaN)."""
    value = float(value)
    return value if math.isfinite(value) else None


def json_ready(value: Any) -> Any:
    """``value`` as :func:`json.dumps` takes it with ``allow_nan=False``: mappings (as dicts) and
    lists, tuples and NumPy arrays (as lists) converted item by item, a NumPy scalar as the Python
    number or bool it holds, and a float that is infinite or NaN as None (:func:`json_number`).
    Strings, ints, bools and None stay as they are; anything else is left for ``json.dumps`` to
    refuse.

    >>> json_ready({"t60_s": (1.5, float("inf")), "n": 3})
    {'t60_s': [1.5, None], 'n': 3}
    """
    if isinstance(value, float):
        return json_number(value)
    if value is None or isinstance(value, (str, int)):
        return value
    if isinstance(value, Mapping):
        return {key: json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(item) for item in value]
    if type(value).__module__ == "numpy":  # a scalar (.item()) or an array (.tolist()): Python values
        return json_ready(value.tolist())
    return value
