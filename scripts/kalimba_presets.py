"""Write the kalimba's presets: a 17-key kalimba in C (C4 to E6), each tine tuned by its length.

    python scripts/kalimba_presets.py [--check] [--write-doc docs/kalimba.md]

Each note starts from the clamped-free length of docs/kalimba-notes.md's Table 1 (a 1.0 mm steel
tine: ``scripts/kalimba_table.py``). The part behind the bridge (``back_length_m``, the same for
every tine) and the bridge's stiffness lower the pitch, so each vibrating length is then found
by a root-find (Brent) on the grid's fundamental of the tine on its bridge as the scheme plays it
at 48 kHz (:func:`barsynth.models.kalimba.tine_modes`), and corrected by a secant step or two on
the pitch measured in the rendered sound (:func:`measured_hz`) until that is within
:data:`TOLERANCE_CENTS` of the note. The grid (``points``) is fixed per note first, from Table 1's
length (about :data:`CELL_M` a cell), so the root-find moves a continuous function.

With ``--check`` nothing is written: each preset's rendered pitch is printed with its error in cents.
With ``--write-doc`` the presets are not written either: the table between
``<!-- kalimba-presets:start -->`` and ``<!-- kalimba-presets:end -->`` in that file is replaced by
:func:`presets_table` (what each preset plays, measured; tests/test_kalimba.py checks it).
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import re
import tomllib
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

from barsynth.models.kalimba import MODEL, kalimba_setup, tine_modes

ROOT = Path(__file__).resolve().parents[1]
FOLDER = ROOT / "src" / "barsynth" / "presets" / "kalimba"
SAMPLE_RATE = 48000
CELL_M = 0.0008
"""About this much tine per grid cell."""
TOLERANCE_CENTS = 0.5
"""The rendered fundamental is tuned to the note within this (the tests allow 5 cents)."""
MEASURE_START_S = 0.05
MEASURE_S = 0.5


def _table_script():
    spec = importlib.util.spec_from_file_location("kalimba_table", ROOT / "scripts" / "kalimba_table.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def measured_hz(x: np.ndarray, sample_rate: float, near_hz: float) -> float:
    """The strongest spectral peak within a semitone and a half of ``near_hz`` (Hz) in
    ``MEASURE_S`` of ``x`` from ``MEASURE_START_S``: a Hann window, 8x zero padding and a
    parabola through the log magnitudes of the peak's bin and its neighbours."""
    start = int(MEASURE_START_S * sample_rate)
    z = x[start:start + int(MEASURE_S * sample_rate)]
    size = 8 * z.size
    spectrum = np.log(np.abs(np.fft.rfft(z * np.hanning(z.size), size)) + 1e-300)
    f = np.fft.rfftfreq(size, 1.0 / sample_rate)
    band = np.flatnonzero((f > near_hz * 2 ** (-1.5 / 12)) & (f < near_hz * 2 ** (1.5 / 12)))
    i = band[np.argmax(spectrum[band])]
    a, b, c = spectrum[i - 1], spectrum[i], spectrum[i + 1]
    return float(f[i] + 0.5 * (a - c) / (a - 2 * b + c) * (f[1] - f[0]))


def rendered_hz(parameters: dict, near_hz: float) -> float:
    """The fundamental (Hz) of the tine ``parameters`` rendered at 48 kHz."""
    x = MODEL.render(parameters, duration_s=MEASURE_START_S + MEASURE_S, sample_rate=SAMPLE_RATE,
                     normalize=False, dtype=np.float64)
    return measured_hz(x, SAMPLE_RATE, near_hz)


def cents(f: float, reference: float) -> float:
    return 1200.0 * math.log2(f / reference)


def tuned(note: str) -> dict:
    """The parameters of the tine that plays ``note`` (its length tuned, everything else default)."""
    script = _table_script()
    target = script.note_hz(note)
    start = script.tine_length_m(target)
    back = MODEL.table.resolve().back_length_m
    points = round((start + back) / CELL_M) + 1

    def described(length: float) -> float:
        s = kalimba_setup(MODEL.resolve({"vibrating_length_m": length, "points": points}))
        return float(tine_modes(s, SAMPLE_RATE, 1)[0][0])

    length = brentq(lambda L: cents(described(L), target), 0.6 * start, 1.05 * start, xtol=1e-9)
    parameters = {"vibrating_length_m": round(length, 7), "points": points}
    for _ in range(4):  # secant steps on the rendered pitch (f ~ 1/L^2)
        error = cents(rendered_hz(parameters, target), target)
        if abs(error) <= TOLERANCE_CENTS:
            return parameters
        parameters["vibrating_length_m"] = round(parameters["vibrating_length_m"] * 2 ** (error / 2400), 7)
    raise SystemExit(f"{note}: the rendered pitch stays {error:+.2f} cents off")


def preset_text(note: str, parameters: dict) -> str:
    target = _table_script().note_hz(note)
    defaults = MODEL.table.resolve()
    return (
        "[preset]\n"
        f'description = "kalimba tine {note}, {target:.2f} Hz: a 1.0 mm steel tine of a 17-key kalimba in C, '
        f'{parameters["vibrating_length_m"] * 1000:.2f} mm beyond the bridge"\n'
        f'material = "spring steel (barsynth materials: steel), 1.0 x {defaults.width_m * 1000:g} mm"\n'
        f'source = "written by scripts/kalimba_presets.py: Table 1 of docs/kalimba-notes.md, the vibrating '
        f'length then tuned so the rendered fundamental at 48 kHz is {note} (equal temperament, A4 = 440 Hz) '
        f'with {defaults.back_length_m * 1000:g} mm behind the bridge"\n'
        "\n[parameters]\n"
        f"vibrating_length_m = {parameters['vibrating_length_m']}\n"
        f"points = {parameters['points']}\n"
    )


CLAMPED_FREE_RATIO = (4.6940911330 / 1.8751040687) ** 2
"""f2 / f1 of the clamped-free beam (6.267)."""


def presets_table() -> str:
    """Each preset, measured: its note, the vibrating length, b / L, the rendered f1 and its error,
    the rendered f2 / f1, and f2 / f1 of Chapman's support (clamped, rigid pin, free: Table 2 of
    docs/kalimba-notes.md), of the grid's tine on its 1e7 N/m bridge without the time step's warp
    and with it (describe at 48 kHz)."""
    script = _table_script()
    rows = [("| preset | note (Hz) | vibrating_length_m | b / L | rendered f1 (Hz) | error (cents) | "
             "rendered f2 / f1 | Chapman's support f2 / f1 | grid, no step warp | grid at 48 kHz |"),
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for note in script.NOTES:
        parameters = tomllib.loads((FOLDER / f"{note.lower()}.toml").read_text(encoding="utf-8"))["parameters"]
        p = MODEL.resolve(parameters)
        target = script.note_hz(note)
        x = MODEL.render(parameters, duration_s=MEASURE_START_S + MEASURE_S, sample_rate=SAMPLE_RATE,
                         normalize=False, dtype=np.float64)
        s = kalimba_setup(p)
        described = tine_modes(s, SAMPLE_RATE, 2)[0]
        unwarped = tine_modes(s, 1e9, 2)[0]
        f1 = measured_hz(x, SAMPLE_RATE, target)
        f2 = measured_hz(x[:int((MEASURE_START_S + 0.2) * SAMPLE_RATE)], SAMPLE_RATE, described[1])
        back = p.back_length_m / p.vibrating_length_m
        k = script.supported_eigenvalues(back, 2)
        rows.append(f"| `{note.lower()}` | {note} ({target:.2f}) | {p.vibrating_length_m:.7g} | {back:.3f} | "
                    f"{f1:.2f} | {cents(f1, target):+.2f} | {f2 / f1:.3f} | {(k[1] / k[0]) ** 2:.3f} | "
                    f"{unwarped[1] / unwarped[0]:.3f} | {described[1] / described[0]:.3f} |")
    return "\n".join(rows)


def written(text: str) -> str:
    """``text`` with the marked presets table replaced by :func:`presets_table`."""
    pattern = re.compile(r"(<!-- kalimba-presets:start -->\n).*?(\n<!-- kalimba-presets:end -->)", re.DOTALL)
    if not pattern.search(text):
        raise SystemExit("no <!-- kalimba-presets:start --> ... <!-- kalimba-presets:end --> markers")
    rows = presets_table()
    return pattern.sub(lambda m: m.group(1) + rows + m.group(2), text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="print each preset's rendered pitch; write nothing")
    parser.add_argument("--write-doc", type=Path, metavar="MD", help="replace the marked presets table in this file")
    args = parser.parse_args()
    script = _table_script()
    if args.write_doc is not None:
        args.write_doc.write_text(written(args.write_doc.read_text(encoding="utf-8")), encoding="utf-8")
        return
    if args.check:
        for note in script.NOTES:
            target = script.note_hz(note)
            parameters = tomllib.loads((FOLDER / f"{note.lower()}.toml").read_text())["parameters"]
            f = rendered_hz(parameters, target)
            print(f"{note}: {f:.3f} Hz ({cents(f, target):+.2f} cents)")
        return
    FOLDER.mkdir(parents=True, exist_ok=True)
    for note in script.NOTES:
        parameters = tuned(note)
        (FOLDER / f"{note.lower()}.toml").write_text(preset_text(note, parameters), encoding="utf-8")
        print(f"{note}: vibrating_length_m = {parameters['vibrating_length_m']}, points = {parameters['points']}")


if __name__ == "__main__":
    main()
