"""The kalimba's numbers (spec 9.4): tine lengths for a 17-key kalimba in C, and what the part
behind the bridge does to the tine's modes.

    python scripts/kalimba_table.py [--write docs/kalimba-notes.md]

Table 1: the vibrating length (bridge to tip) of a uniform steel tine, 1.0 mm thick, clamped at
the bridge and free at the tip, whose first clamped-free mode is each note of the usual 17-key
layout in C major (C4 to E6, equal temperament, A4 = 440 Hz), with its second and third modes.
From :func:`barsynth.physics.bar_frequencies` (Euler-Bernoulli; ``barsynth materials`` steel:
E = 200 GPa, rho = 7850 kg/m^3). f1 ~ h / L^2, so L ~ 1 / sqrt(f1): an octave up is the length
times 1/sqrt(2), and the width does not enter.

Table 2: a tine clamped at the load point, a length b behind the bridge, simply supported (a
rigid pin) at the bridge and free at the tip, a length L beyond it: the support Chapman
modelled (JASA 131(1), 2012; as Ludwigsen, JASA 153, A227 (2023), describes it). Eigenvalues
k L from the exact Euler-Bernoulli frequency equation of the two spans (a 6 x 6 determinant,
bracketed on a grid and refined by Brent's method); b -> 0 is the clamped-free bar.

With ``--write`` the tables replace the text between ``<!-- kalimba-lengths:start -->`` and
``<!-- kalimba-lengths:end -->`` and between ``<!-- kalimba-support:start -->`` and
``<!-- kalimba-support:end -->``; tests/test_kalimba_notes_doc.py checks that the file says what
this script writes.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

from barsynth.physics import bar_frequencies, lambdas, material

THICKNESS_M = 0.001
MATERIAL = "steel"
A4_HZ = 440.0
NOTES = ("C4", "D4", "E4", "F4", "G4", "A4", "B4", "C5", "D5", "E5", "F5", "G5", "A5", "B5",
         "C6", "D6", "E6")
"""The 17-key kalimba in C: lowest tine in the middle, the scale alternating outwards
(D6 B5 G5 E5 C5 A4 F4 D4 C4 E4 G4 B4 D5 F5 A5 C6 E6 from left to right)."""
BACK_RATIOS = (0.05, 0.1, 0.2, 0.3, 0.5)
"""b / L: the clamped span behind the bridge over the vibrating length."""
_SEMITONES = {"C": -9, "D": -7, "E": -5, "F": -4, "G": -2, "A": 0, "B": 2}


def note_hz(note: str) -> float:
    """Equal-tempered frequency of a natural note such as ``"C4"`` (A4 = 440 Hz)."""
    return A4_HZ * 2.0 ** ((_SEMITONES[note[0]] + 12 * (int(note[1:]) - 4)) / 12)


def tine_modes_hz(length_m: float, count: int = 3) -> np.ndarray:
    """Clamped-free modes of the 1.0 mm steel tine of vibrating length ``length_m`` (Hz)."""
    steel = material(MATERIAL)
    return bar_frequencies(youngs_modulus_pa=steel.youngs_modulus_pa, density_kg_m3=steel.density_kg_m3,
                           length_m=length_m, thickness_m=THICKNESS_M, bc="clamped-free", count=count)


def tine_length_m(frequency_hz: float) -> float:
    """The vibrating length whose first clamped-free mode is ``frequency_hz`` (f1 ~ 1/L^2)."""
    return math.sqrt(tine_modes_hz(1.0, 1)[0] / frequency_hz)


def _determinant(k: float, back: float) -> float:
    """Frequency determinant of the clamped (x = -b) / pinned (x = 0) / free (x = L = 1) tine.

    Unknowns: the back span w = a1 (cos kx - cosh kx) + a2 (sin kx - sinh kx) from the clamp
    (x measured from it), the front span w = c1 cos ks + c2 sin ks + c3 cosh ks + c4 sinh ks
    from the bridge. Rows: both spans at rest on the pin, slope and moment continuous over it,
    no moment and no shear at the tip."""
    cb, sb, chb, shb = math.cos(k * back), math.sin(k * back), math.cosh(k * back), math.sinh(k * back)
    c1, s1, ch1, sh1 = math.cos(k), math.sin(k), math.cosh(k), math.sinh(k)
    matrix = np.array([
        [cb - chb, sb - shb, 0, 0, 0, 0],
        [0, 0, 1, 0, 1, 0],
        [-sb - shb, cb - chb, 0, -1, 0, -1],
        [-cb - chb, -sb - shb, 1, 0, -1, 0],
        [0, 0, -c1, -s1, ch1, sh1],
        [0, 0, s1, -c1, sh1, ch1],
    ])
    return float(np.linalg.det(matrix))


def supported_eigenvalues(back: float, count: int = 3) -> np.ndarray:
    """First ``count`` eigenvalues k L of the tine with a clamped span ``back`` = b / L behind
    a pinned bridge (f_n = sqrt(E h^2 / (12 rho)) (k_n L)^2 / (2 pi L^2), as clamped-free)."""
    grid = np.linspace(0.05, 14.0, 4000)
    values = [_determinant(k, back) for k in grid]
    found = []
    for (k0, d0), (k1, d1) in zip(zip(grid, values), zip(grid[1:], values[1:])):
        if d0 == 0.0 or (d0 < 0.0) != (d1 < 0.0):
            found.append(brentq(_determinant, k0, k1, args=(back,), xtol=1e-13))
            if len(found) == count:
                return np.array(found)
    raise ValueError(f"fewer than {count} modes below k L = 14 for b / L = {back}")


def lengths_table() -> str:
    rows = ["| note | f1 (Hz) | length_mm | f2 (Hz) | f3 (Hz) |", "|---|---:|---:|---:|---:|"]
    for note in NOTES:
        length = tine_length_m(note_hz(note))
        f1, f2, f3 = tine_modes_hz(length)
        rows.append(f"| {note} | {f1:.2f} | {length * 1e3:.1f} | {f2:.0f} | {f3:.0f} |")
    return "\n".join(rows)


def support_table() -> str:
    clamped = lambdas("clamped-free", 3)
    rows = ["| b / L | k1 L | k2 L | k3 L | f2 / f1 | f3 / f1 | f1 vs clamped-free (cents) |",
            "|---|---:|---:|---:|---:|---:|---:|",
            (f"| 0 (clamped-free) | {clamped[0]:.4f} | {clamped[1]:.4f} | {clamped[2]:.4f} | "
             f"{(clamped[1] / clamped[0]) ** 2:.3f} | {(clamped[2] / clamped[0]) ** 2:.3f} | 0 |")]
    for back in BACK_RATIOS:
        k = supported_eigenvalues(back)
        cents = 1200 * math.log2((k[0] / clamped[0]) ** 2)
        rows.append(f"| {back:g} | {k[0]:.4f} | {k[1]:.4f} | {k[2]:.4f} | {(k[1] / k[0]) ** 2:.3f} | "
                    f"{(k[2] / k[0]) ** 2:.3f} | {cents:+.0f} |")
    return "\n".join(rows)


TABLES = {"kalimba-lengths": lengths_table, "kalimba-support": support_table}


def written(text: str) -> str:
    """``text`` with each marked table replaced by what this script computes."""
    for name, table in TABLES.items():
        pattern = re.compile(rf"(<!-- {name}:start -->\n).*?(\n<!-- {name}:end -->)", re.DOTALL)
        if not pattern.search(text):
            raise SystemExit(f"no <!-- {name}:start --> ... <!-- {name}:end --> markers")
        rows = table()
        text = pattern.sub(lambda m, rows=rows: m.group(1) + rows + m.group(2), text)
    return text


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", type=Path, metavar="MD", help="replace the marked tables in this file")
    args = parser.parse_args()
    if args.write is None:
        for table in TABLES.values():
            print(table() + "\n")
        return
    args.write.write_text(written(args.write.read_text(encoding="utf-8")), encoding="utf-8")
    print(f"wrote {args.write}", file=sys.stderr)


if __name__ == "__main__":
    main()
