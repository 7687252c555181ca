"""The twang's Q, gain shape, mixes and level from the recording's spectrum (analysis by synthesis).

Once the frequencies are known (:mod:`.twang`), what is left sets how loud and how long each
mode sounds: ``q``, the beta gain shape ``l`` (``shape``), the three mix gains and
``level_db``. The measured partials cannot tell them apart well: a free-bar band (noise through a
band-pass) lies on a cantilever mode (the free-free and clamped-free eigenvalues nearly
coincide), and its level is not that of a damped cosine. So the fit compares energies:

1. The recording (from the onset, the first ``T`` = up to 1 s) as band energies, 48 bands an
   octave over the modes, in the first and second half of ``T`` (the halves tell the decay, so
   ``Q``); the noise floor of each band is the 20th percentile of the spectrum within half an
   octave, added to the model.
2. Templates: the model rendered (it takes milliseconds) at the fitted frequencies with one group
   at a time (mixes 1, 0, 0 and so on), each spectrum bin given to its nearest mode of the group,
   so each mode's band energies per half are known for a reference ``Q`` and shape.
3. Any other ``Q`` and shape scale each mode's template in closed form: its gain (the model's
   own design, normalisation included) squared, and each half's energy by
   ``int exp(-2 alpha t) dt`` with ``alpha = pi f / Q``; the mixes add power (groups are
   independent: cosines and noise). A bounded fit of the band energies by their deviance as
   exponentially distributed values (Whittle's likelihood: least squares on their dB would put
   a noise band's energy, which scatters by several dB, too low) finds ``Q``, ``l`` and each
   group's power; the templates are rendered again at the result and the fit repeated, at most
   :data:`ITERATIONS` times in all.
4. The full-length cantilever's mix is 1 (the paper's) unless another group needs more room; the
   level then follows from the group powers.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

import numpy as np

__all__ = ["fit_levels", "measure"]

BANDS_PER_OCTAVE = 48
LONGEST_S = 1.0
FLOOR_PERCENTILE = 20.0
REFERENCE_LEVEL_DB = -3.0  # the templates' level (the model's default)
RANGE_DB = 80.0  # bands this far below the strongest are left out (the model culls quieter modes)
ITERATIONS = 3
NOISE_RENDERS = 4  # free-bar renders averaged into its template
Q_STARTS = (0.6, 1.0, 1.6)
MIX_TOPS = (1.0, 1.0, 4.0)  # full, short, free: the table's maxima
MIX_NAMES = ("full_cantilever_gain", "short_cantilever_gain", "free_bar_gain")


def _gains(base: float, ratio: float, q: float, shape: float, sample_rate: float,
           fixed: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 18 modes' frequencies (Hz), gains (mixes 1, the level scale included) and decay rates
    (1/s), from the model's own design."""
    from ..models.twang.design import N_MODES, design, mode_lambdas, new_modes
    from ..models.twang.table import ROWS

    values = _controls(base, ratio, tuple(sorted(fixed.items()))).copy()
    values[ROWS.q] = min(max(q, 50.0), 800.0)
    values[ROWS.shape] = min(max(shape, 0.5), 10.0)
    modes = new_modes()
    _, norm = design(values, ROWS, mode_lambdas(), np.ones(N_MODES), float(sample_rate), 0.0, 0.0, modes)
    return modes.frequency_hz.copy(), modes.gain * norm, modes.alpha_per_s.copy()


@lru_cache(maxsize=64)
def _controls(base: float, ratio: float, fixed: tuple[tuple[str, Any], ...]) -> np.ndarray:
    """The twang's control vector for the ruler ``fixed`` with its modes at ``base`` (Hz), the
    short length ``ratio`` and every mix 1 (q and shape are set per call)."""
    from ..models.twang import TWANG_TABLE
    from ..models.twang.table import ROWS, control_vector
    from ..physics import bending_wave_constant

    p = TWANG_TABLE.resolve({**dict(fixed), "short_length_ratio": ratio, "full_cantilever_gain": 1.0,
                             "short_cantilever_gain": 1.0, "free_bar_gain": 1.0})
    values = control_vector(p)
    a = bending_wave_constant(p.youngs_modulus_pa, p.density_kg_m3, p.thickness_m)
    values[ROWS.length_m] = math.sqrt(a / (2.0 * math.pi * base))
    return values


def _half_energy(alpha: np.ndarray, half_s: float, which: int) -> np.ndarray:
    """``int exp(-2 alpha t) dt`` over the first (0) or second (1) half of ``2 half_s``."""
    a2 = np.maximum(2.0 * alpha, 1e-9)
    first = (1.0 - np.exp(-a2 * half_s)) / a2
    return first if which == 0 else first * np.exp(-a2 * half_s)


class _Bands:
    """Band energies of a sound's first and second half (48 bands an octave over ``lo``-``hi`` Hz)."""

    def __init__(self, sample_rate: float, n: int, lo: float, hi: float):
        self.n = n
        self.half = n // 2
        self.freqs = np.fft.rfftfreq(self.half, 1.0 / sample_rate)
        edges = lo * 2.0 ** (np.arange(int(math.ceil(BANDS_PER_OCTAVE * math.log2(hi / lo))) + 1) / BANDS_PER_OCTAVE)
        self.index = np.searchsorted(edges, self.freqs) - 1
        self.inside = (self.index >= 0) & (self.index < edges.size - 1)
        self.count = edges.size - 1
        self.centres = np.sqrt(edges[:-1] * edges[1:])
        self.window = np.hanning(self.half)

    def spectra(self, x: np.ndarray) -> np.ndarray:
        """Power spectra of the two halves, shape (2, bins)."""
        padded = np.zeros(self.n)
        padded[:min(self.n, x.size)] = x[:self.n]
        halves = padded[:2 * self.half].reshape(2, self.half) * self.window
        return np.abs(np.fft.rfft(halves, axis=1)) ** 2

    def energies(self, power: np.ndarray) -> np.ndarray:
        """Band sums of power spectra (..., bins) -> (..., bands)."""
        out = np.zeros(power.shape[:-1] + (self.count,))
        idx = self.index[self.inside]
        flat = power[..., self.inside].reshape(-1, idx.size)
        acc = out.reshape(-1, self.count)
        for row in range(flat.shape[0]):
            acc[row] = np.bincount(idx, weights=flat[row], minlength=self.count)[:self.count]
        return out

    def floor(self, power: np.ndarray) -> np.ndarray:
        """Each band's noise floor (the spectrum's FLOOR_PERCENTILE within half an octave, per bin,
        times the band's bins), shape (2, bands)."""
        counts = np.bincount(self.index[self.inside], minlength=self.count)[:self.count]
        out = np.zeros((2, self.count))
        for b, centre in enumerate(self.centres):
            near = (self.freqs >= centre * 2.0 ** -0.5) & (self.freqs <= centre * 2.0 ** 0.5)
            if near.any():
                out[:, b] = np.percentile(power[:, near], FLOOR_PERCENTILE, axis=1) * max(counts[b], 1)
        return out


def _templates(bands: _Bands, base: float, ratio: float, q: float, shape: float, sample_rate: float,
               fixed: dict[str, Any], freqs: np.ndarray, gains: np.ndarray) -> np.ndarray:
    """Each mode's band energies per half, shape (18, 2, bands), for mixes 1 at (q, shape)."""
    from ..models import get_model

    from .twang import length_for_base

    model = get_model("twang")
    out = np.zeros((18, 2, bands.count))
    params = {**fixed, "length_m": length_for_base(base, fixed), "short_length_ratio": ratio, "q": q,
              "shape": shape, "level_db": REFERENCE_LEVEL_DB}
    seconds = bands.n / sample_rate
    for g, mixes in enumerate(((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))):
        members = [k for k in range(6 * g, 6 * g + 6) if gains[k] > 0.0]
        if not members:
            continue
        # the free bar is noise: its template is the mean of a few renders (the expected spectrum)
        seeds = range(1, 1 + (NOISE_RENDERS if g == 2 else 1))
        power = np.mean([bands.spectra(model.render({**params, **dict(zip(MIX_NAMES, mixes))}, duration_s=seconds,
                                                    sample_rate=sample_rate, normalize=False, dtype=np.float64,
                                                    seed=seed)) for seed in seeds], axis=0)
        owner = np.abs(np.log(np.maximum(bands.freqs[:, None], 1e-9) / freqs[members][None, :])).argmin(axis=1)
        for j, k in enumerate(members):
            out[k] = bands.energies(np.where(owner == j, power, 0.0))
    return out


def measure(recording: np.ndarray, sample_rate: float) -> tuple[_Bands, np.ndarray, np.ndarray, np.ndarray] | None:
    """What the fit compares with (frequency hypotheses share it): the bands, the recording's band
    energies and noise floors per half, and the bands that hold signal (above the floor, within
    RANGE_DB of the strongest). None for a recording too short to measure."""
    n = int(min(recording.size, round(LONGEST_S * sample_rate)))
    n -= n % 2
    if n < 256:
        return None
    bands = _Bands(sample_rate, n, 15.0, 0.49 * sample_rate)
    power = bands.spectra(recording[:n])
    measured = bands.energies(power)
    floor = bands.floor(power)
    strongest = measured.max(axis=0)
    signal = ((strongest > 3.0 * floor.max(axis=0)) & (measured.min(axis=0) > 0.0)
              & (strongest > strongest.max() * 10.0 ** (-RANGE_DB / 10.0)))
    return bands, measured, floor, signal


def fit_levels(recording: np.ndarray, sample_rate: float, base: float, ratio: float, q: float, shape: float,
               fixed: dict[str, Any], *, screen: bool = False,
               measured: tuple[Any, ...] | None = None) -> tuple[dict[str, float], float]:
    """``q``, ``shape``, the three mixes and ``level_db`` of the twang (frequencies ``base``, ``ratio``
    fixed) whose band energies best match ``recording`` (from its onset); see the module docstring.
    ``q`` and ``shape`` start the search; ``fixed`` holds the ruler's material settings. Returns
    them and the fit's mean deviance per band (comparable between frequency hypotheses: the
    bands span 15 Hz to nearly Nyquist whatever the modes). ``screen``: one start and no second
    rendering of the templates (a quick look, to choose between frequency hypotheses);
    ``measured``: :func:`measure` of the recording, if already taken."""
    from scipy.optimize import least_squares

    freqs, gains, _ = _gains(base, ratio, q, shape, sample_rate, fixed)
    taken = measured if measured is not None else measure(recording, float(sample_rate))
    if taken is None or not (gains > 0.0).any():
        return {}, math.inf
    bands, measured, floor, signal = taken
    if signal.sum() < 3:
        return {}, math.inf
    half_s = bands.half / sample_rate

    def solve(q: float, shape: float) -> tuple[float, float, float, np.ndarray]:
        """(cost, Q, shape, group powers) from templates rendered at ``q`` and ``shape``."""
        from scipy.optimize import nnls

        q, shape = min(max(q, 50.0), 800.0), min(max(shape, 0.5), 10.0)
        f_ref, g_ref, a_ref = _gains(base, ratio, q, shape, sample_rate, fixed)
        templates = _templates(bands, base, ratio, q, shape, sample_rate, fixed, f_ref, g_ref)
        held = g_ref > 0.0
        e_ref = np.stack([_half_energy(a_ref, half_s, h) for h in (0, 1)], axis=1)  # (18, 2)
        observed = measured[:, signal].ravel()

        def residual(x: np.ndarray) -> np.ndarray:
            _, g, a = _gains(base, ratio, q * math.exp(x[0]), x[1], sample_rate, fixed)
            e = np.stack([_half_energy(a, half_s, h) for h in (0, 1)], axis=1)
            scale = np.where(held, (g / np.where(held, g_ref, 1.0)) ** 2, 0.0)[:, None] * e / np.maximum(e_ref, 1e-300)
            per_mode = scale[:, :, None] * templates  # (18, 2, bands)
            total = sum(math.exp(x[2 + k]) * per_mode[6 * k:6 * k + 6].sum(axis=0) for k in range(3))
            total = total + math.exp(x[5]) * floor
            # deviance residuals of exponentially distributed band energies (Whittle): a noise band's
            # energy scatters by several dB about its mean, and the mean of its dB lies below the dB
            # of its mean, so least squares on dB would put the noise low
            ratio_ = observed / np.maximum(total[:, signal].ravel(), 1e-300)
            return np.sign(ratio_ - 1.0) * np.sqrt(np.maximum(2.0 * (ratio_ - 1.0 - np.log(ratio_)), 0.0))

        # each group's power to start from: non-negative least squares on the band energies,
        # each band's error relative to its energy (as the dB the fit then minimises)
        columns = np.stack([templates[6 * k:6 * k + 6].sum(axis=0)[:, signal].ravel() for k in range(3)], axis=1)
        target = np.maximum(measured - floor, 0.0)[:, signal].ravel()
        weight = 1.0 / np.maximum(measured[:, signal].ravel(), 1e-300)
        powers, _ = nnls(columns * weight[:, None], target * weight)
        top = max(float(powers.max()), 1e-300)
        lower = np.array([math.log(50.0 / q) - 1e-3, 0.5, -80.0, -80.0, -80.0, -30.0])
        upper = np.array([math.log(800.0 / q) + 1e-3, 10.0, 80.0, 80.0, 80.0, 3.0])
        x0 = np.array([0.0, shape, *(math.log(max(v, 1e-6 * top)) for v in powers), 0.0])
        x0 = np.clip(x0, lower + 1e-6, upper - 1e-6)
        solved = least_squares(residual, x0, bounds=(lower, upper), x_scale=[0.05, 0.1, 0.5, 0.5, 0.5, 1.0],
                               max_nfev=200)
        powers = np.exp(solved.x[2:5]) * np.array([(g_ref[6 * k:6 * k + 6] > 0.0).any() for k in range(3)])
        return float(solved.cost), q * math.exp(float(solved.x[0])), float(solved.x[1]), powers

    # Q from the analysis' T60s can be far off where a noise band sits on a mode: three starts
    result = min((solve(q * factor, shape) for factor in ((1.0,) if screen else Q_STARTS)), key=lambda r: r[0])
    for _ in range(0 if screen else ITERATIONS - 1):  # templates again at the result, until it settles
        again = solve(result[1], result[2])
        settled = abs(math.log(again[1] / result[1])) < 0.02 and abs(again[2] - result[2]) < 0.05
        result = again
        if settled:
            break
    cost, q, shape, power = result
    amplitude = np.sqrt(power)  # each group's mix x (the level's amplitude over the template's)
    amplitude = np.where(amplitude < 1e-3 * amplitude.max(), 0.0, amplitude)  # a group 60 dB down is not there
    scale = max(amplitude[0], amplitude[1] / MIX_TOPS[1], amplitude[2] / MIX_TOPS[2], 1e-12)
    mixes = {name: float(min(a / scale, top)) for name, a, top in zip(MIX_NAMES, amplitude, MIX_TOPS)}
    level = REFERENCE_LEVEL_DB + 20.0 * math.log10(scale)
    return ({"q": float(min(max(q, 50.0), 800.0)), "shape": float(min(max(shape, 0.5), 10.0)), **mixes,
             "level_db": float(min(max(level, -60.0), 0.0))}, cost / max(int(signal.sum()), 1))
