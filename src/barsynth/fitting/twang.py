"""Fitting the ruler twang (Selfridge et al., AES 2022) to a recording of a ruler.

The twang's 18 modes (:mod:`barsynth.models.twang.design`) all scale with one number, the
full-length cantilever's ``base = sqrt(E/rho) h / (sqrt(12) 2 pi L^2)`` (Hz): the cantilever's
modes are ``base lambda_c^2``, the short cantilever's ``base lambda_c^2 / r^2`` (``r`` the
short length ratio) and the free bar's ``base lambda_f^2``. E, rho, h and L enter only through
``base`` (spec 7.2), so the fit finds ``base`` and ``r`` from the measured frequencies, ``Q``
from their T60s (``T60 = Q ln(1000) / (pi f)``), the gain shape ``l`` and the three mix gains
from their levels, and then the physical settings that give ``base``: for a named material
and thickness, the length (or for a given length, the thickness).

1. Hypotheses: for each short length ratio on a grid and each of the 18 modes, the strongest
   partials are taken in turn as that mode; each gives a ``base``. Every hypothesis is scored
   by how close (in cents, capped) every measured partial lies to some audible mode, weighted
   by level; a weak pull toward the paper's ratio (0.7) breaks the tie when only one group of
   modes is heard.
2. The best is refined by least squares on log-frequencies of the matched partials
   (``scipy.optimize.least_squares``, bounded).
3. ``Q``: the level-weighted median of each matched partial's ``pi f T60 / ln 1000``.
4. Levels: the beta shape ``l`` by a bounded scalar search (dB error against the model's gains,
   with the common offset solved exactly), then each group's mix gain from its mean residual.
5. Given the recording itself, steps 3 and 4 only start the fit of Q, the shape, the mixes and
   the level to its band energies (:mod:`.twang_levels`), which tells a free-bar band from the
   cantilever mode it lies on; the five best frequency hypotheses of step 1 (distinct rulers) are each fitted so,
   and the one whose spectrum comes closest is kept (a noise band can pull a measured partial
   by tens of cents, enough to prefer a wrong hypothesis on frequencies alone).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..physics import bending_wave_constant, lambdas, material as find_material
from .targets import Target, article, cents, strongest

__all__ = ["TwangFit", "fit_twang", "length_for_base"]

RATIO_GRID = np.linspace(0.3, 0.95, 131)
CAP_CENTS = 60.0  # a partial further than this from every mode counts as this far
PAPER_RATIO = 0.7
RATIO_PULL = 2.0  # cents of cost per 0.1 of ratio away from the paper's
GROUPS = ("full-cantilever", "short-cantilever", "free-bar")
MERGED_CENTS = 2.0  # modes closer than this sound as one: no ambiguity
CANDIDATES = 5  # frequency hypotheses the recording's spectrum decides between


@dataclass(frozen=True)
class Match:
    """A measured partial and the model's mode it was taken as."""

    target: Target
    group: str
    number: int  # 1-based within its group
    model_hz: float

    @property
    def cents(self) -> float:
        return float(cents(self.model_hz, self.target.frequency_hz))


@dataclass(frozen=True)
class TwangFit:
    """The fitted twang: its parameters (the model's table names) and how each partial matched."""

    parameters: dict[str, Any]
    base_hz: float
    matches: tuple[Match, ...]
    unmatched: tuple[Target, ...] = field(default=())


def _multipliers(ratio: float | np.ndarray) -> np.ndarray:
    """Each mode's frequency / base, shape (..., 18): cantilever, short cantilever, free bar."""
    lc = lambdas("clamped-free", 6) ** 2
    lf = lambdas("free-free", 6) ** 2
    r = np.asarray(ratio, dtype=float)[..., None]
    return np.concatenate([np.broadcast_to(lc, r.shape[:-1] + (6,)), lc / r ** 2,
                           np.broadcast_to(lf, r.shape[:-1] + (6,))], axis=-1)


def _cost(freqs: np.ndarray, weights: np.ndarray, modes_hz: np.ndarray, nyquist: float) -> np.ndarray:
    """Level-weighted capped squared cents from each measured partial to its nearest audible mode,
    for each row of ``modes_hz`` (hypotheses x 18)."""
    audible = (modes_hz >= 20.0) & (modes_hz < nyquist)
    distance = np.abs(1200.0 * np.log2(freqs[None, :, None] / modes_hz[:, None, :]))
    distance = np.where(audible[:, None, :], distance, np.inf)  # a mode nobody hears explains nothing
    nearest = np.minimum(distance.min(axis=2), CAP_CENTS)
    return (weights[None, :] * nearest ** 2).sum(axis=1) / weights.sum()


def _match(targets: list[Target], base: float, ratio: float, nyquist: float) -> tuple[list[Match], list[Target]]:
    modes = base * _multipliers(ratio)
    matches, unmatched = [], []
    for t in targets:
        distance = np.abs(cents(t.frequency_hz, modes))
        distance[(modes < 20.0) | (modes >= nyquist)] = np.inf
        k = int(np.argmin(distance))
        if distance[k] <= CAP_CENTS:
            matches.append(Match(t, GROUPS[k // 6], k % 6 + 1, float(modes[k])))
        else:
            unmatched.append(t)
    return matches, unmatched


def _frequencies(targets: list[Target], sample_rate: float, bases_hz: tuple[float, float] = (0.0, math.inf),
                 count: int = 1) -> list[tuple[float, float]]:
    """Up to ``count`` distinct ``(base, ratio)``, best first, that place the measured partials on
    the twang's modes; a ``base`` outside ``bases_hz`` (a ruler out of the model's ranges) is
    taken only if nothing else fits."""

    nyquist = 0.5 * sample_rate
    freqs = np.array([t.frequency_hz for t in targets])
    levels = np.array([t.level_db for t in targets])
    weights = 10.0 ** ((levels - levels.max()) / 40.0)  # -40 dB weighs 0.1: levels matter, gently
    anchors = np.argsort(-levels)[:3]
    found = []
    for ratio in RATIO_GRID:
        mult = _multipliers(ratio)
        bases = (freqs[anchors][:, None] / mult[None, :]).ravel()
        bases = bases[bases > 0.0]
        scores = _cost(freqs, weights, bases[:, None] * mult[None, :], nyquist)
        scores = scores + RATIO_PULL * abs(ratio - PAPER_RATIO) * 10.0
        scores = scores + np.where((bases >= bases_hz[0]) & (bases <= bases_hz[1]), 0.0, 2.0 * CAP_CENTS ** 2)
        for i in np.argsort(scores)[:count]:
            found.append((float(scores[i]), float(bases[i]), float(ratio)))
    chosen: list[tuple[float, float]] = []
    for _, base, ratio in sorted(found):
        if len(chosen) == count:
            break
        if all(abs(math.log(base / b)) > 0.03 for b, _ in chosen):  # another ruler, not another ratio
            chosen.append(_refined(targets, base, ratio, nyquist, levels.max()))
    return chosen


def _refined(targets: list[Target], base: float, ratio: float, nyquist: float, top_db: float) -> tuple[float, float]:
    """``(base, ratio)`` refined by least squares on the log-frequencies of the partials they match.
    A partial whose mode has another within a few tens of cents (a free-bar band beside a
    cantilever mode: the analysis hears one partial between them) weighs a tenth."""
    from scipy.optimize import least_squares

    matches, _ = _match(targets, base, ratio, nyquist)
    if len(matches) >= 2:
        index = [GROUPS.index(m.group) * 6 + m.number - 1 for m in matches]
        f = np.array([m.target.frequency_hz for m in matches])
        w = np.sqrt(10.0 ** ((np.array([m.target.level_db for m in matches]) - top_db) / 40.0))
        modes = base * _multipliers(ratio)
        for j, k in enumerate(index):
            apart = np.abs(cents(modes, modes[k]))
            apart[k] = np.inf
            if np.any((apart > MERGED_CENTS) & (apart < CAP_CENTS)):
                w[j] *= math.sqrt(0.1)

        def residual(x: np.ndarray) -> np.ndarray:
            model = math.exp(x[0]) * _multipliers(x[1])[index]
            return w * 1200.0 * np.log2(model / f)

        lo, hi = RATIO_GRID[0], RATIO_GRID[-1]
        solved = least_squares(residual, [math.log(base), min(max(ratio, lo), hi)],
                               bounds=([-np.inf, lo], [np.inf, hi]), x_scale=[0.01, 0.01])
        if solved.success:
            base, ratio = math.exp(solved.x[0]), float(solved.x[1])
    return base, ratio


def _q(matches: list[Match]) -> float:
    """Level-weighted median of the matched partials' Q (100, the model's default, if none decays)."""
    qs, ws = [], []
    for m in matches:
        t60 = m.target.t60_s
        if t60 is not None and math.isfinite(t60) and t60 > 0.0:
            qs.append(math.pi * m.target.frequency_hz * t60 / math.log(1000.0))
            ws.append(10.0 ** (m.target.level_db / 20.0))
    if not qs:
        return 100.0
    order = np.argsort(qs)
    cumulative = np.cumsum(np.array(ws)[order])
    return float(np.array(qs)[order][np.searchsorted(cumulative, 0.5 * cumulative[-1])])


def _levels(matches: list[Match], base: float, ratio: float, sample_rate: float) -> dict[str, float]:
    """The gain shape and the three mix gains that best give the matched partials' levels."""
    from scipy.optimize import minimize_scalar

    from ..models.twang import TWANG_TABLE

    if not matches:
        return {}
    index = [GROUPS.index(m.group) * 6 + m.number - 1 for m in matches]
    measured = np.array([m.target.level_db for m in matches])

    def model_db(shape: float) -> np.ndarray:
        p = TWANG_TABLE.resolve({"shape": shape, "short_length_ratio": ratio})
        modes = _design_all(p, sample_rate, base)
        gains = np.array([modes[i] for i in index])
        return 20.0 * np.log10(np.maximum(gains, 1e-12))

    def error(shape: float) -> float:
        d = measured - model_db(shape)
        return float(np.mean((d - d.mean()) ** 2))

    shape = float(minimize_scalar(error, bounds=(0.5, 10.0), method="bounded", options={"xatol": 1e-3}).x)
    residual = measured - model_db(shape)
    residual = residual - residual.max()
    mix = {}
    for group, name, top in (("full-cantilever", "full_cantilever_gain", 1.0),
                             ("short-cantilever", "short_cantilever_gain", 1.0), ("free-bar", "free_bar_gain", 4.0)):
        mine = [r for m, r in zip(matches, residual) if m.group == group]
        mix[name] = 0.0 if not mine else float(min(top, 10.0 ** (np.mean(mine) / 20.0)))
    if max(mix.values()) > 0.0:  # the loudest group at its full mix
        scale = 1.0 / max(mix["full_cantilever_gain"], mix["short_cantilever_gain"], mix["free_bar_gain"] / 4.0)
        mix = {k: float(min(v * scale, 4.0 if k == "free_bar_gain" else 1.0)) for k, v in mix.items()}
    return {"shape": shape, **mix}


def _design_all(p: Any, sample_rate: float, base: float) -> np.ndarray:
    """The model's 18 gains for parameters ``p`` with its modes at ``base`` (Hz) (the design's
    own arithmetic: nothing re-derived here)."""
    from ..models.twang.design import N_MODES, design, mode_lambdas, new_modes
    from ..models.twang.table import ROWS, control_vector

    values = control_vector(p)
    # put the design's base where the fit found it: length follows from E, rho and h
    a = bending_wave_constant(p.youngs_modulus_pa, p.density_kg_m3, p.thickness_m)
    values[ROWS.length_m] = math.sqrt(a / (2.0 * math.pi * base))
    modes = new_modes()
    design(values, ROWS, mode_lambdas(), np.ones(N_MODES), float(sample_rate), 0.0, 0.0, modes)  # plain Python
    return modes.gain.copy()


def _bases(material: str, thickness_m: float | None, length_m: float | None) -> tuple[float, float]:
    """The lowest and highest ``base`` (Hz) a ruler of ``material`` can have within the model's
    ranges, with the thickness (or length) given and the other free."""
    from ..models.twang import TWANG_TABLE

    row = {p.name: p for p in TWANG_TABLE}
    m = find_material(material)
    root = math.sqrt(m.youngs_modulus_pa / m.density_kg_m3) / math.sqrt(12.0)
    if length_m is None:
        h = thickness_m if thickness_m is not None else row["thickness_m"].default
        lengths = (row["length_m"].maximum, row["length_m"].minimum)
        return tuple(root * h / (2.0 * math.pi * L ** 2) for L in lengths)
    thicknesses = (row["thickness_m"].minimum, row["thickness_m"].maximum)
    return tuple(root * h / (2.0 * math.pi * length_m ** 2) for h in thicknesses)


def _physical(base: float, material: str, thickness_m: float | None, length_m: float | None) -> dict[str, Any]:
    """The material, length and thickness that give ``base`` (Hz): the length for the given (or
    the model's default) thickness, else the thickness for a given length."""
    from ..models.twang import TWANG_TABLE

    row = {p.name: p for p in TWANG_TABLE}
    m = find_material(material)
    root = math.sqrt(m.youngs_modulus_pa / m.density_kg_m3) / math.sqrt(12.0)  # a = root * h
    if length_m is None:
        h = thickness_m if thickness_m is not None else row["thickness_m"].default
        length = math.sqrt(root * h / (2.0 * math.pi * base))
        result = {"thickness_m": h, "length_m": length}
    else:
        h = 2.0 * math.pi * base * length_m ** 2 / root
        result = {"thickness_m": h, "length_m": length_m}
    for name, value in result.items():
        p = row[name]
        if not p.minimum <= value <= p.maximum:
            raise ParameterError(
                f"{article(material)} {material} ruler would need {name} = {value:.4g} {p.unit} to ring as recorded, "
                f"out of range; allowed: {p.minimum:g} to {p.maximum:g} {p.unit} (give another material, thickness or length)")
    return {"material": material, **result}


def length_for_base(base: float, fixed: dict[str, Any]) -> float:
    """The clamped length (m) at which the ruler ``fixed`` (material or E and rho, thickness)
    has its full-length cantilever's ``base`` (Hz)."""
    from ..models.twang import TWANG_TABLE

    p = TWANG_TABLE.resolve({k: v for k, v in fixed.items() if k != "length_m"})
    a = bending_wave_constant(p.youngs_modulus_pa, p.density_kg_m3, p.thickness_m)
    return math.sqrt(a / (2.0 * math.pi * base))


def fit_twang(targets: list[Target], *, sample_rate: float, material: str = "acrylic",
              thickness_m: float | None = None, length_m: float | None = None,
              recording: np.ndarray | None = None) -> TwangFit:
    """The twang whose modes best match ``targets`` (see the module docstring).

    ``material`` (a name of ``barsynth materials``) and ``thickness_m`` (default: the model's) or
    ``length_m`` fix what frequencies cannot tell apart. With ``recording`` (mono, from the
    onset, at ``sample_rate``) Q, the gain shape, the mixes and the level are then fitted to its
    band energies (:mod:`.twang_levels`). Raises :class:`ParameterError` (one line) when there
    is nothing to fit or the ruler it needs is out of the model's ranges."""
    if thickness_m is not None and length_m is not None:  # the frequencies fix one from the other
        raise ParameterError(f"parameters thickness_m = {thickness_m:g} m and length_m = {length_m:g} m are both "
                             "given; allowed: one of them (the recording's frequencies fix the other)")
    kept = strongest(targets, within_db=40.0, at_most=18)
    if not kept:
        raise ParameterError("the recording has no sustained partial to fit a twang to; allowed: a recording "
                             "of a ruler with at least one partial above 20 Hz")
    candidates = _frequencies(kept, sample_rate, _bases(material, thickness_m, length_m),
                              count=1 if recording is None else CANDIDATES)
    best: tuple[float, TwangFit] | None = None
    screen = len(candidates) > 1
    signal = None if recording is None else np.asarray(recording, dtype=float)
    if signal is not None:
        from .twang_levels import measure

        measured = measure(signal, float(sample_rate))
    for k, (base, ratio) in enumerate(candidates):
        try:
            parameters: dict[str, Any] = _physical(base, material, thickness_m, length_m)
        except ParameterError:
            if k == 0 and len(candidates) == 1:
                raise
            continue
        matches, unmatched = _match(kept, base, ratio, 0.5 * sample_rate)
        parameters["short_length_ratio"] = ratio
        parameters["q"] = float(min(max(_q(matches), 50.0), 800.0))
        parameters.update(_levels(matches, base, ratio, sample_rate))
        cost = 0.0 if recording is None else math.inf  # a ruler that explains no partial never wins
        if recording is not None and matches:
            from .twang_levels import fit_levels

            fixed = {"material": material, "thickness_m": parameters["thickness_m"]}
            levels, cost = fit_levels(signal, sample_rate, base, ratio, parameters["q"],
                                      parameters.get("shape", 1.5), fixed, screen=screen,
                                      measured=measured)
            parameters.update(levels)
        fit = TwangFit(parameters, base, tuple(matches), tuple(unmatched))
        if best is None or cost < best[0]:
            best = (cost, fit)
    if best is not None and screen and recording is not None and best[1].matches:
        from .twang_levels import fit_levels

        chosen = best[1]  # the hypothesis the spectrum chose, fitted in full from its quick look
        fixed = {"material": material, "thickness_m": chosen.parameters["thickness_m"]}
        levels, cost = fit_levels(signal, sample_rate, chosen.base_hz,
                                  chosen.parameters["short_length_ratio"], chosen.parameters["q"],
                                  chosen.parameters["shape"], fixed, measured=measured)
        best = (cost, TwangFit({**chosen.parameters, **levels}, chosen.base_hz, chosen.matches, chosen.unmatched))
    if best is None:  # every candidate's ruler is out of range: say so for the best one
        _physical(candidates[0][0], material, thickness_m, length_m)
        raise ParameterError("no ruler within the model's ranges rings as recorded; allowed: a recording of a ruler")
    return best[1]
