"""docs/real-bars.md says what scripts/thickness_table.py computes (the thickness and shear tables)."""

import importlib.util
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location("thickness_table", ROOT / "scripts" / "thickness_table.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_doc_tables_are_current():
    doc = (ROOT / "docs" / "real-bars.md").read_text()
    assert _script().written(doc) == doc, "run: python scripts/thickness_table.py --write docs/real-bars.md"


def test_the_rosewood_row_is_the_issue_s_marimba_bar():
    """The table's h/L = 0.05, E/G = 16 row against the 40 x 5 x 2 cm rosewood bar (h/L = 0.05,
    E/G = 15): the same order of cents, and the correction grows mode by mode."""
    cents = _script().sharpness_cents(0.05, 15.0)
    assert np.all(np.diff(cents) > 0) and 40.0 < cents[0] < 50.0 and 140.0 < cents[1] < 160.0
