"""Write the kalimba's presets: a 17-key kalimba in C (C4 to E6), each tine tuned by its length.

    python scripts/kalimba_presets.py [--check]

Each note starts from the clamped-free length of docs/kalimba-notes.md's Table 1 (a 1.0 mm steel
tine: ``scripts/kalimba_table.py``). The part behind the bridge (``back_length_m``, the same for
every tine) and the bridge's stiffness lower the pitch, so each vibrating length is then found
by a root-find (Brent) on the grid's fundamental of the tine on its bridge as the scheme plays it
at 48 kHz (:func:`barsynth.models.kalimba.tine_modes`), and corrected by a secant step or two on
the pitch measured in the rendered sound (:func:`measured_hz`) until that is within
:data:`TOLERANCE_CENTS` of the note. The grid (``points``) is fixed per note first, from Table 1's
length (about :data:`CELL_M` a cell), so the root-find moves a continuous function.

With ``--check`` nothing is written: each preset's rendered pitch is printed with its error in cents.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
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
    points = int(round((start + back) / CELL_M)) + 1

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="print each preset's rendered pitch; write nothing")
    args = parser.parse_args()
    script = _table_script()
    if args.check:
        import tomllib

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
