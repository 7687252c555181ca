"""Complex demodulation of one partial and its fits: the engine behind :mod:`.search`.

Each partial is modelled as a damped cosine that starts with the sound,
``A exp(-(t - t0) ln(1000) / T60) cos(2 pi f t + phi)``.

- **Demodulation.** Around each partial the sound's spectrum is cut out, shifted
  to 0 Hz and low-passed with the zero-phase response ``exp(-0.5 (f / f1)**4)``
  (-6 dB at the cutoff, -96 dB at twice the cutoff); a short inverse FFT gives the
  partial's complex envelope.
- **First estimate.** For a ladder of decay rates, the complex amplitude that best
  fits the envelope follows by linear least squares; the best rate wins. Two
  nuisance columns (the low-pass's response to an impulse at the onset) take up
  the onset skirts of partials not yet modelled, which would otherwise pass for a
  fast decay.
- **Gauss-Newton on the residual.** A partial's frequency, decay and amplitude are
  corrected so that its model, sent through *the same* band extraction and
  low-pass (its DFT is a geometric series, in closed form), best matches the
  filtered residual plus its old model; the nearest partials on either side take
  part in the solve. The low-pass therefore biases nothing.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .candidates import global_onset

LN1000 = math.log(1000.0)  # a decay rate sigma (1/s) is a T60 of LN1000 / sigma
_DB_PER_NEPER = 20.0 / math.log(10.0)
# exp(-0.5 (f/f1)^4) is 6 dB down at f = f1 * (2 ln 2)^(1/4).
SG_6DB = (2.0 * math.log(2.0)) ** 0.25
# beyond 2.6 f1 the response is below 1e-10: the band kept around a partial
_SG_EXTENT = 2.6
MIN_FIT_POINTS = 8  # the fewest envelope samples a fit is made on


def _damped_phasor(start: float, count: int, s: complex) -> np.ndarray:
    """exp(s * (start + n)) for n = 0..count-1, by an outer product of two short tables.

    As exact as ``np.exp`` on every sample (no recursion, no drift) at a fraction of
    its cost.
    """
    if count <= 0:
        return np.zeros(0, dtype=np.complex128)
    block = 512
    nblocks = -(-count // block)
    inner = np.exp(s * np.arange(block))
    outer = np.exp(s * (start + block * np.arange(nblocks)))
    return np.multiply.outer(outer, inner).ravel()[:count]


@dataclass
class Mode:
    """A partial being refined.

    Its model, sampled like the sound, is 2 Re(amp exp((-sigma + 2j pi f)(t - t_on)))
    for t >= t_on and 0 before.
    """

    frequency_hz: float
    centre_hz: float  # where its demodulation band is centred
    cutoff_hz: float = 0.0
    fixed_cutoff: bool = False
    fixed_centre: bool = False
    sigma: float = 0.0  # decay rate, 1/s (amplitude ~ exp(-sigma t))
    amp: complex = 0j  # complex amplitude (half the cosine amplitude) at t_on
    t_on: float = 0.0
    fitted: bool = False
    ok: bool = True
    coherence: float = 1.0  # share of the band's energy the model explains
    settled: bool = False  # its last Gauss-Newton step changed nothing that matters
    pinned: bool = False  # measure_partial's partial: never dropped
    moved: bool = True  # it changed in the last sweep

    @property
    def level_db(self) -> float:
        a = 2.0 * abs(self.amp)
        return 20.0 * math.log10(a) if a > 0 else -math.inf

    def copy(self, **changes: Any) -> Mode:
        return dataclasses.replace(self, **changes)


@dataclass
class Band:
    """The demodulation band of one partial: FFT bins, low-pass weights, time grid."""

    k: np.ndarray  # FFT bins (k0 + m; may be negative or beyond Nyquist)
    m: np.ndarray  # offsets from k0
    mask: np.ndarray  # zero-phase low-pass response at each offset
    f_bin: float  # frequency of bin k0, Hz
    size: int  # length of the inverse FFT
    t: np.ndarray  # times of the envelope samples (within the sound), s


class Engine:
    """One analysis: the signal, its zero padding and the demodulation machinery."""

    def __init__(self, x: np.ndarray, fs: float) -> None:
        self.x = x
        self.fs = fs
        self.n = x.size
        self.duration = x.size / fs
        self.n0 = global_onset(x, fs)
        self.t0 = self.n0 / fs
        self.peak = float(np.max(np.abs(x))) if x.size else 0.0
        self.npad = 0

    def prepare(self, modes: list[Mode]) -> None:
        """Choose the FFT length: room for the narrowest filter's smear on both sides."""
        from scipy import fft as sfft

        narrowest = min((m.cutoff_hz for m in modes), default=10.0)
        f1 = narrowest / SG_6DB
        pad = int(math.ceil(2.0 * 2.3 / f1 * self.fs))
        pad = min(self.n, max(self.n // 4, pad, 64))
        self.npad = sfft.next_fast_len(self.n + pad, real=True)

    def spectrum(self, signal: np.ndarray) -> np.ndarray:
        from scipy import fft as sfft

        return sfft.rfft(signal, self.npad)

    # -- bands ---------------------------------------------------------------------
    def band(self, centre_hz: float, cutoff_hz: float) -> Band:
        from scipy import fft as sfft

        npad, fs = self.npad, self.fs
        k0 = int(round(centre_hz * npad / fs))
        f1 = cutoff_hz / SG_6DB
        half = int(math.ceil(_SG_EXTENT * f1 * npad / fs))
        half = max(1, min(half, npad // 2 - 1))
        m = np.arange(-half, half + 1)
        mask = np.exp(-0.5 * ((m * (fs / npad)) / f1) ** 4)
        size = sfft.next_fast_len(max(256, 2 * m.size))
        size = min(size, npad)
        dt = npad / (size * fs)
        count = min(size, int(math.ceil(self.duration / dt)))
        t = np.arange(count) * dt
        return Band(k=k0 + m, m=m, mask=mask, f_bin=k0 * fs / npad, size=size, t=t)

    def band_values(self, spec: np.ndarray, band: Band) -> np.ndarray:
        """A real signal's spectrum at the band's bins (negative ones mirrored)."""
        npad = self.npad
        k = band.k
        j = np.abs(k)
        beyond = j > npad // 2
        j = np.where(beyond, npad - j, j)
        vals = spec[np.clip(j, 0, spec.size - 1)]
        return np.where((k < 0) ^ beyond, np.conj(vals), vals)

    def envelope(self, band: Band, values: np.ndarray) -> np.ndarray:
        """Low-passed complex envelope (on band.t) of spectrum values at the band's bins.

        A cosine A cos(2 pi f t + phi) in the band gives (A/2) exp(j(2 pi (f - f_bin) t + phi)).
        """
        from scipy import fft as sfft

        buf = np.zeros(band.size, dtype=np.complex128)
        np.add.at(buf, band.m % band.size, values * band.mask)
        z = sfft.ifft(buf) * (band.size / self.npad)
        return z[: band.t.size]

    def envelopes(self, band: Band, values: np.ndarray) -> np.ndarray:
        """:meth:`envelope` of several rows of spectrum values at once."""
        from scipy import fft as sfft

        buf = np.zeros((values.shape[0], band.size), dtype=np.complex128)
        buf[:, band.m % band.size] = values * band.mask
        z = sfft.ifft(buf, axis=1) * (band.size / self.npad)
        return z[:, : band.t.size]

    # -- models ----------------------------------------------------------------------
    def span(self, m: Mode) -> tuple[int, int]:
        """First sample of a model and how many samples it lasts (until 1e-14 of the peak)."""
        n_on = max(0, int(math.ceil(m.t_on * self.fs - 1e-9)))
        count = self.n - n_on
        floor = 1e-14 * max(self.peak, 1e-300)
        a2 = 2.0 * abs(m.amp)
        if m.sigma > 0 and a2 > floor:
            count = min(count, int(math.log(a2 / floor) / m.sigma * self.fs) + 1)
        return n_on, max(count, 0)

    def synthesise(
        self, modes: list[Mode], out: np.ndarray | None = None, sign: float = 1.0
    ) -> np.ndarray:
        """Sum of the models, sampled like the input (added with ``sign`` to ``out``)."""
        if out is None:
            out = np.zeros(self.n)
        for m in modes:
            if not (m.fitted and m.ok) or m.amp == 0:
                continue
            n_on, count = self.span(m)
            if count <= 0:
                continue
            s = complex(-m.sigma, 2.0 * math.pi * m.frequency_hz) / self.fs
            ph = _damped_phasor(n_on - m.t_on * self.fs, count, s)
            out[n_on : n_on + count] += (2.0 * sign) * (m.amp * ph).real
        return out

    def residual(self, modes: list[Mode], state: dict | None) -> tuple[np.ndarray, dict]:
        """The sound less all models, updated from ``state`` for the models that changed.

        ``state`` holds the last residual and the models in it (keyed by their
        parameters); pass None to start afresh.
        """
        wanted = {
            (m.frequency_hz, m.sigma, m.amp, m.t_on): m
            for m in modes
            if m.fitted and m.ok and m.amp != 0
        }
        if state is None:
            return self.x - self.synthesise(list(wanted.values())), {"models": wanted}
        held = state["models"]
        gone = [m for key, m in held.items() if key not in wanted]
        new = [m for key, m in wanted.items() if key not in held]
        out = state["residual"]
        self.synthesise(gone, out, +1.0)
        self.synthesise(new, out, -1.0)
        return out, {"models": wanted}

    def model_dft(
        self,
        m: Mode,
        band: Band,
        span: tuple[int, int],
        sigma: float,
        frequency_hz: float,
        amp: complex,
        derivative: bool = False,
    ):
        """DFT (length npad) at the band's bins of amp exp(s (n - t_on fs)), n in the span.

        Only the positive-frequency half of the (real) model: its mirror image is at
        least two cutoffs away and filtered out. With ``derivative``, also returns
        the derivative with respect to the complex rate -sigma + 2j pi f (1/s).
        """
        n_on, count = span
        if count <= 0:
            zero = np.zeros(band.k.size, dtype=np.complex128)
            return (zero, zero) if derivative else zero
        fs, npad = self.fs, self.npad
        s = complex(-sigma, 2.0 * math.pi * frequency_hz) / fs
        # u = s - 2j pi k / npad with the phase reduced near zero for precision;
        # the sum over the span is geometric: expm1(count u) / expm1(u)
        u = (-sigma / fs) + 2j * math.pi * (frequency_hz / fs - band.k / npad)
        den = np.expm1(u)
        num = np.expm1(count * u)
        tiny = np.abs(count * u) < 1e-4
        safe = np.where(tiny, 1.0, den)
        geo = np.where(tiny, count + 0.5 * count * (count - 1) * u, num / safe)
        phase0 = np.exp(-2j * math.pi * (np.mod(band.k * n_on, npad) / npad))
        offset = n_on - m.t_on * fs
        pre = amp * np.exp(s * offset) * phase0
        value = pre * geo
        if not derivative:
            return value
        # d geo / du = sum p exp(p u) = (count exp(count u) - geo exp(u)) / expm1(u)
        c = float(count)
        dgeo = np.where(
            tiny,
            0.5 * c * (c - 1.0) + c * (c - 1.0) * (2.0 * c - 1.0) / 6.0 * u,
            (c * (num + 1.0) - geo * (den + 1.0)) / safe,
        )
        return value, (value * offset + pre * dgeo) / fs

    def skip(self, cutoff_hz: float, t_on: float) -> float:
        """What the fits leave out after a partial's onset (the strike itself), s."""
        return min(0.5 / cutoff_hz, 0.005, 0.1 * (self.duration - t_on))

    # -- the first estimate: a ladder of decay rates ------------------------------------
    def initial_fit(self, m: Mode, spec: np.ndarray) -> Mode:
        """First estimate of a partial at its candidate frequency.

        The partial is taken to start with the sound; for each of a ladder of decay
        rates the complex amplitude that best fits the band's envelope follows by
        linear least squares, and the best decay rate wins. Gauss-Newton then
        refines frequency, decay and amplitude together.

        Every partial not yet modelled leaves, through the low-pass, a pulse at the
        onset in this band (the skirt of its sudden start); two nuisance columns,
        the low-pass's impulse response at the onset and its derivative, take that
        up, so that it does not pass for a fast decay.
        """
        band = self.band(m.centre_hz, m.cutoff_hz)
        t = band.t
        sel = t >= self.t0 + self.skip(m.cutoff_hz, self.t0)
        if np.count_nonzero(sel) < MIN_FIT_POINTS + 2:
            return m.copy(ok=False)
        slowest = 0.3 / max(self.duration - self.t0, 1e-9)
        # from nearly steady to three cycles within the T60
        fastest = min(4.0 * math.pi * m.cutoff_hz, LN1000 * m.centre_hz / 3.0)
        fastest = max(fastest, 2.0 * slowest)
        sigmas = np.concatenate(([0.0], np.geomspace(slowest, fastest, 16)))
        impulse = np.exp(-2j * math.pi * (np.mod(band.k * self.n0, self.npad) / self.npad))
        env = self.envelopes(
            band, np.stack([self.band_values(spec, band), impulse, impulse * band.m])
        )[:, sel]
        d, nuisance = env[0], env[1:].T
        # take the nuisance out of the data and of every column (orthogonal projection)
        q, _ = np.linalg.qr(nuisance)
        d = d - q @ (q.conj().T @ d)
        tt = t[sel]
        carrier = np.exp(2j * math.pi * (m.centre_hz - band.f_bin) * tt)
        cols = np.exp(-np.outer(tt - self.t0, sigmas)) * carrier[:, None]
        cols = cols - q @ (q.conj().T @ cols)
        power = np.sum(np.abs(cols) ** 2, axis=0)
        inner = cols.conj().T @ d
        score = np.abs(inner) ** 2 / np.maximum(power, 1e-300)
        k = int(np.argmax(score))
        if not (score[k] > 0 and power[k] > 0):
            return m.copy(ok=False)
        amp = complex(inner[k] / power[k]) * complex(np.exp(2j * math.pi * m.centre_hz * self.t0))
        return m.copy(
            frequency_hz=m.centre_hz,
            sigma=float(sigmas[k]),
            amp=amp,
            t_on=self.t0,
            fitted=True,
            ok=True,
        )

    # -- Gauss-Newton on the band-limited residual ----------------------------------------
    def newton_step(self, m: Mode, spec: np.ndarray, neighbours: list[Mode]) -> Mode:
        """One Gauss-Newton step of a partial's model against the residual in its band.

        The model's own spectrum goes through the same band extraction and low-pass
        as the residual, so the filter biases nothing: this minimises
        sum |LPF(residual + model_old - model_new)|^2 over the partial's stretch.
        The nearest partials on either side take part in the least-squares solve
        (only this partial is updated), so that what is left of their errors in
        this band is not mistaken for this partial's.
        """
        band = self.band(m.centre_hz, m.cutoff_hz)
        t = band.t
        span = self.span(m)
        spectra = [self.band_values(spec, band)]
        for mode in [m, *neighbours]:
            sp = span if mode is m else self.span(mode)
            # d model / d log(amp) is the model itself; and d model / d(-sigma + 2j pi f)
            spectra += self.model_dft(
                mode, band, sp, mode.sigma, mode.frequency_hz, mode.amp, derivative=True
            )
        env = self.envelopes(band, np.stack(spectra))
        # the stretch: from just after the onset to 100 dB down (or the end)
        skip = self.skip(m.cutoff_hz, m.t_on)
        t_end = self.duration
        if m.sigma > 0:
            t_end = min(t_end, m.t_on + (100.0 / _DB_PER_NEPER) / m.sigma)
        sel = (t >= m.t_on + skip) & (t <= t_end)
        if np.count_nonzero(sel) < MIN_FIT_POINTS:
            sel = t >= m.t_on
            if np.count_nonzero(sel) < MIN_FIT_POINTS:
                return m.copy(ok=False)
        env = env[:, sel]
        ds, a1 = env[0], env[1]
        target = ds + a1
        energy = float(np.vdot(target, target).real)
        obj0 = float(np.vdot(ds, ds).real)
        if not energy > 0:
            return m.copy(ok=False)
        cols = env[1:].T
        # columns of neighbours that do not reach this band only spoil the conditioning
        norms = np.sqrt(np.sum(np.abs(cols) ** 2, axis=0))
        use = np.ones(cols.shape[1], dtype=bool)
        use[2:] = norms[2:] > 1e-9 * max(norms[0], 1e-300)
        try:
            sol, *_ = np.linalg.lstsq(cols[:, use], ds, rcond=1e-12)
        except np.linalg.LinAlgError:
            return m.copy(ok=False)
        da, dr = complex(sol[0]), complex(sol[1])
        if not (np.isfinite(da) and np.isfinite(dr)):
            return m.copy(ok=False)
        # keep a step within reason: the frequency within the band, the decay modest
        limit_f = 2.0 * math.pi * 0.5 * m.cutoff_hz
        limit_s = 5.0 / max(self.duration - m.t_on, 1e-9) + 0.5 * abs(m.sigma)
        scale = min(1.0, limit_f / max(abs(dr.imag), 1e-300), limit_s / max(abs(dr.real), 1e-300))
        scale = min(scale, 3.0 / max(abs(da), 1e-300))
        da, dr = da * scale, dr * scale
        best = None
        for _ in range(8):
            sigma = m.sigma - dr.real
            freq = m.frequency_hz + dr.imag / (2.0 * math.pi)
            amp = m.amp * complex(np.exp(da))
            trial = self.envelope(band, self.model_dft(m, band, span, sigma, freq, amp))[sel]
            resid = target - trial
            obj = float(np.vdot(resid, resid).real)
            if obj <= obj0 * (1.0 + 1e-9):
                best = (sigma, freq, amp, obj)
                break
            da, dr = 0.5 * da, 0.5 * dr
        if best is None:
            coherence = max(0.0, 1.0 - obj0 / energy)
            # a model that explains nothing and cannot be improved is not a partial
            return m.copy(coherence=coherence, ok=coherence > 0.01)
        sigma, freq, amp, obj = best
        return m.copy(
            frequency_hz=freq, sigma=sigma, amp=amp, coherence=max(0.0, 1.0 - obj / energy), ok=True
        )
