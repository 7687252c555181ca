"""Design of the all-pass waveguide bar: dispersion chains, end reflections, losses.

Pure functions, numbers in, numbers out (barsynth spec 3.2; the model is
:mod:`barsynth.models.allpass`). Sources: S. A. Van Duyne and J. O. Smith, "A
simplified approach to modeling dispersion caused by stiffness in strings and
plates", Proc. ICMC 1994 (a waveguide whose unit delays become all-pass filters);
J. S. Abel and J. O. Smith, "Robust design of very high-order allpass dispersion
filters", Proc. DAFx 2006 (one pole pair per 2 pi of phase: the start of the fit
here); J. Rauhala and V. Välimäki, "Tunable dispersion filter design for piano
synthesis", IEEE Signal Processing Letters 13 (2006); G. Essl and P. R. Cook,
"Banded waveguides", Proc. ICMC 1999 (the comparison of the three bar models);
K. F. Graff, *Wave Motion in Elastic Solids* (1975), ch. 3 (bending waves: point
force on a beam, reflections at its ends).

The waveguide
-------------
A bending wave of angular frequency ``w`` travels with phase velocity
``v = sqrt(a w)``, ``a = sqrt(E I / (rho A))``, so over the bar's length it lags
``lambda(w) = L sqrt(w / a)`` radians; a mode of the uniform bar lies where
``lambda = lambda_n`` (:func:`barsynth.physics.lambdas`). The strike point and
the pick-up point split the bar at ``x_a <= x_b`` (fractions of the length) into
four filters around one loop::

    end0:   x_a -> 0 -> x_a    lag 2 x_a lambda + psi_0 + delta_0
    right:  x_a -> x_b         lag (x_b - x_a) lambda
    endL:   x_b -> L -> x_b    lag 2 (1 - x_b) lambda + psi_L + delta_L
    left:   x_b -> x_a         the same filter as ``right``

``psi`` is the phase lag of the travelling wave's reflection at an end:
``pi / 2`` (a factor ``-j``) at a free or a clamped end, ``pi`` at a pinned one
(Graff). ``delta`` folds in what the travelling waves miss, the near field: it is
the smooth function that is zero far from the ends' coupling and makes the round
trip ``2 lambda + psi_0 + psi_L + delta`` a multiple of ``2 pi`` exactly at every
``lambda_n``, so the modes fall where ``cos(lambda) cosh(lambda) = 1`` (and the
other characteristic equations) put them. It is large only for the first mode
of a cantilever (``lambda_1 = 1.875`` instead of ``pi / 2``).

Each filter is ``sign x z^-D x`` a chain of all-pass sections ``x`` its loss. A
filter only has to match its target modulo ``2 pi`` (that leaves every wave at every
point unchanged in steady state); of the equivalent targets the design takes the one
that needs the least phase from the chain below the band, which also decides the
sign. Where both ends are of one kind at the same distance from the two points, the
loop is symmetric and both ends share one design (so a point in the middle of it is
an exact node of every other mode).

The fit
-------
``allpass_order`` all-pass sections round the loop in all (both directions of the
middle counted), shared so that each filter gets about as many sections per radian
of phase. The fitted band runs from 0.9 x the first mode up to ``min(0.45 fs, 20
kHz)``, or over fewer modes when the order cannot give each filter the phase it
needs (one section per ``pi``, with each filter's delay the longest that leaves it
enough) or cannot give at least one free parameter per mode, plus one
(:func:`_fitted_band`). A bar that needs fewer sections gets fewer
(``AllpassDesign.order``). Each filter starts from the equation-error least-squares
all-pass of its target (Lang and Laakso 1994; one pole pair per ``2 pi`` of phase,
after Abel and Smith, if that is unstable), then all are refined together by
Levenberg-Marquardt on, in order of weight: every fitted mode's round-trip error
(10 per cent), the round trip's group delay there (100 per relative error: it sets
each mode's level and decay), each filter's phase at the modes (10 per radian: the
mode shapes at the strike and pick-up points) and between them (0.1 per radian, RMS).
If a mode is left more than 1 cent out (or its group delay 50 %), the top mode is
given up and the fit repeated (at most 5 times; the best attempt is kept).

Sections are second order (poles anywhere inside radius ``R_MAX``, reached through
``a2 = R^2 tanh u``, ``a1 = R (1 + tanh u) tanh v``) and one first-order section when
the order is odd, so every design is stable.

The rest
--------
* Loss: each filter holds its share (its length) of the round trip's loss, a gain
  and up to three first-order low shelves (minimum phase, gain below one at every
  frequency) fitted in relative terms so that mode n loses ``w_n tau_n / (2 q)``
  nepers per round trip of group delay ``tau_n``: ``T60_n = q ln(1000) / (pi f_n)``.
  The shelves' phase is part of the fit; they are redesigned for the group delays
  the fit gave and the fit refined (``LOSS_PASSES`` times).
* Strike: the force enters both directions through ``1 / (4 rho A v(w))`` (the
  travelling waves' share of a point force on an infinite bar; Graff), real poles
  every two octaves with zeros placed by least squares (within 0.15 dB over the
  band), times a fourth-order Butterworth high-pass at half the first mode.
* Pick-up: the sum of the two travelling waves, through the same high-pass. The
  two high-passes keep DC out (the loop has a pole there when its signs multiply
  to +1) and any of the loop's resonances below the first mode far down.

Signature::

    allpass_design(*, youngs_modulus_pa, density_kg_m3, length_m, thickness_m, width_m=0.04,
                   bc="free-free", allpass_order=16, q=300.0, sample_rate=48000.0,
                   strike_position=0.1, pickup_position=0.0) -> AllpassDesign

``AllpassDesign.modes`` is the report: one :class:`ModeFit` per resonance of the
loop from the first mode up to Nyquist, with the physics frequency, the model's,
their difference in cents, the target and the model's T60, the gain, and whether
it lies in the fitted band; ``AllpassDesign.spurious`` lists the loop's
resonances below the first mode with their (tiny) gains and T60s.

Examples
--------
>>> d = allpass_design(youngs_modulus_pa=69e9, density_kg_m3=2700.0, length_m=0.3,
...                    thickness_m=0.01, bc="clamped-free", allpass_order=16)
>>> [round(m.physics_hz, 1) for m in d.modes[:3]]
[90.7, 568.6, 1592.2]
>>> sum(m.fitted for m in d.modes), max(abs(m.cents) for m in d.modes if m.fitted) < 1.0
(8, True)
>>> [f.name for f in d.filters], d.order
(['end0', 'right', 'endL', 'left'], 16)
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from ...errors import ParameterError

__all__ = ["AllpassDesign", "Filter", "ModeFit", "allpass_design", "response"]

HALF_PI = 0.5 * math.pi
CENTS_PER_NEPER = 1200.0 / math.log(2.0)
END_LAG = {"free": HALF_PI, "clamped": HALF_PI, "pinned": math.pi}
"""Phase lag of a travelling bending wave's reflection at each kind of end (rad)."""
R_MAX = 0.99995  # largest pole radius of a dispersion section
BAND_TOP_FRACTION = 0.45  # of the sample rate
BAND_TOP_HZ = 20000.0
BAND_BOTTOM = 0.9  # the fitted band starts at this fraction of the first mode
HIGH_PASS_FRACTION = 0.5  # strike and pick-up high-passes: this fraction of the first mode
SPARE_PHASE = 0.5 * math.pi  # phase each chain keeps for above the band (rad)
CAPACITY = (1.0, 1.0)  # free parameters (poles) needed per fitted mode, and in all besides
MAX_CENTS, MAX_SLOPE_ERROR = 1.0, 0.5  # a fit worse than this at a mode gives up the band's top mode
MAX_RETRIES = 5
LOSS_PASSES = 2  # losses redesigned for the fitted group delays, and the fit refined, this often
PINK_SPACING = 4.0  # frequency ratio between the -3 dB/octave filter's poles
W_CENTS, W_SLOPE, W_AT_MODES, W_BETWEEN, W_ABOVE = 10.0, 100.0, 10.0, 0.1, 0.1  # weights of the fit
W_STAY = 1e-3  # a weak pull towards the starting poles, for parameters the modes leave free


@dataclass(frozen=True)
class Filter:
    """One of the loop's filters: ``sign x z^-delay x sections`` (general biquads).

    ``sections`` rows are ``b0 b1 b2 a1 a2`` (``a0 = 1``): the all-pass sections
    first, then the loss (one row). ``poles`` are the all-pass poles
    (one per pair or real pole).
    """

    name: str
    delay: int
    sign: float
    poles: tuple[complex, ...]
    sections: np.ndarray = field(repr=False)
    loss: "Loss | None" = None  # its share of the bar's loss (None: a zero-length filter)

    @property
    def order(self) -> int:
        return sum(1 if p.imag == 0.0 else 2 for p in self.poles)


@dataclass(frozen=True)
class ModeFit:
    """One resonance of the loop against the uniform bar's mode of the same number."""

    number: int
    physics_hz: float
    model_hz: float
    cents: float
    target_t60_s: float
    model_t60_s: float
    gain: float
    fitted: bool


@dataclass(frozen=True)
class AllpassDesign:
    """Everything the kernel needs, and the report of what it will do."""

    sample_rate: float
    bc: str
    requested_order: int
    band_hz: tuple[float, float]
    positions: tuple[float, float]
    strike_at_a: bool
    pickup_at_a: bool
    filters: tuple[Filter, Filter, Filter, Filter]  # end0, right, endL, left
    injection: np.ndarray = field(repr=False)  # force (N) -> wave (m/s): sections
    pickup: np.ndarray = field(repr=False)  # sum of the waves -> output: sections
    modes: tuple[ModeFit, ...] = ()
    spurious: tuple[tuple[float, float, float], ...] = ()  # (Hz, gain, T60 in s) below the first mode

    @property
    def order(self) -> int:
        """All-pass sections in the loop, both directions of the middle counted."""
        return sum(f.order for f in self.filters)


# -- phase of the pieces --------------------------------------------------------------
def _real_lag(p: np.ndarray, w: np.ndarray):
    """Lag (rad) of first-order all-passes with real poles ``p`` (shape (k, 1)), and d/dp."""
    c, s = np.cos(w), np.sin(w)
    return w + 2.0 * np.arctan2(p * s, 1.0 - p * c), 2.0 * s / (1.0 - 2.0 * p * c + p * p)


def _shelf_lag(b: float, c: float, w: np.ndarray) -> np.ndarray:
    """Lag (rad) of ``(1 + b z^-1) / (1 + c z^-1)``."""
    s, co = np.sin(w), np.cos(w)
    return np.arctan2(b * s, 1.0 + b * co) - np.arctan2(c * s, 1.0 + c * co)


def _shelf_loss(b: float, c: float, w: np.ndarray) -> np.ndarray:
    """``-ln |(1 + b z^-1) / (1 + c z^-1)|`` (nepers)."""
    co = np.cos(w)
    return 0.5 * (np.log1p(c * c + 2.0 * c * co) - np.log1p(b * b + 2.0 * b * co))


@dataclass(frozen=True)
class Loss:
    """A gain below one times first-order low shelves, each ``(1 + b z^-1) / (1 + c z^-1)``
    scaled to unit gain at DC: minimum phase, and below one at every frequency."""

    gain: float
    shelves: tuple[tuple[float, float], ...] = ()

    def nepers(self, w) -> np.ndarray:
        """``-ln |G(w)|``."""
        w = np.asarray(w, dtype=float)
        out = np.full(w.shape, -math.log(self.gain))
        for b, c in self.shelves:
            out = out + _shelf_loss(b, c, w) - math.log((1.0 + c) / (1.0 + b))
        return out

    def lag(self, w) -> np.ndarray:
        w = np.asarray(w, dtype=float)
        out = np.zeros(w.shape)
        for b, c in self.shelves:
            out = out + _shelf_lag(b, c, w)
        return out

    def rows(self) -> np.ndarray:
        """Biquad rows ``b0 b1 b2 a1 a2``: two shelves a row (the gain in the first)."""
        out = []
        for start in range(0, max(len(self.shelves), 1), 2):
            num, den, k = np.array([1.0]), np.array([1.0]), self.gain if start == 0 else 1.0
            for b, c in self.shelves[start:start + 2]:
                num, den, k = np.convolve(num, [1.0, b]), np.convolve(den, [1.0, c]), k * (1.0 + c) / (1.0 + b)
            num, den = np.pad(num, (0, 3 - num.size)), np.pad(den, (0, 3 - den.size))
            out.append([k * num[0], k * num[1], k * num[2], den[1], den[2]])
        return np.array(out)


def response(sections: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Complex frequency response of a cascade of biquad rows ``b0 b1 b2 a1 a2`` at ``w``."""
    z1 = np.exp(-1j * np.asarray(w, dtype=float))
    h = np.ones(z1.shape, dtype=complex)
    for b0, b1, b2, a1, a2 in np.asarray(sections, dtype=float).reshape(-1, 5):
        h *= (b0 + z1 * (b1 + z1 * b2)) / (1.0 + z1 * (a1 + z1 * a2))
    return h


# -- the bar's targets -----------------------------------------------------------------
@dataclass(frozen=True)
class _Bar:
    bending: float  # a = sqrt(E I / (rho A)), m^2/s
    length_m: float
    mass_kg: float
    bc: str
    sample_rate: float

    def lam(self, w):
        """Phase lag over the length of a travelling wave at ``w`` (rad/sample)."""
        return self.length_m * np.sqrt(np.asarray(w, dtype=float) * self.sample_rate / self.bending)

    def w_of_lam(self, lam):
        return (np.asarray(lam, dtype=float) / self.length_m) ** 2 * self.bending / self.sample_rate

    @property
    def ends(self) -> tuple[str, str]:
        left, right = self.bc.split("-")
        return left, right


def _smooth_steps(x: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Through ``(xs, ys)`` with zero slope at every point (raised-cosine steps), flat outside."""
    x = np.asarray(x, dtype=float)
    if xs.size == 1:
        return np.full(x.shape, ys[0])
    i = np.clip(np.searchsorted(xs, x) - 1, 0, xs.size - 2)
    s = np.clip((x - xs[i]) / (xs[i + 1] - xs[i]), 0.0, 1.0)
    return ys[i] + (ys[i + 1] - ys[i]) * 0.5 * (1.0 - np.cos(np.pi * s))


class _Targets:
    """The physical lag of each of the loop's filters (end0, middle, endL) at any ``w``."""

    def __init__(self, bar: _Bar, a: float, b: float, lam_top: float):
        from ...physics import lambdas

        self.bar, self.a, self.b = bar, a, b
        left, right = bar.ends
        self.psi = (END_LAG[left], END_LAG[right])
        count = max(2, int(lam_top / math.pi) + 3)
        self.lam_n = np.asarray(lambdas(bar.bc, count), dtype=float)
        rt = 2.0 * self.lam_n + self.psi[0] + self.psi[1]
        self.loop_count = np.round(rt / (2.0 * math.pi))
        self.delta_n = 2.0 * math.pi * self.loop_count - rt
        near = [0.0 if end == "pinned" else 1.0 for end in (left, right)]
        total = sum(near) or 1.0
        self.share = (near[0] / total, near[1] / total)

    def delta(self, w):
        return _smooth_steps(self.bar.lam(w), self.lam_n, self.delta_n)

    def lags(self, w) -> np.ndarray:
        """Shape (3, n): end0, middle, endL."""
        lam, d = self.bar.lam(w), self.delta(w)
        return np.stack([2.0 * self.a * lam + self.psi[0] + self.share[0] * d,
                         (self.b - self.a) * lam,
                         2.0 * (1.0 - self.b) * lam + self.psi[1] + self.share[1] * d])


# -- plan: band, orders, delays, signs ---------------------------------------------------
@dataclass
class _Plan:
    """What one distinct filter must do: ``lag(w)`` is the phase its sign, delay and
    chain must provide (the loss shelf's own lag already taken off)."""

    name: str
    mult: int  # 1 for an end, 2 for the middle (both directions)
    lag: Callable[[np.ndarray], np.ndarray]  # w (rad/sample) -> rad
    identity: bool = False
    order: int = 0
    delay: int = 0
    offset: int = 0  # the target is lag + offset * pi; the sign is (-1)^offset

    def chain_target(self, w, delay=None, offset=None):
        """The phase the all-pass chain must add to the sign and the delay (rad)."""
        d = self.delay if delay is None else delay
        c = self.offset if offset is None else offset
        return self.lag(w) + c * math.pi - d * np.asarray(w)

    def fit_target(self, w, w_hi: float) -> np.ndarray:
        """:meth:`chain_target` in the band; above it the bar's own continuation plus a
        smooth ramp to the chain's ``order pi`` at Nyquist where that fits, else a straight
        line to it (so no pole has to crowd the band's top)."""
        w = np.asarray(w, dtype=float)
        out = self.chain_target(np.minimum(w, w_hi))
        above = w > w_hi
        if above.any():
            end = self.order * math.pi
            at_top, at_nyquist = (float(v) for v in self.chain_target(np.array([w_hi, math.pi])))
            ramp = (w[above] - w_hi) / (math.pi - w_hi)
            if at_nyquist <= end:
                out[above] = self.chain_target(w[above]) + (end - at_nyquist) * ramp ** 2
            else:
                out[above] = at_top + (end - at_top) * ramp
        return out


def _grid(bar: _Bar, w_lo: float, w_hi: float, per_pi: int = 8) -> np.ndarray:
    """Points uniformly spaced in lambda (so equally many per mode) from w_lo to w_hi."""
    l_lo, l_hi = float(bar.lam(w_lo)), float(bar.lam(w_hi))
    n = int(np.clip(per_pi * (l_hi - l_lo) / math.pi, 24, 600))
    return bar.w_of_lam(np.linspace(l_lo, l_hi, n))


def _options(plan: _Plan, grid: np.ndarray, spare: float = SPARE_PHASE):
    """For every delay D from 0 to the largest the band allows: the offset that leaves
    the chain the least phase below the band, and the chain's phase at the band top."""
    lag = plan.lag(grid)
    group = np.diff(lag) / np.diff(grid)
    d_max = max(0, int(math.floor(group.min() - 1e-6)))
    delays = np.arange(d_max + 1)
    low = lag[0] - delays * grid[0]
    offsets = np.ceil((-1e-9 - low) / math.pi).astype(int)
    top = lag[-1] + offsets * math.pi - delays * grid[-1]
    needs = np.ceil((top + spare) / math.pi).astype(int)
    flat = np.ptp(lag) < 1e-9 and abs(low[0] + offsets[0] * math.pi) < 1e-9
    needs[0] = 0 if flat else needs[0]  # a sign alone (a pinned end at the point)
    return delays, offsets, top, needs


def _allocate(plans: list[_Plan], grid: np.ndarray, order: int) -> bool:
    """Share ``order`` sections among the filters; False if the band needs more."""
    live = [p for p in plans if not p.identity]
    opts = {p.name: _options(p, grid) for p in live}
    least = {p.name: int(opts[p.name][3][-1]) for p in live}  # with the longest delay
    most = {p.name: int(opts[p.name][3][0]) for p in live}  # with no delay
    if sum(p.mult * least[p.name] for p in live) > order:
        return False
    for p in live:
        p.order = least[p.name]
    budget = order - sum(p.mult * p.order for p in live)
    span = {p.name: max(float(opts[p.name][2][0]), 1e-9) for p in live}
    while True:
        can = [p for p in live if p.order < most[p.name] and p.mult <= budget]
        if not can:
            break
        best = max(can, key=lambda p: span[p.name] / max(p.order, 0.5))
        best.order += 1
        budget -= best.mult
    for p in live:
        delays, offsets, _, needs = opts[p.name]
        fits = needs <= p.order
        nyquist = p.lag(math.pi) + offsets * math.pi - delays * math.pi
        whole = fits & (nyquist <= p.order * math.pi)  # the bar's own continuation fits too
        k = int(np.flatnonzero(whole if whole.any() else fits)[0])  # the shortest such delay
        p.delay, p.offset = int(delays[k]), int(offsets[k])
    _ensure_delay(live, grid)
    return True


def _ensure_delay(live: list[_Plan], grid: np.ndarray) -> None:
    """The loop needs one sample of pure delay somewhere (the kernel starts each sample
    there): if no filter has one, give it to the filter with the most group delay."""
    if not live or any(p.delay >= 1 for p in live):
        return
    best = max(live, key=lambda p: float(np.min(np.diff(p.lag(grid)) / np.diff(grid))))
    best.delay = 1
    best.offset = int(math.ceil((-1e-9 - (float(best.lag(grid[:1])[0]) - grid[0])) / math.pi))


def _best_effort(plans: list[_Plan], grid: np.ndarray, order: int) -> None:
    """Too few sections for even the lowest band: give them to the filters that need
    the most phase; a filter without one is a delay and a sign, as close as can be."""
    live = sorted((p for p in plans if not p.identity), key=lambda p: -float(np.ptp(p.lag(grid))))
    budget = order
    for p in live:
        delays, offsets, top, needs = _options(p, grid)
        p.order = min(int(needs[-1]), budget // p.mult)
        budget -= p.mult * p.order
        fits = np.flatnonzero(needs <= p.order)
        if fits.size:
            k = int(fits[0])
            p.delay, p.offset = int(delays[k]), int(offsets[k])
            continue
        lag = p.lag(grid)
        errors = []
        for d in range(int(delays[-1]) + 2):
            rest = lag - d * grid
            c = int(np.round(-rest.mean() / math.pi))
            errors.append((float(np.sum((rest + c * math.pi) ** 2)), d, c))
        _, p.delay, p.offset = min(errors)
    _ensure_delay(live, grid)


def _band_top(w_modes: np.ndarray, count: int, w_top: float) -> float:
    """Top of a band that holds the first ``count`` of ``w_modes`` (all below ``w_top``)."""
    if count >= w_modes.size:
        return w_top
    return min(w_top, math.sqrt(w_modes[count - 1] * w_modes[count]))


def _fitted_band(plans: list[_Plan], bar: _Bar, order: int, w_lo: float, w_modes: np.ndarray, w_top: float,
                 most: int) -> int:
    """How many of the modes ``w_modes`` (those below ``w_top``), at most ``most``, the
    ``order`` sections can fit: enough phase (``_allocate``) and enough free parameters
    (``CAPACITY`` per mode); orders, delays and offsets of ``plans`` are set for it."""
    for count in range(min(most, w_modes.size), 0, -1):
        grid = _grid(bar, w_lo, _band_top(w_modes, count, w_top))
        if _allocate(plans, grid, order) and \
                sum(p.order for p in plans) >= CAPACITY[0] * count + CAPACITY[1]:
            return count
    _best_effort(plans, _grid(bar, w_lo, _band_top(w_modes, 1, w_top)), order)
    return 1


# -- fitting -------------------------------------------------------------------------------
def _levenberg_marquardt(fun, x0: np.ndarray, iterations: int = 80) -> np.ndarray:
    """Minimise ``|r(x)|^2`` where ``fun(x) = (r, J)``; a few dozen damped Gauss-Newton steps."""
    x = np.asarray(x0, dtype=float).copy()
    r, jac = fun(x)
    cost = float(r @ r)
    mu = 1e-3
    for _ in range(iterations):
        jtj, g = jac.T @ jac, jac.T @ r
        scale = np.diag(jtj) + 1e-12
        try:
            step = np.linalg.solve(jtj + mu * np.diag(scale), -g)
        except np.linalg.LinAlgError:
            mu *= 10.0
            continue
        r_new, jac_new = fun(x + step)
        new = float(r_new @ r_new)
        if np.isfinite(new) and new < cost:
            done = cost - new < 1e-9 * cost
            x, r, jac, cost = x + step, r_new, jac_new, new
            mu = max(mu * 0.3, 1e-9)
            if done:
                break
        else:
            mu *= 5.0
            if mu > 1e8:
                break
    return x


def _numeric_jacobian(residual):
    def fun(x):
        r = residual(x)
        jac = np.empty((r.size, x.size))
        for i in range(x.size):
            h = 1e-6 * max(1.0, abs(x[i]))
            dx = x.copy()
            dx[i] += h
            jac[:, i] = (residual(dx) - r) / h
        return r, jac
    return fun


class _Chain:
    """The all-pass sections of one filter as free parameters. A second-order section
    ``(a2 + a1 z^-1 + z^-2) / (1 + a1 z^-1 + a2 z^-2)`` is reached through
    ``a2 = R^2 tanh(u)``, ``a1 = R (1 + tanh(u)) tanh(v)`` (any pair of real or complex
    poles inside radius ``R = R_MAX``); an odd order adds one first-order section with
    its pole at ``R tanh(u)``."""

    def __init__(self, order: int):
        self.pairs, self.reals = divmod(order, 2)
        self.size = 2 * self.pairs + self.reals

    def encode(self, a1, a2, p) -> np.ndarray:
        """Parameters of pairs with denominators ``1 + a1 z^-1 + a2 z^-2`` and real poles ``p``."""
        b2 = np.clip(np.asarray(a2, dtype=float) / R_MAX ** 2, -0.999999, 0.999999)
        b1 = np.asarray(a1, dtype=float) / R_MAX
        x = np.concatenate([np.arctanh(b2), np.arctanh(np.clip(b1 / (1.0 + b2), -0.999999, 0.999999))])
        if self.reals:
            x = np.append(x, np.arctanh(np.clip(np.asarray(p, dtype=float) / R_MAX, -0.999999, 0.999999)))
        return x

    def from_poles(self, poles: np.ndarray) -> np.ndarray | None:
        """Parameters for the given poles (conjugates paired, real ones paired up, one left
        over when the order is odd), or None if one lies outside radius ``R_MAX``."""
        poles = np.asarray(poles, dtype=complex)
        if poles.size != 2 * self.pairs + self.reals or np.any(np.abs(poles) >= R_MAX):
            return None
        upper = poles[poles.imag > 1e-12]
        reals = np.sort(poles[np.abs(poles.imag) <= 1e-12].real)
        a1 = list(-2.0 * upper.real)
        a2 = list(np.abs(upper) ** 2)
        left = reals[:self.reals]
        for p1, p2 in zip(reals[self.reals::2], reals[self.reals + 1::2]):
            a1.append(-(p1 + p2))
            a2.append(p1 * p2)
        if len(a1) != self.pairs:
            return None
        return self.encode(np.array(a1), np.array(a2), left)

    def coefficients(self, x: np.ndarray):
        """``a1, a2`` of each pair and the real poles."""
        k = self.pairs
        t_u, t_v = np.tanh(x[:k]), np.tanh(x[k:2 * k])
        return R_MAX * (1.0 + t_u) * t_v, R_MAX ** 2 * t_u, R_MAX * np.tanh(x[2 * k:])

    def lag(self, x: np.ndarray, w: np.ndarray, unit: tuple[np.ndarray, np.ndarray] | None = None):
        """Lag at ``w`` (rad) and its Jacobian in ``x``; ``unit`` = ``(e^-jw, e^-2jw)`` if
        already at hand (the fit calls this hundreds of times on the same points)."""
        k = self.pairs
        a1, a2, p = self.coefficients(x)
        lag = np.zeros(w.shape)
        jac = np.zeros((w.size, self.size))
        if k:
            e1, e2 = unit if unit is not None else (np.exp(-1j * w), np.exp(-2j * w))
            den = 1.0 + a1[:, None] * e1 + a2[:, None] * e2
            lag += (2.0 * w + 2.0 * np.angle(den)).sum(axis=0)
            d_a1, d_a2 = 2.0 * (e1 / den).imag, 2.0 * (e2 / den).imag
            t_u, t_v = np.tanh(x[:k])[:, None], np.tanh(x[k:2 * k])[:, None]
            du, dv = 1.0 - t_u ** 2, 1.0 - t_v ** 2
            jac[:, :k] = (d_a2 * R_MAX ** 2 * du + d_a1 * R_MAX * t_v * du).T
            jac[:, k:2 * k] = (d_a1 * R_MAX * (1.0 + t_u) * dv).T
        if self.reals:
            real, d_p = _real_lag(p[:, None], w)
            lag += real.sum(axis=0)
            jac[:, 2 * k:] = (d_p * (R_MAX * (1.0 - np.tanh(x[2 * k:]) ** 2))[:, None]).T
        return lag, jac

    def poles(self, x: np.ndarray) -> tuple[complex, ...]:
        """One pole of each pair (both when they are real), then the real pole."""
        a1, a2, p = self.coefficients(x)
        out: list[complex] = []
        for c1, c2 in zip(a1, a2):
            roots = np.roots([1.0, c1, c2])
            if abs(roots[0].imag) > 0.0:
                out.append(complex(roots[0].real, abs(roots[0].imag)))
            else:
                out += [complex(float(roots[0].real), 0.0), complex(float(roots[1].real), 0.0)]
        return tuple(out) + tuple(complex(float(v), 0.0) for v in p)

    def rows(self, x: np.ndarray) -> np.ndarray:
        a1, a2, p = self.coefficients(x)
        pairs = [[c2, c1, 1.0, c1, c2] for c1, c2 in zip(a1, a2)]
        reals = [[-v, 1.0, 0.0, -v, 0.0] for v in p]
        return np.array(pairs + reals, dtype=float).reshape(-1, 5)


def _initial_poles(chain: _Chain, target, w_lo: float, w_hi: float, order: int) -> np.ndarray:
    """One pole pair per 2 pi of the target phase, at the frequency where the target
    passes the middle of its share, as wide as that share (after Abel & Smith)."""
    w = np.concatenate([np.linspace(0.0, w_lo, 200, endpoint=False), np.linspace(w_lo, w_hi, 2000),
                        np.linspace(w_hi, math.pi, 200)[1:]])
    lag = np.asarray(target(np.clip(w, w_lo, w_hi)), dtype=float)
    low, high = w < w_lo, w > w_hi
    lag[low] = lag[low] * np.sqrt(w[low] / w_lo)  # the bar's own law, down to 0 at DC
    top = float(target(np.array([w_hi]))[0])
    lag[high] = top + (order * math.pi - top) * (w[high] - w_hi) / (math.pi - w_hi)
    lag = np.maximum.accumulate(np.maximum(lag, 0.0))
    lag += np.linspace(0.0, 1e-9, lag.size)  # strictly increasing for the inverse

    def at(level):
        return float(np.interp(level, lag, w))

    base, p = 0.0, np.zeros(0)
    if chain.reals:
        half = max(at(0.5 * math.pi), 1e-4)
        t = math.tan(0.5 * half)
        p = np.array([(1.0 - t) / (1.0 + t)])
        base = math.pi
    levels = base + 2.0 * math.pi * np.arange(chain.pairs)
    theta = np.array([at(v + math.pi) for v in levels])
    width = np.array([at(v + 2.0 * math.pi) - at(v) for v in levels])
    r = np.clip(1.0 - 0.5 * width, 0.05, R_MAX * 0.999)
    theta = np.clip(theta, 1e-4, math.pi - 1e-4)
    return chain.encode(-2.0 * r * np.cos(theta), r * r, p)


def _equation_error_poles(target: np.ndarray, order: int, w: np.ndarray) -> np.ndarray:
    """Poles of the all-pass of ``order`` whose phase best matches ``target`` on ``w`` in the
    equation-error sense, reweighted towards the true phase error (Lang and Laakso, "Simple
    and robust method for the design of allpass filters using least-squares phase error
    criterion", IEEE Trans. CAS II 41, 1994)."""
    beta = 0.5 * (target - order * w)
    k = np.arange(1, order + 1)
    basis = np.sin(np.outer(w, k) + beta[:, None])
    rhs = -np.sin(beta)
    weight = np.ones(w.size)
    coeffs = np.zeros(order)
    for _ in range(4):
        sq = np.sqrt(weight)
        coeffs = np.linalg.lstsq(basis * sq[:, None], rhs * sq, rcond=None)[0]
        den = 1.0 + np.exp(-1j * np.outer(w, k)) @ coeffs
        weight = 1.0 / np.maximum(np.abs(den) ** 2, 1e-12)
        weight /= weight.mean()
    return np.roots(np.concatenate([[1.0], coeffs]))


def _start(chain: _Chain, plan: _Plan, target: np.ndarray, w: np.ndarray, w_lo: float, w_hi: float) -> np.ndarray:
    """Starting parameters of one filter: the equation-error fit, or (if that is unstable)
    one pole pair per 2 pi of phase."""
    start = chain.from_poles(_equation_error_poles(target, plan.order, w)) if plan.order else None
    return start if start is not None else _initial_poles(chain, plan.chain_target, w_lo, w_hi, plan.order)


def _fit(plans: list[_Plan], bar: _Bar, w_modes: np.ndarray, lam_modes: np.ndarray, w_lo: float, w_hi: float,
         warm: list[np.ndarray] | None = None):
    """Refine every filter's poles together (see the module notes for the weights), from
    ``warm`` (parameters of an earlier fit) if given. Returns each filter's parameters, and
    each mode's round-trip error in cents and the relative error of the round trip's group
    delay there."""
    grid, above = _grid(bar, w_lo, w_hi), np.linspace(w_hi, math.pi, 42)[1:-1]
    m, n_grid, n_above = w_modes.size, grid.size, above.size
    h = 1e-5 * w_modes
    points = np.concatenate([grid, above, w_modes, w_modes - h, w_modes + h])
    n_free = n_grid + n_above
    targets = [p.fit_target(points, w_hi) for p in plans]
    chains = [_Chain(p.order) for p in plans]
    x0 = warm or [_start(chain, plan, target[:n_free], points[:n_free], w_lo, w_hi)
                  for chain, plan, target in zip(chains, plans, targets)]
    cuts = np.cumsum([0] + [c.size for c in chains])
    weights = np.concatenate([np.full(n_grid, W_BETWEEN / math.sqrt(n_grid)),
                              np.full(n_above, W_ABOVE / math.sqrt(n_above)), np.full(m, W_AT_MODES)])
    to_cents = -CENTS_PER_NEPER / lam_modes
    slope = W_SLOPE * w_modes / lam_modes / (2.0 * h)  # relative error of the round trip's group delay
    to_slope = 0.0 * slope  # first the phase alone (a smoother problem), then with the slopes

    unit = (np.exp(-1j * points), np.exp(-2j * points))

    def fun(x):
        blocks, jacs = [], []
        loop = np.zeros(3 * m)
        loop_jac = np.zeros((3 * m, x.size))
        for k, (chain, plan, target) in enumerate(zip(chains, plans, targets)):
            lag, jac = chain.lag(x[cuts[k]:cuts[k + 1]], points, unit)
            err = lag - target
            rows = np.zeros((points.size, x.size))
            rows[:, cuts[k]:cuts[k + 1]] = jac
            weight = math.sqrt(plan.mult) * weights
            blocks.append(weight * err[:n_free + m])
            jacs.append(weight[:, None] * rows[:n_free + m])
            loop += plan.mult * err[n_free:]
            loop_jac += plan.mult * rows[n_free:]
        blocks += [W_CENTS * to_cents * loop[:m], to_slope * (loop[2 * m:] - loop[m:2 * m]),
                   W_STAY * (x - start)]
        jacs += [W_CENTS * to_cents[:, None] * loop_jac[:m],
                 to_slope[:, None] * (loop_jac[2 * m:] - loop_jac[m:2 * m]), W_STAY * np.eye(x.size)]
        return np.concatenate(blocks), np.vstack(jacs)

    x = np.concatenate(x0) if cuts[-1] else np.zeros(0)
    start = x.copy()
    if x.size:
        if warm is None:
            x = _levenberg_marquardt(fun, x, iterations=60)
        to_slope = slope
        x = _levenberg_marquardt(fun, x, iterations=30 if warm else 80)
    r, _ = fun(x)
    r = r[:r.size - x.size]
    cents = r[-2 * m:-m] / W_CENTS
    slope_error = r[-m:] / W_SLOPE
    return [x[cuts[k]:cuts[k + 1]] for k in range(len(chains))], cents, slope_error


MAX_SHELF_NEPERS = 10.0  # deepest loss of one shelf (at Nyquist) or of the gain
SHELF_POLES = (-0.995, -0.98, -0.95, -0.9, -0.8, -0.6, -0.3, 0.0, 0.4)  # starting points of the loss fit


def _shelf(c: float, nyquist_nepers: float) -> tuple[float, float]:
    """``(b, c)`` of the unit-DC shelf with pole ``-c`` that loses ``nyquist_nepers`` at Nyquist."""
    kappa = math.exp(-nyquist_nepers) * (1.0 - c) / (1.0 + c)  # (1 - b) / (1 + b)
    return (1.0 - kappa) / (1.0 + kappa), c


def _design_loss(w_modes: np.ndarray, loss_modes: np.ndarray) -> Loss:
    """The :class:`Loss` whose nepers best match ``loss_modes`` at ``w_modes`` in relative
    terms: a gain and up to three shelves (a gain alone for one mode, one shelf for two,
    two for three to six, three for more).
    Start: for small losses each shelf adds (nearly) a fixed shape times its depth, so
    every pair of shelf poles from ``SHELF_POLES`` gives a linear least-squares problem;
    the best is refined by Levenberg-Marquardt on the exact losses."""
    count = 0 if w_modes.size == 1 else 1 if w_modes.size == 2 else 2 if w_modes.size < 7 else 3
    if count == 0:
        return Loss(math.exp(-float(loss_modes[0])))

    def make(x):  # x = [sqrt(DC nepers), (sqrt(Nyquist nepers), atanh(c)) per shelf]
        shelves = tuple(_shelf(0.999 * math.tanh(x[2 + 2 * k]), min(x[1 + 2 * k] ** 2, MAX_SHELF_NEPERS))
                        for k in range(count))
        return Loss(math.exp(-min(x[0] ** 2, MAX_SHELF_NEPERS)), shelves)

    def residual(x):
        return make(x).nepers(w_modes) / loss_modes - 1.0

    shapes = {c: Loss(1.0, (_shelf(c, 1e-6),)).nepers(w_modes) / 1e-6 for c in SHELF_POLES}
    best = None
    for poles in itertools.combinations(SHELF_POLES, count):
        basis = np.column_stack([np.ones(w_modes.size)] + [shapes[c] for c in poles]) / loss_modes[:, None]
        coef = np.maximum(np.linalg.lstsq(basis, np.ones(w_modes.size), rcond=None)[0], 1e-12)
        cost = float(np.sum((basis @ coef - 1.0) ** 2))
        if best is None or cost < best[0]:
            best = (cost, coef, poles)
    _, coef, poles = best
    x0 = [math.sqrt(coef[0])]
    for depth, c in zip(coef[1:], poles):
        x0 += [math.sqrt(depth), math.atanh(c / 0.999)]
    return make(_levenberg_marquardt(_numeric_jacobian(residual), np.array(x0), iterations=60))


# -- filters around the loop, and the strike and pick-up filters ---------------------------------
def _make_filter(name: str, plan: _Plan, chain: _Chain, x: np.ndarray, loss: Loss | None) -> Filter:
    poles = chain.poles(x) if plan.order else ()
    rows = chain.rows(x) if plan.order else np.zeros((0, 5))
    if loss is not None:
        rows = np.vstack([rows, loss.rows()])
    return Filter(name, plan.delay, -1.0 if plan.offset % 2 else 1.0, poles, rows, loss)


def _high_pass(w_c: float) -> np.ndarray:
    """Fourth-order Butterworth high-pass at ``w_c`` (rad/sample), bilinear with prewarping."""
    rows = []
    cw, sw = math.cos(w_c), math.sin(w_c)
    for q in (0.5411961001461969, 1.3065629648763766):
        alpha = sw / (2.0 * q)
        a0 = 1.0 + alpha
        b0 = 0.5 * (1.0 + cw) / a0
        rows.append([b0, -2.0 * b0, b0, -2.0 * cw / a0, (1.0 - alpha) / a0])
    return np.array(rows)


def _pink(w_from: float, w_to: float) -> np.ndarray:
    """Magnitude ``w^-1/2`` (-3 dB per octave) from ``w_from`` to ``w_to`` (rad/sample):
    real poles every ``PINK_SPACING`` in frequency (matched z: radius ``exp(-w_pole)``),
    a real zero after each, placed by least squares on the log magnitude (the bilinear
    or matched-z zeros alone bend away near Nyquist); unit gain at ``w_from``."""
    poles = [w_from / PINK_SPACING]
    while poles[-1] < w_to:
        poles.append(poles[-1] * PINK_SPACING)
    p = np.exp(-np.array(poles))
    w = np.geomspace(w_from, w_to, 8 * len(poles) + 8)
    z1 = np.exp(-1j * w)
    want = -0.5 * np.log(w)

    def log_gain(zeros):
        return (np.log(np.abs(1.0 - np.outer(z1, zeros))).sum(axis=1)
                - np.log(np.abs(1.0 - np.outer(z1, p))).sum(axis=1))

    def residual(x):
        err = log_gain(np.tanh(x)) - want
        return err - err.mean()

    x0 = np.arctanh(np.exp(-np.array(poles) * math.sqrt(PINK_SPACING)))
    zeros = np.tanh(_levenberg_marquardt(_numeric_jacobian(residual), x0, iterations=40))
    rows = np.column_stack([np.ones(p.size), -zeros, np.zeros(p.size), -p, np.zeros(p.size)])
    rows[0, :3] /= abs(complex(response(rows, np.array([w_from]))[0]))
    return rows


def _injection(bar: _Bar, w_1: float, w_top: float, w_modes: np.ndarray) -> np.ndarray:
    """Force (N per sample) to travelling-wave velocity (m/s): ``1 / (4 rho A v(w))``
    from just below the first mode to ``w_top``, scaled to match at the fitted modes (least
    squares in dB), then high-passed."""
    rows = _pink(BAND_BOTTOM * w_1, w_top)
    wanted = bar.length_m / (4.0 * bar.mass_kg * np.sqrt(bar.bending * w_modes * bar.sample_rate))
    scale = math.exp(float(np.mean(np.log(wanted / np.abs(response(rows, w_modes))))))
    rows[0, :3] *= scale
    return np.vstack([rows, _high_pass(HIGH_PASS_FRACTION * w_1)])


# -- what the designed loop does ------------------------------------------------------------
def _filter_lag(f: Filter, w: np.ndarray) -> np.ndarray:
    """Lag (rad) of one loop filter, continuous in ``w`` (sign, delay, sections, loss)."""
    w = np.asarray(w, dtype=float)
    lag = (math.pi if f.sign < 0 else 0.0) + f.delay * w
    e1, e2 = np.exp(-1j * w), np.exp(-2j * w)
    for _, _, b2, a1, a2 in f.sections[:len(f.sections) - (0 if f.loss is None else len(f.loss.rows()))]:
        if b2 == 1.0:  # second-order all-pass
            lag = lag + 2.0 * w + 2.0 * np.angle(1.0 + a1 * e1 + a2 * e2)
        else:  # first-order all-pass
            lag = lag + w + 2.0 * np.angle(1.0 + a1 * e1)
    if f.loss is not None:
        lag = lag + f.loss.lag(w)
    return lag


def _loop_lag(filters, w: np.ndarray) -> np.ndarray:
    return sum(_filter_lag(f, w) for f in filters)


def _loop_loss(filters, w: np.ndarray) -> np.ndarray:
    """``-ln |T(w)|`` of the round trip (nepers): the shelves'."""
    return sum(f.loss.nepers(w) for f in filters if f.loss is not None)


def _crossings(filters, w_from: float) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (rad/sample) above ``w_from`` where the loop's lag is a multiple of
    2 pi, and those multiples."""
    w = np.linspace(math.sqrt(w_from), math.sqrt(math.pi), 20000) ** 2
    lag = _loop_lag(filters, w)
    turns = np.arange(math.floor(lag[0] / (2 * math.pi)) + 1, math.floor(lag[-1] / (2 * math.pi)) + 1)
    found = np.interp(2 * math.pi * turns, lag, w)
    for _ in range(3):  # secant refinement on the exact lag
        h = 1e-7 * np.maximum(found, 1e-6)
        lag_at = _loop_lag(filters, found)
        slope = (_loop_lag(filters, found + h) - lag_at) / h
        found = np.clip(found - (lag_at - 2 * math.pi * turns) / slope, w_from, math.pi)
    return found, turns


def _rails(design_filters, strike_at_a: bool, pickup_at_a: bool, w: np.ndarray):
    """Pick-up sum of the waves per unit wave injected at the strike point (complex, at
    ``w``), and the round trip ``T``."""
    s = [f.sign * np.exp(-1j * f.delay * w) * response(f.sections, w) for f in design_filters]
    ia, ib = (1.0, 0.0) if strike_at_a else (0.0, 1.0)
    pa, pb = (1.0, 0.0) if pickup_at_a else (0.0, 1.0)
    loop = s[0] * s[1] * s[2] * s[3]
    x3 = (s[2] * s[1] * s[0] * ia + s[2] * s[1] * ia + s[2] * ib + ib) / (1.0 - loop)
    x0 = s[3] * x3 + ia
    x1 = s[0] * x0 + ia
    x2 = s[1] * x1 + ib
    y0, y1, y2, y3 = s[0] * x0, s[1] * x1, s[2] * x2, s[3] * x3
    return pa * (y0 + y3 + ia) + pb * (y1 + y2 + ib), loop


def _resonances(design_filters, injection, pickup, strike_at_a, pickup_at_a, w_from, bar):
    """Each resonance of the loop above ``w_from``: (w, turns, T60 in s, gain), where the
    gain is the velocity amplitude per unit impulse times the bar's mass (for a real bar:
    the product of the two mode shapes)."""
    w, turns = _crossings(design_filters, w_from)
    h = 1e-6 * w
    group = (_loop_lag(design_filters, w + h) - _loop_lag(design_filters, w - h)) / (2 * h)
    loss = _loop_loss(design_filters, w)
    t60 = math.log(1000.0) * group / (np.maximum(loss, 1e-300) * bar.sample_rate)
    path, loop = _rails(design_filters, strike_at_a, pickup_at_a, w)
    numerator = path * (1.0 - loop)
    size = np.abs(numerator * response(injection, w) * response(pickup, w))
    gain = 2.0 * bar.mass_kg * bar.sample_rate * size / group * np.sign(numerator.real)
    return w, turns, t60, gain


# -- the design --------------------------------------------------------------------------------
def allpass_design(*, youngs_modulus_pa: float, density_kg_m3: float, length_m: float, thickness_m: float,
                   width_m: float = 0.04, bc: str = "free-free", allpass_order: int = 16, q: float = 300.0,
                   sample_rate: float = 48000.0, strike_position: float = 0.1,
                   pickup_position: float = 0.0) -> AllpassDesign:
    """Design the all-pass waveguide of a uniform bar (see the module notes).

    Parameters
    ----------
    youngs_modulus_pa, density_kg_m3 : float
        Young's modulus ``E`` (Pa) and density ``rho`` (kg/m^3).
    length_m, thickness_m, width_m : float
        The bar's length, thickness (bending direction) and width (m; the width
        only sets the mass, hence the level).
    bc : str
        Boundary conditions, one of :data:`barsynth.physics.BOUNDARY_CONDITIONS`.
    allpass_order : int
        All-pass sections in the loop in all (an upper limit: a bar that needs fewer
        gets fewer; see ``AllpassDesign.order``).
    q : float
        Quality factor of every mode: ``T60 = q ln(1000) / (pi f)``.
    sample_rate : float
        Hz.
    strike_position, pickup_position : float
        Fractions of the length, 0 to 1.

    Returns
    -------
    AllpassDesign
        Filters for the kernel, and ``modes``: each resonance against physics.

    Raises
    ------
    ParameterError
        If the first mode lies above the band that can be fitted at this sample
        rate, or the design cannot be built.
    """
    return _design(float(youngs_modulus_pa), float(density_kg_m3), float(length_m), float(thickness_m),
                   float(width_m), str(bc), int(allpass_order), float(q), float(sample_rate),
                   float(strike_position), float(pickup_position))


@lru_cache(maxsize=32)
def _design(e: float, rho: float, length: float, thickness: float, width: float, bc: str, order: int,
            q: float, rate: float, strike: float, pickup: float) -> AllpassDesign:
    from ...physics import bar_frequencies, bending_wave_constant

    bar = _Bar(bending_wave_constant(e, rho, thickness), length, rho * length * thickness * width, bc, rate)
    f_1 = float(bar_frequencies(youngs_modulus_pa=e, density_kg_m3=rho, length_m=length, thickness_m=thickness,
                                bc=bc, count=1)[0])
    top_hz = min(BAND_TOP_FRACTION * rate, BAND_TOP_HZ)
    if f_1 >= 0.8 * top_hz:
        raise ParameterError(
            f"parameters length_m = {length:g}, thickness_m = {thickness:g}, youngs_modulus_pa = {e:g}, "
            f"density_kg_m3 = {rho:g} put the first mode at {f_1:.0f} Hz; allowed: a bar whose first mode "
            f"lies below {0.8 * top_hz:.0f} Hz (the fitted band ends at {top_hz:.0f} Hz at sample_rate "
            f"{rate:g} Hz)")
    w_1, w_top = 2 * math.pi * f_1 / rate, 2 * math.pi * top_hz / rate
    a, b = sorted((strike, pickup))
    targets = _Targets(bar, a, b, float(bar.lam(math.pi)))
    w_all = bar.w_of_lam(targets.lam_n)
    below_top = w_all < w_top
    # each filter loses its share (its length) of lambda_n / (2 q) nepers per round trip
    round_trip = targets.lam_n[below_top] / (2.0 * q)
    losses = _losses(w_all[below_top], round_trip, a, b)
    plans = _plans(targets, losses, a, b)
    w_lo = BAND_BOTTOM * w_1
    count, xs, w_hi = _fit_band(plans, bar, order, w_lo, w_all[below_top], w_top, targets.lam_n)
    filters = _refine_losses(plans, targets, bar, xs, losses, w_all[below_top], count, (w_lo, w_hi), q, (a, b))
    injection = _injection(bar, w_1, w_top, w_all[:count])
    pickup_rows = _high_pass(HIGH_PASS_FRACTION * w_1)
    strike_at_a = strike <= pickup
    pickup_at_a = pickup <= strike
    modes, spurious = _report(filters, injection, pickup_rows, strike_at_a, pickup_at_a, bar, w_all, count,
                              _first_turn(plans, targets, w_all[0]), q)
    return AllpassDesign(rate, bc, order, (w_lo * rate / (2 * math.pi), w_hi * rate / (2 * math.pi)), (a, b),
                         strike_at_a, pickup_at_a, filters, injection, pickup_rows, modes, spurious)


def _refine_losses(plans, targets, bar, xs, losses, w_modes, count, band, q, points):
    """The filters, with their losses redesigned for the group delays the fit gave at the
    fitted modes and the fit refined for the losses' (slightly different) phase,
    ``LOSS_PASSES`` times."""
    def build(xs, losses):
        return _loop_filters({p.name: _make_filter(p.name, p, _Chain(p.order), x, losses[p.name])
                              for p, x in zip(plans, xs)})

    filters = build(xs, losses)
    fitted = w_modes[:count]  # the modes the loop has; above them its resonances are not the bar's
    for _ in range(LOSS_PASSES):
        losses = _losses(fitted, fitted * _group_delay(filters, fitted) / (2.0 * q), *points)
        for plan, again in zip(plans, _plans(targets, losses, *points)):
            plan.lag = again.lag
        xs = _fit(plans, bar, w_modes[:count], targets.lam_n[:count], *band, warm=xs)[0]
        filters = build(xs, losses)
    return filters


def _fit_band(plans, bar, order, w_lo, w_modes, w_top, lam_n):
    """Fit as many modes as the order allows; if the fit misses ``MAX_CENTS`` or
    ``MAX_SLOPE_ERROR`` at a mode, try again without the top mode (at most ``MAX_RETRIES``
    times) and keep the best attempt. Returns the number of fitted modes, the filters'
    parameters and the band's top (rad/sample); ``plans`` are left as fitted."""
    count, attempts = w_modes.size, []
    for _ in range(MAX_RETRIES):
        count = _fitted_band(plans, bar, order, w_lo, w_modes, w_top, count)
        w_hi = _band_top(w_modes, count, w_top)
        xs, cents, slope_error = _fit(plans, bar, w_modes[:count], lam_n[:count], w_lo, w_hi)
        misses = np.maximum(np.abs(cents) / MAX_CENTS, np.abs(slope_error) / MAX_SLOPE_ERROR)
        badness = float(misses.max())
        attempts.append((max(badness, 1.0), -count, [(p.order, p.delay, p.offset) for p in plans], xs, w_hi))
        if badness <= 1.0 or count == 1:
            break
        count -= 1
    _, minus_count, chosen, xs, w_hi = min(attempts, key=lambda attempt: attempt[:2])
    for plan, (order_k, delay_k, offset_k) in zip(plans, chosen):
        plan.order, plan.delay, plan.offset = order_k, delay_k, offset_k
    return -minus_count, xs, w_hi


def _losses(w_modes: np.ndarray, round_trip: np.ndarray, a: float, b: float) -> dict:
    """Each distinct filter's :class:`Loss`, its share of the round trip's being its length."""
    shares = {"end0": a, "middle": 0.5 * (b - a), "endL": 1.0 - b}
    shares["ends"] = shares["end0"]
    return {name: _design_loss(w_modes, share * round_trip) if share > 1e-9 else None
            for name, share in shares.items()}


def _group_delay(filters, w: np.ndarray) -> np.ndarray:
    """The loop's group delay (samples) at ``w``."""
    h = 1e-6 * w
    return (_loop_lag(filters, w + h) - _loop_lag(filters, w - h)) / (2.0 * h)


def _plans(targets: _Targets, losses: dict, a: float, b: float) -> list[_Plan]:
    """The distinct filters to design; both ends as one when the loop is symmetric about
    the middle of the two points (the same kind of end at the same distance)."""

    def filter_lag(k, loss):
        if loss is None:
            return lambda w: targets.lags(w)[k]
        return lambda w: targets.lags(w)[k] - loss.lag(w)

    ident = b - a < 1e-9
    middle = _Plan("middle", 2, filter_lag(1, losses["middle"]), identity=ident)
    symmetric = abs(a - (1.0 - b)) < 1e-12 and targets.psi[0] == targets.psi[1] and \
        targets.share[0] == targets.share[1]
    if symmetric:
        return [_Plan("ends", 2, filter_lag(0, losses["ends"])), middle]
    return [_Plan("end0", 1, filter_lag(0, losses["end0"])), middle, _Plan("endL", 1, filter_lag(2, losses["endL"]))]


def _loop_filters(made: dict) -> tuple[Filter, Filter, Filter, Filter]:
    """end0, right, endL, left: in the order a wave goes round."""
    def renamed(f, name):
        return Filter(name, f.delay, f.sign, f.poles, f.sections, f.loss)

    end0 = made.get("end0", made.get("ends"))
    end_l = made.get("endL", made.get("ends"))
    return (renamed(end0, "end0"), renamed(made["middle"], "right"), renamed(end_l, "endL"),
            renamed(made["middle"], "left"))


def _first_turn(plans: list[_Plan], targets: _Targets, w_1: float) -> int:
    """How many times 2 pi the designed round trip's phase is at the first mode (from the
    targets and the chosen offsets, not from the fit)."""
    lags = targets.lags(np.array([w_1]))[:, 0]
    total = lags[0] + 2.0 * lags[1] + lags[2]
    total += sum(p.mult * (p.offset + p.offset % 2) * math.pi for p in plans)
    return int(round(total / (2.0 * math.pi)))


def _report(filters, injection, pickup, strike_at_a, pickup_at_a, bar, w_all, count, first, q):
    """Each resonance against the bar's mode of the same number, and those below mode 1."""
    w, turns, t60, gain = _resonances(filters, injection, pickup, strike_at_a, pickup_at_a, 1e-4 * w_all[0], bar)
    to_hz = bar.sample_rate / (2 * math.pi)
    modes, spurious = [], []
    for wk, turn, t, g in zip(w, turns, t60, gain):
        n = int(turn) - first + 1
        if n < 1:
            spurious.append((float(wk * to_hz), float(g), float(t)))
            continue
        if n > w_all.size or wk >= math.pi:
            break
        f_phys = float(w_all[n - 1] * to_hz)
        modes.append(ModeFit(n, f_phys, float(wk * to_hz), float(1200 * math.log2(wk * to_hz / f_phys)),
                             q * math.log(1000.0) / (math.pi * f_phys), float(t), float(g), n <= count))
    return tuple(modes), tuple(spurious)
