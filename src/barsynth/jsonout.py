"""Numbers for JSON output: what the CLI and the studio send where JSON has no number (inf, NaN)."""

from __future__ import annotations

import math

__all__ = ["json_number"]


def json_number(value: float) -> float | None:
    """``value`` as a float, or None where JSON has no number for it (infinite or NaN)."""
    value = float(value)
    return value if math.isfinite(value) else None
