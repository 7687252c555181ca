"""When thickness matters: how sharp Euler–Bernoulli rings against Timoshenko (issue 15).

    python scripts/thickness_table.py [--write docs/real-bars.md]

For a uniform free-free bar (the struck bars of marimbas, xylophones, vibraphones and
glockenspiels), each cell is Euler–Bernoulli's frequency above Timoshenko's in cents, mode by
mode, by thickness/length ratio h/L and stiffness ratio E/G (κ = 5/6). Both from closed forms:
:func:`barsynth.physics.bar_frequencies` and :func:`barsynth.physics.timoshenko_frequencies`;
the ratio depends on h/L and E/G only. A second table lists the materials table's shear
stiffness (``barsynth materials`` has the sources). With ``--write`` the tables replace the text
between ``<!-- thickness-table:start -->`` and ``<!-- thickness-table:end -->`` and between
``<!-- shear-table:start -->`` and ``<!-- shear-table:end -->``; tests/test_real_bars_doc.py
checks that the file says what this script writes.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

from barsynth.physics import bar_frequencies, materials, timoshenko_frequencies

RATIOS_H_L = (0.005, 0.01, 0.02, 0.03, 0.05, 0.1)
STIFFNESS_E_G = (2.6, 12.0, 16.0)
"""Aluminium and steel (2.6), and woods along the grain (12 to 16)."""
MODES = 5
MARKERS = {"thickness": ("<!-- thickness-table:start -->", "<!-- thickness-table:end -->"),
           "shear": ("<!-- shear-table:start -->", "<!-- shear-table:end -->")}


def sharpness_cents(h_over_l: float, e_over_g: float, count: int = MODES) -> np.ndarray:
    bar = {"youngs_modulus_pa": 20e9, "density_kg_m3": 1000.0, "length_m": 1.0, "thickness_m": h_over_l,
           "bc": "free-free", "count": count}
    thin = bar_frequencies(**bar)
    thick = timoshenko_frequencies(shear_modulus_pa=20e9 / e_over_g, shear_coefficient=5.0 / 6.0, **bar)
    return 1200.0 * np.log2(thin / thick)


def table() -> str:
    head = "| h/L | E/G | " + " | ".join(f"mode {n}" for n in range(1, MODES + 1)) + " |"
    lines = [head, "|" + "---|" * (MODES + 2)]
    for ratio in RATIOS_H_L:
        for stiffness in STIFFNESS_E_G:
            cents = sharpness_cents(ratio, stiffness)
            lines.append(f"| {ratio:g} | {stiffness:g} | " + " | ".join(f"{c:+.1f}" for c in cents) + " |")
    return "\n".join(lines)


def shear_table() -> str:
    lines = ["| material | E (GPa) | rho (kg/m^3) | nu | G (GPa) | E/G | kappa |", "|---|---|---|---|---|---|---|"]
    for name, m in materials().items():
        nu = "-" if m.poisson_ratio is None else f"{m.poisson_ratio:g}"
        lines.append(f"| {name} | {m.youngs_modulus_pa / 1e9:g} | {m.density_kg_m3:g} | {nu} | "
                     f"{m.shear_modulus_pa / 1e9:.3g} | {m.youngs_modulus_pa / m.shear_modulus_pa:.1f} | "
                     f"{m.shear_coefficient:.4f} |")
    return "\n".join(lines)


def tables() -> dict[str, str]:
    return {"thickness": table(), "shear": shear_table()}


def written(doc: str) -> str:
    """``doc`` with every marked table replaced by what this script computes."""
    for key, text in tables().items():
        start, end = MARKERS[key]
        if start not in doc or end not in doc:
            raise ValueError(f"no {start} ... {end} markers")
        doc = re.sub(re.escape(start) + ".*?" + re.escape(end), lambda _, s=start, e=end, t=text: f"{s}\n{t}\n{e}",
                     doc, flags=re.S)
    return doc


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", type=Path, help="the Markdown file whose marked table to replace")
    args = parser.parse_args(argv)
    if args.write is None:
        for text in tables().values():
            print(text + "\n")
        return 0
    try:
        doc = written(args.write.read_text())
    except ValueError as exc:
        print(f"{args.write}: {exc}", file=sys.stderr)
        return 2
    args.write.write_text(doc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
