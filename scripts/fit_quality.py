"""Measure the banded fit's quality (issue 14): real recordings and synthetic ground truth.

    python scripts/fit_quality.py [--write docs/fitting.md] [--quick]

**Real recordings**: the bar, bell and tine instruments (marimba, xylophone, vibraphone,
glockenspiel, celesta, music box, kalimba, tubular bells, steel drums) of Debian's two
soundfonts (``musescore-general-soundfont-small``'s SF3 and ``timgm6mb-soundfont``'s SF2),
read with :class:`barsynth.soundfont.SoundFont`, a few keys each (the zones that play MIDI
keys 48, 60, 72 and 84, each sample once), ``nominal_hz`` from the zone's root key. Each
note is fitted (``fit_recording(model="banded")``) and judged on its sustained partials within
:data:`WITHIN_DB` of the strongest (spec 7 targets, issue 14):

- frequency within 3 cents, level within 3 dB (resynthesis against recording, measured
  the same way on both);
- T60 within 15 % where the recording's decay is single-slope (one line, no knee, not
  held) over at least 20 dB;
- spectral distance (spec 7.3) at most half that of one decaying sine at f0.

**Synthetic ground truth**: barsynth's banded presets rendered at two pitches (44.1 kHz,
2 s), with white noise 40 dB below the peak and a short room (:func:`room`) added, then
fitted; each mode within 40 dB of the strongest is compared with the truth: frequency
(cents, target 0.5), T60 (target 3 %) and level (target 1 dB) relative to the strongest.
The truth's levels are the modes' in the reverberant sound: the room is a linear filter,
so once its response has ended every mode is the same damped cosine scaled by the room's
response at its complex frequency (:func:`room_gain`).

Everything is seeded: two runs write the same table. With ``--write`` the tables replace
the text between ``<!-- fit-quality:start -->`` and ``<!-- fit-quality:end -->``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from barsynth.analysis import analyze_note
from barsynth.fitting import fit_recording
from barsynth.fitting.modal import mode_amplitudes
from barsynth.models import get_model
from barsynth.soundfont import GM_PROGRAMS, SoundFont

FONTS = {"MuseScore": Path("/usr/share/sounds/sf3/MuseScore_General_Lite.sf3"),
         "TimGM6mb": Path("/usr/share/sounds/sf2/TimGM6mb.sf2")}
KEYS = (48, 60, 72, 84)
LONGEST_S = 3.0  # a sample is fitted over at most its first 3 s
UNROLLED_S = 1.0  # a sample with a loop too short to analyse is played this long, the loop repeated
WITHIN_DB = 40.0
HUM_BELOW = 0.25  # partials below this times f0 are hum (and below the banded model's ratios)
CENTS, LEVEL_DB, T60_FRACTION = 3.0, 3.0, 0.15
SINGLE_SLOPE_DB = 20.0
SYNTH_CENTS, SYNTH_T60, SYNTH_DB = 0.5, 0.03, 1.0
SYNTH_RATE = 44100
SYNTH_SECONDS = 2.0
NOISE_DB = -40.0  # white noise RMS re the note's peak
ROOM_T60_S = 0.05  # the room's reverberation time: shorter than every mode's
ROOM_LENGTH_S = 0.05  # its impulse response's length (60 dB down)
ROOM_LEVEL_DB = -12.0  # the reverberant part's energy re the direct sound's
ROOM_LENGTHS = 3.0  # a mode is judged when its T60 is at least this many times the room's length
SYNTH_CASES = [  # preset, frequency_hz (None: the preset's own)
    ("marimba", None), ("marimba", 523.25), ("xylophone", None), ("xylophone", 1046.5),
    ("vibraphone", None), ("vibraphone", 220.0), ("glass", None), ("bowl", None),
    ("uniform-bar", None), ("glass", 1400.0), ("marimba", 110.0),
]
START = "<!-- fit-quality:start -->"
END = "<!-- fit-quality:end -->"


# -- real recordings -------------------------------------------------------------------------
@dataclass(frozen=True)
class Note:
    font: str
    instrument: str
    key: int
    nominal_hz: float
    samples: np.ndarray
    sample_rate: float
    looped: bool = False  # too short to analyse: played with its loop (:func:`unrolled`)


def notes(fonts: dict[str, Path] = FONTS, keys: tuple[int, ...] = KEYS, instruments: Any = None) -> list[Note]:
    """The soundfonts' bar, bell and tine samples (each once) at ``keys``; fonts not installed
    are skipped."""
    out = []
    for font_name, path in fonts.items():
        if not path.exists():
            continue
        font = SoundFont(path)
        for instrument, program in GM_PROGRAMS.items():
            if instruments is not None and instrument not in instruments:
                continue
            try:
                preset = font.preset(program)
            except KeyError:
                continue
            seen = set()
            for key in keys:
                zone = preset.zone_for(key)
                if zone.sample.index in seen:
                    continue
                seen.add(zone.sample.index)
                x, rate = font.read(zone.sample)
                x = np.asarray(x, dtype=float)[: int(LONGEST_S * rate)]
                loop = font.loop(zone.sample)
                looped = loop is not None and analyze_note(x, rate, nominal_hz=zone.nominal_hz).f0_hz is None
                if looped:
                    x = unrolled(x, loop, rate)
                out.append(Note(font_name, instrument, zone.root_key, zone.nominal_hz, x, rate, looped))
    return out


def unrolled(x: np.ndarray, loop: tuple[int, int] | None, sample_rate: float) -> np.ndarray:
    """A sample with a loop played as a SoundFont synthesiser plays it (the loop repeated;
    without the preset's envelope) for :data:`UNROLLED_S`."""
    if loop is None or not 0 <= loop[0] < loop[1] <= x.size:
        return x
    first, end = loop
    repeats = int(math.ceil((UNROLLED_S * sample_rate - first) / (end - first)))
    return np.concatenate([x[:first], np.tile(x[first:end], repeats)])[: int(UNROLLED_S * sample_rate)]


def judged(fit: Any) -> list[Any]:
    """The comparison rows judged: sustained partials within WITHIN_DB of the strongest, from
    :data:`HUM_BELOW` times f0 up (lower ones are hum or rumble: spec 7.1 reports them)."""
    rows = [r for r in fit.comparison if math.isfinite(r.level_db)]
    if not rows:
        return []
    top = max(r.level_db for r in rows)
    lowest = HUM_BELOW * fit.analysis.f0_hz
    return [r for r in rows if r.level_db >= top - WITHIN_DB and r.frequency_hz >= lowest]


def single_slope(partial: Any) -> bool:
    """Is the recording's decay of this partial one slope over at least 20 dB?"""
    d = partial.decay
    return (partial.t60_s is not None and d is not None and d.method == "line" and d.knee_s is None
            and not d.sustains and (d.range_start_db - d.range_end_db) >= SINGLE_SLOPE_DB)


@dataclass(frozen=True)
class RealResult:
    note: Note
    f0_hz: float
    judged: int
    freq_ok: int
    level_ok: int
    t60_judged: int
    t60_ok: int
    distance_db: float
    baseline_db: float
    seconds: float
    worst: str

    @property
    def distance_ok(self) -> bool:
        return self.distance_db <= 0.5 * self.baseline_db

    @property
    def passed(self) -> bool:
        return (self.freq_ok == self.judged and self.level_ok == self.judged and self.t60_ok == self.t60_judged
                and self.distance_ok)


def judge(fit: Any) -> tuple[int, int, int, int, int, str]:
    """(judged, frequency ok, level ok, T60 judged, T60 ok, the worst miss) of a fit."""
    partials = {p.frequency_hz: p for p in (*fit.analysis.partials, *fit.analysis.below_f0)}
    rows = judged(fit)
    freq_ok = level_ok = t60_judged = t60_ok = 0
    misses = []
    for r in rows:
        if r.cents is not None and abs(r.cents) <= CENTS:
            freq_ok += 1
        else:
            misses.append(f"{r.frequency_hz:.0f} Hz " + ("missing" if r.cents is None else f"{r.cents:+.1f} c"))
        if r.level_error_db is not None and abs(r.level_error_db) <= LEVEL_DB:
            level_ok += 1
        elif r.level_error_db is not None:
            misses.append(f"{r.frequency_hz:.0f} Hz {r.level_error_db:+.1f} dB")
        p = partials.get(r.frequency_hz)
        if p is not None and single_slope(p):
            t60_judged += 1
            if r.t60_error is not None and abs(r.t60_error) <= T60_FRACTION:
                t60_ok += 1
            else:
                misses.append(f"{r.frequency_hz:.0f} Hz T60 " + ("-" if r.t60_error is None
                                                                 else f"{100 * r.t60_error:+.0f} %"))
    return len(rows), freq_ok, level_ok, t60_judged, t60_ok, "; ".join(misses[:2])


def measure_real(note: Note) -> RealResult:
    began = time.perf_counter()
    fit = fit_recording(note.samples, note.sample_rate, model="banded", nominal_hz=note.nominal_hz)
    seconds = time.perf_counter() - began
    n, f, lv, tj, tk, worst = judge(fit)
    return RealResult(note, float(fit.parameters["frequency_hz"]), n, f, lv, tj, tk, fit.distance_db,
                      fit.baseline_db, seconds, worst)


# -- synthetic ground truth ------------------------------------------------------------------
def room(sample_rate: float, seed: int = 1) -> np.ndarray:
    """A short room's impulse response: the direct sound (1 at 0) and, from 2 ms, exponentially
    decaying white noise (T60 ROOM_T60_S, ROOM_LENGTH_S long) at ROOM_LEVEL_DB of its energy."""
    rng = np.random.default_rng(seed)
    n = int(ROOM_LENGTH_S * sample_rate)
    t = np.arange(n) / sample_rate
    tail = rng.standard_normal(n) * np.exp(-t * math.log(1000.0) / ROOM_T60_S)
    tail[: int(0.002 * sample_rate)] = 0.0
    tail *= math.sqrt(10.0 ** (ROOM_LEVEL_DB / 10.0) / np.sum(tail ** 2))
    tail[0] = 1.0
    return tail


def room_gain(response: np.ndarray, sample_rate: float, frequency_hz: float, t60_s: float) -> complex:
    """The room's response at a mode's complex frequency: after the response has ended, the
    mode ``exp((-s + jw) t)`` comes out multiplied by ``sum h[n] exp(-(-s + jw) n / fs)``."""
    s = math.log(1000.0) / t60_s if math.isfinite(t60_s) and t60_s > 0 else 0.0
    n = np.arange(response.size) / sample_rate
    return complex(np.sum(response * np.exp(-(-s + 2j * math.pi * frequency_hz) * n)))


@dataclass(frozen=True)
class Truth:
    frequencies_hz: np.ndarray
    t60s_s: np.ndarray
    levels_db: np.ndarray  # in the reverberant sound, dB re full scale


def synthetic(preset: str, frequency_hz: float | None, seed: int = 0) -> tuple[np.ndarray, Truth]:
    """A preset rendered (2 s, 44.1 kHz) with noise and a room, and the truth."""
    model = get_model("banded")
    overrides: dict[str, Any] = {} if frequency_hz is None else {"frequency_hz": frequency_hz}
    parameters = model.resolve({**_preset_mapping(preset), **overrides})
    rate = SYNTH_RATE
    dry = model.render(parameters, duration_s=SYNTH_SECONDS, sample_rate=rate, normalize=False, dtype=np.float64)
    modes = model.describe(parameters, sample_rate=rate)
    freqs = np.array([m.frequency_hz for m in modes])
    t60s = np.array([m.t60_s for m in modes])
    skip = int(0.02 * rate)
    amps = mode_amplitudes(dry, rate, freqs, t60s, fit_from=skip)
    response = room(rate, seed + 1)
    wet = np.convolve(dry, response)[: dry.size]
    gains = np.array([abs(room_gain(response, rate, f, t)) for f, t in zip(freqs, t60s)])
    levels = 20.0 * np.log10(np.maximum(np.abs(amps) * gains, 1e-30))
    x = wet  # from the strike, as a soundfont's sample (noise before it would move spec 7.3's onset)
    peak = float(np.max(np.abs(x)))
    x = x / peak * 0.5
    levels = levels + 20.0 * math.log10(0.5 / peak)
    rng = np.random.default_rng(seed)
    x = x + 0.5 * 10.0 ** (NOISE_DB / 20.0) * rng.standard_normal(x.size)
    return x, Truth(freqs, t60s, levels)


def _preset_mapping(preset: str) -> dict[str, Any]:
    from barsynth.presets import preset_parameters

    return dict(preset_parameters("banded", preset))


@dataclass(frozen=True)
class SynthResult:
    preset: str
    f0_hz: float
    judged: int
    freq_ok: int
    t60_ok: int
    level_ok: int
    worst_cents: float
    worst_t60: float
    worst_db: float
    seconds: float

    @property
    def passed(self) -> bool:
        return self.freq_ok == self.t60_ok == self.level_ok == self.judged and self.judged > 0


def fitted_modes(fit: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fitted preset's mode frequencies (Hz), T60s (s) and levels (dB, as the preset plays
    them: its render, modes measured by least squares at their known frequencies and T60s)."""
    p = fit.parameters
    freqs = float(p["frequency_hz"]) * np.array(p["mode_ratios"], dtype=float)
    t60s = np.array(p["mode_t60s_s"], dtype=float)
    from barsynth.fitting import _render

    x = _render("banded", p, fit.sample_rate, 1.0, float(freqs.max()))
    model = get_model("banded")
    played = model.describe(p, sample_rate=fit.sample_rate * _factor(freqs.max(), fit.sample_rate))
    skip = int(0.1 * fit.sample_rate)  # past the attack sample
    amps = mode_amplitudes(x, fit.sample_rate, [m.frequency_hz for m in played], [m.t60_s for m in played],
                           fit_from=skip)
    return freqs, t60s, 20.0 * np.log10(np.maximum(np.abs(amps), 1e-30))


def _factor(highest_hz: float, rate: float) -> int:
    from barsynth.fitting.banded import render_factor

    return render_factor(highest_hz, rate)


def measure_synthetic(preset: str, frequency_hz: float | None, seed: int = 0) -> SynthResult:
    x, truth = synthetic(preset, frequency_hz, seed)
    began = time.perf_counter()
    fit = fit_recording(x, SYNTH_RATE, model="banded")
    seconds = time.perf_counter() - began
    freqs, t60s, levels = fitted_modes(fit)
    top = truth.levels_db.max()
    # a mode that dies within the room's response is never heard apart from the room: not judged
    keep = (truth.levels_db >= top - WITHIN_DB) & (truth.t60s_s >= ROOM_LENGTHS * ROOM_LENGTH_S)
    cents, t60e, dbe = [], [], []
    # levels relative to each side's strongest mode
    strongest = int(np.argmax(truth.levels_db))
    anchor = np.argmin(np.abs(np.log(freqs / truth.frequencies_hz[strongest])))
    for i in np.flatnonzero(keep):
        j = int(np.argmin(np.abs(np.log(freqs / truth.frequencies_hz[i]))))
        c = 1200.0 * math.log2(freqs[j] / truth.frequencies_hz[i])
        if abs(c) > 50.0:
            cents.append(math.inf)
            t60e.append(math.inf)
            dbe.append(math.inf)
            continue
        cents.append(c)
        t60e.append(t60s[j] / truth.t60s_s[i] - 1.0)
        dbe.append((levels[j] - levels[anchor]) - (truth.levels_db[i] - top))
    cents, t60e, dbe = np.abs(cents), np.abs(t60e), np.abs(dbe)
    return SynthResult(preset, float(truth.frequencies_hz[0]), int(keep.sum()), int(np.sum(cents <= SYNTH_CENTS)),
                       int(np.sum(t60e <= SYNTH_T60)), int(np.sum(dbe <= SYNTH_DB)), float(cents.max()),
                       float(t60e.max()), float(dbe.max()), seconds)


# -- tables ----------------------------------------------------------------------------------
def real_table(results: list[RealResult]) -> str:
    lines = ["| font | instrument | key | pitch (Hz) | partials | freq <= 3 c | level <= 3 dB | T60 <= 15 % "
             "| distance / sine (dB) | pass | worst misses |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        t60 = f"{r.t60_ok}/{r.t60_judged}" if r.t60_judged else "-"
        key = f"{r.note.key} (loop)" if r.note.looped else f"{r.note.key}"
        lines.append(f"| {r.note.font} | {r.note.instrument} | {key} | {r.f0_hz:.2f} | {r.judged} | "
                     f"{r.freq_ok}/{r.judged} | {r.level_ok}/{r.judged} | {t60} | "
                     f"{r.distance_db:.2f} / {r.baseline_db:.2f} | {'yes' if r.passed else 'no'} | {r.worst} |")
    return "\n".join(lines)


def synth_table(results: list[SynthResult]) -> str:
    lines = ["| preset | f0 (Hz) | modes | freq <= 0.5 c | T60 <= 3 % | level <= 1 dB | worst cents | "
             "worst T60 | worst dB | pass |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        lines.append(f"| {r.preset} | {r.f0_hz:.2f} | {r.judged} | {r.freq_ok}/{r.judged} | {r.t60_ok}/{r.judged} | "
                     f"{r.level_ok}/{r.judged} | {r.worst_cents:.3f} | {100 * r.worst_t60:.1f} % | "
                     f"{r.worst_db:.2f} | {'yes' if r.passed else 'no'} |")
    return "\n".join(lines)


def summary(real: list[RealResult], synth: list[SynthResult]) -> str:
    n = len(real)
    freq = sum(r.freq_ok == r.judged for r in real)
    level = sum(r.level_ok == r.judged for r in real)
    with_t60 = [r for r in real if r.t60_judged]
    t60 = sum(r.t60_ok == r.t60_judged for r in with_t60)
    dist = sum(r.distance_ok for r in real)
    passed = sum(r.passed for r in real)
    parts = sum(r.judged for r in real)
    return (f"**Summary**: {n} real notes ({parts} partials judged): every partial within 3 cents in {freq}/{n}, "
            f"within 3 dB in {level}/{n}, T60 within 15 % in {t60}/{len(with_t60)} (notes with a single-slope "
            f"partial), distance at most half the sine's in {dist}/{n}; all four in {passed}/{n}. "
            f"Synthetic round trip: {sum(s.passed for s in synth)}/{len(synth)} within 0.5 cent, 3 % and 1 dB.")


def report(real: list[RealResult], synth: list[SynthResult]) -> str:
    return "\n\n".join([summary(real, synth), "### Real recordings", real_table(real),
                        "### Synthetic round trip (noise -40 dB, a short room)", synth_table(synth)])


def write(path: Path, text: str) -> None:
    doc = path.read_text()
    head, rest = doc.split(START, 1)
    _, tail = rest.split(END, 1)
    path.write_text(f"{head}{START}\n{text}\n{END}{tail}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", type=Path, help="replace the table between the markers in this file")
    parser.add_argument("--quick", action="store_true", help="one key per instrument, four synthetic cases")
    args = parser.parse_args(argv)
    keys = (60,) if args.quick else KEYS
    real = []
    for note in notes(keys=keys):
        try:
            real.append(measure_real(note))
        except Exception as exc:  # noqa: BLE001 - a note that cannot be fitted is a row saying why
            print(f"{note.font} {note.instrument} {note.key}: {exc}", file=sys.stderr)
            continue
        r = real[-1]
        print(f"{r.note.font:9s} {r.note.instrument:13s} {r.note.key:3d} f0 {r.f0_hz:8.2f} "
              f"freq {r.freq_ok}/{r.judged} level {r.level_ok}/{r.judged} T60 {r.t60_ok}/{r.t60_judged} "
              f"dist {r.distance_db:.2f}/{r.baseline_db:.2f} {'PASS' if r.passed else 'fail'} {r.seconds:.2f}s "
              f"{r.worst}", file=sys.stderr)
    synth = []
    for preset, freq in (SYNTH_CASES[:4] if args.quick else SYNTH_CASES):
        s = measure_synthetic(preset, freq)
        synth.append(s)
        print(f"synthetic {s.preset:11s} {s.f0_hz:8.2f} {s.freq_ok}/{s.t60_ok}/{s.level_ok} of {s.judged} "
              f"worst {s.worst_cents:.3f} c {100 * s.worst_t60:.1f} % {s.worst_db:.2f} dB", file=sys.stderr)
    text = report(real, synth)
    print(text)
    if args.write:
        write(args.write, text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
