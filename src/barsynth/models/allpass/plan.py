"""The plan of the all-pass waveguide's filters: the fitted band, and each filter's order,
delay and sign.

Each filter is ``sign x z^-D x`` a chain of all-pass sections ``x`` its loss. A filter only
has to match its target modulo ``2 pi`` (that leaves every wave at every point unchanged in
steady state); of the equivalent targets the plan takes the one that needs the least phase
from the chain below the band, which also decides the sign. Where both ends are of one kind at
the same distance from the two points, the loop is symmetric and both ends share one design
(so a point in the middle of it is an exact node of every other mode).

``allpass_order`` all-pass sections round the loop in all (both directions of the middle
counted) are shared so that each filter gets about as many sections per radian of phase.
The fitted band runs from ``BAND_BOTTOM`` x the first mode up to ``min(0.45 fs, 20 kHz)``,
or over fewer modes when the order cannot give each filter the phase it needs (one section
per ``pi``, with each filter's delay the longest that leaves it enough) or cannot give at
least one free parameter per mode, plus one (:func:`fitted_band`). A bar that needs fewer
sections gets fewer. After J. S. Abel and J. O. Smith, "Robust design of very high-order
allpass dispersion filters", Proc. DAFx 2006 (about one section per ``pi`` of phase).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .targets import Bar, Targets

BAND_TOP_FRACTION = 0.45  # of the sample rate
BAND_TOP_HZ = 20000.0
BAND_BOTTOM = 0.9  # the fitted band starts at this fraction of the first mode
LOWEST_FIRST_MODE_HZ = 1.0  # a bar whose first mode lies lower is refused
HIGHEST_FIRST_MODE = 0.8  # of the band's top: a bar whose first mode lies higher is refused


def band_top_hz(rate: float) -> float:
    """The top of the fitted band (Hz) at sample rate ``rate``."""
    return min(BAND_TOP_FRACTION * rate, BAND_TOP_HZ)


def first_mode_refusal(f_1: float, rate: float | None, *, youngs_modulus_pa: float, density_kg_m3: float,
                       length_m: float, thickness_m: float) -> str | None:
    """The one-line refusal of a bar whose first mode ``f_1`` (Hz) lies below
    :data:`LOWEST_FIRST_MODE_HZ` or, at sample rate ``rate`` (None: not checked), at or above
    :data:`HIGHEST_FIRST_MODE` of the fitted band's top; None for a bar the waveguide can fit."""
    if f_1 < LOWEST_FIRST_MODE_HZ:
        return (f"parameters length_m = {length_m:g}, thickness_m = {thickness_m:g} put the first mode at "
                f"{f_1:.3g} Hz; allowed: a bar whose first mode lies at or above {LOWEST_FIRST_MODE_HZ:g} Hz "
                "(shorter or thicker)")
    if rate is None or f_1 < HIGHEST_FIRST_MODE * band_top_hz(rate):
        return None
    top_hz = band_top_hz(rate)
    return (f"parameters length_m = {length_m:g}, thickness_m = {thickness_m:g}, youngs_modulus_pa = "
            f"{youngs_modulus_pa:g}, density_kg_m3 = {density_kg_m3:g} put the first mode at {f_1:.0f} Hz; "
            f"allowed: a bar whose first mode lies below {HIGHEST_FIRST_MODE * top_hz:.0f} Hz (the fitted band "
            f"ends at {top_hz:.0f} Hz at sample_rate {rate:g} Hz)")
SPARE_PHASE = 0.5 * math.pi  # phase each chain keeps for above the band (rad)
CAPACITY = (1.0, 1.0)  # free parameters (poles) needed per fitted mode, and in all besides


@dataclass
class Plan:
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


def band_grid(bar: Bar, w_lo: float, w_hi: float, per_pi: int = 8) -> np.ndarray:
    """Points uniformly spaced in lambda (so equally many per mode) from w_lo to w_hi."""
    l_lo, l_hi = float(bar.lam(w_lo)), float(bar.lam(w_hi))
    n = int(np.clip(per_pi * (l_hi - l_lo) / math.pi, 24, 600))
    return bar.w_of_lam(np.linspace(l_lo, l_hi, n))


def _options(plan: Plan, grid: np.ndarray, spare: float = SPARE_PHASE):
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


def _allocate(plans: list[Plan], grid: np.ndarray, order: int) -> bool:
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


def _ensure_delay(live: list[Plan], grid: np.ndarray) -> None:
    """The loop needs one sample of pure delay somewhere (the kernel starts each sample
    there): if no filter has one, give it to the filter with the most group delay."""
    if not live or any(p.delay >= 1 for p in live):
        return
    best = max(live, key=lambda p: float(np.min(np.diff(p.lag(grid)) / np.diff(grid))))
    best.delay = 1
    best.offset = int(math.ceil((-1e-9 - (float(best.lag(grid[:1])[0]) - grid[0])) / math.pi))


def _best_effort(plans: list[Plan], grid: np.ndarray, order: int) -> None:
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


def band_top(w_modes: np.ndarray, count: int, w_top: float) -> float:
    """Top of a band that holds the first ``count`` of ``w_modes`` (all below ``w_top``)."""
    if count >= w_modes.size:
        return w_top
    return min(w_top, math.sqrt(w_modes[count - 1] * w_modes[count]))


def fitted_band(plans: list[Plan], bar: Bar, order: int, w_lo: float, w_modes: np.ndarray, w_top: float,
                 most: int) -> int:
    """How many of the modes ``w_modes`` (those below ``w_top``), at most ``most``, the
    ``order`` sections can fit: enough phase (``_allocate``) and enough free parameters
    (``CAPACITY`` per mode); orders, delays and offsets of ``plans`` are set for it."""
    for count in range(min(most, w_modes.size), 0, -1):
        grid = band_grid(bar, w_lo, band_top(w_modes, count, w_top))
        if _allocate(plans, grid, order) and \
                sum(p.order for p in plans) >= CAPACITY[0] * count + CAPACITY[1]:
            return count
    _best_effort(plans, band_grid(bar, w_lo, band_top(w_modes, 1, w_top)), order)
    return 1


def make_plans(targets: Targets, losses: dict, a: float, b: float) -> list[Plan]:
    """The distinct filters to design; both ends as one when the loop is symmetric about
    the middle of the two points (the same kind of end at the same distance)."""

    def filter_lag(k, loss):
        if loss is None:
            return lambda w: targets.lags(w)[k]
        return lambda w: targets.lags(w)[k] - loss.lag(w)

    ident = b - a < 1e-9
    middle = Plan("middle", 2, filter_lag(1, losses["middle"]), identity=ident)
    symmetric = abs(a - (1.0 - b)) < 1e-12 and targets.psi[0] == targets.psi[1] and \
        targets.share[0] == targets.share[1]
    if symmetric:
        return [Plan("ends", 2, filter_lag(0, losses["ends"])), middle]
    return [Plan("end0", 1, filter_lag(0, losses["end0"])), middle, Plan("endL", 1, filter_lag(2, losses["endL"]))]


def first_turn(plans: list[Plan], targets: Targets, w_1: float) -> int:
    """How many times 2 pi the designed round trip's phase is at the first mode (from the
    targets and the chosen offsets, not from the fit)."""
    lags = targets.lags(np.array([w_1]))[:, 0]
    total = lags[0] + 2.0 * lags[1] + lags[2]
    total += sum(p.mult * (p.offset + p.offset % 2) * math.pi for p in plans)
    return int(round(total / (2.0 * math.pi)))
