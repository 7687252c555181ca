"""docs/kalimba-notes.md says what scripts/kalimba_table.py computes, and its numbers hold."""

from __future__ import annotations

import importlib.util
import itertools
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import eigh

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "kalimba-notes.md"


def _script():
    spec = importlib.util.spec_from_file_location("kalimba_table", ROOT / "scripts" / "kalimba_table.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _rows(doc: str, name: str) -> list[list[str]]:
    block = doc.split(f"<!-- {name}:start -->")[1].split(f"<!-- {name}:end -->")[0]
    return [[cell.strip() for cell in line.strip("|").split("|")] for line in block.strip().splitlines()[2:]]


def test_the_doc_says_what_the_script_writes():
    doc = DOC.read_text(encoding="utf-8")
    assert _script().written(doc) == doc, "run: python scripts/kalimba_table.py --write docs/kalimba-notes.md"


def test_the_lengths_play_the_notes_of_a_17_key_kalimba_in_c():
    script = _script()
    rows = _rows(DOC.read_text(encoding="utf-8"), "kalimba-lengths")
    assert [row[0] for row in rows] == ["C4", "D4", "E4", "F4", "G4", "A4", "B4", "C5", "D5", "E5", "F5",
                                       "G5", "A5", "B5", "C6", "D6", "E6"]
    lengths = {row[0]: float(row[2]) * 1e-3 for row in rows}
    for note, length in lengths.items():
        # The printed length (0.1 mm) plays the note within 0.5 % (clamped-free, 1 mm steel).
        assert script.tine_modes_hz(length)[0] == pytest.approx(script.note_hz(note), rel=5e-3)
    assert script.note_hz("A4") == 440.0 and script.note_hz("C4") == pytest.approx(261.626, abs=1e-3)
    # f ~ 1/L^2: an octave is a factor sqrt(2) in length.
    assert lengths["C4"] / lengths["C5"] == pytest.approx(math.sqrt(2), rel=5e-3)
    assert lengths["C5"] / lengths["C6"] == pytest.approx(math.sqrt(2), rel=5e-3)


def _beam_fem_eigenvalues(back: float, count: int = 3, per_unit: int = 240) -> np.ndarray:
    """k L of the clamped / pinned / free tine from Hermite-cubic beam elements (an
    independent check of the script's frequency determinant); EI = rho A = 1, L = 1."""
    bridge = round(back * per_unit)          # elements behind the bridge: a node sits on it
    h = back / bridge
    elements = round((1.0 + back) / h)
    assert abs(elements * h - (1.0 + back)) < 1e-9
    stiffness = np.array([[12, 6 * h, -12, 6 * h], [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                          [-12, -6 * h, 12, -6 * h], [6 * h, 2 * h * h, -6 * h, 4 * h * h]]) / h**3
    mass = h / 420 * np.array([[156, 22 * h, 54, -13 * h], [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                               [54, 13 * h, 156, -22 * h], [-13 * h, -3 * h * h, -22 * h, 4 * h * h]])
    size = 2 * (elements + 1)
    k_matrix, m_matrix = np.zeros((size, size)), np.zeros((size, size))
    for e in range(elements):
        k_matrix[2 * e:2 * e + 4, 2 * e:2 * e + 4] += stiffness
        m_matrix[2 * e:2 * e + 4, 2 * e:2 * e + 4] += mass
    keep = [i for i in range(size) if i not in (0, 1, 2 * bridge)]
    omega2 = eigh(k_matrix[np.ix_(keep, keep)], m_matrix[np.ix_(keep, keep)], eigvals_only=True)[:count]
    return omega2 ** 0.25


@pytest.mark.parametrize("back", [0.1, 0.3])
def test_the_bridge_model_matches_beam_elements(back):
    assert _script().supported_eigenvalues(back) == pytest.approx(_beam_fem_eigenvalues(back), rel=2e-4)


def test_the_bridge_model_tends_to_the_cantilever_and_lowers_the_pitch():
    script = _script()
    clamped = np.array([1.8751040687, 4.6940911330, 7.8547574382])
    assert script.supported_eigenvalues(0.002) == pytest.approx(clamped, rel=2e-3)
    rows = _rows(DOC.read_text(encoding="utf-8"), "kalimba-support")
    cents = [float(row[-1]) for row in rows]
    ratios = [float(row[4]) for row in rows]
    assert cents[0] == 0 and all(b < a for a, b in itertools.pairwise(cents))   # pitch falls with b
    assert all(b > a for a, b in itertools.pairwise(ratios))                   # f2 / f1 rises
