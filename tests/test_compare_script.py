"""The comparison script measures what it says (a quick run of its measurement)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "compare_bar_models.py"


def load():
    spec = importlib.util.spec_from_file_location("compare_bar_models", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_script_measures_each_models_partial_errors():
    script = load()
    banded, speed = script.measure("banded", {"tuning": "physics", "mode_count": 6}, repeat=1)
    assert np.max(np.abs(banded)) < 0.1 and speed > 1.0
    coarse, _ = script.measure("fd", {"points": 50, "oversampling": 1}, repeat=1)
    assert np.all(np.array(coarse) < -3.0)  # the grid and the step ring every mode flat
    text = script.table([("banded", banded, speed), ("fd", coarse, 1.0)])
    assert text.count("\n") == 4 and "| banded |" in text and "mode 6 (10761 Hz)" in text


def test_the_docs_hold_a_table_for_every_case():
    doc = (SCRIPT.parents[1] / "docs" / "comparison.md").read_text(encoding="utf-8")
    table = doc.split("<!-- comparison:begin -->")[1].split("<!-- comparison:end -->")[0]
    for _, label, _ in load().CASES:
        assert f"| {label} |" in table
