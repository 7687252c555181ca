"""Design of the all-pass waveguide bar: parameters and a sample rate in, filters and their
report out (pure: no state; cached).

Sources: S. A. Van Duyne and J. O. Smith, "A simplified approach to modeling dispersion caused
by stiffness in strings and plates", Proc. ICMC 1994 (a waveguide whose unit delays become
all-pass filters); J. S. Abel and J. O. Smith, "Robust design of very high-order allpass
dispersion filters", Proc. DAFx 2006; J. Rauhala and V. Välimäki, "Tunable dispersion filter
design for piano synthesis", IEEE Signal Processing Letters 13 (2006); G. Essl and P. R. Cook,
"Banded waveguides", Proc. ICMC 1999 (the comparison of the three bar models); K. F. Graff,
*Wave Motion in Elastic Solids* (1975), ch. 3.

The steps, each in its own module: the phase each filter must give (:mod:`.targets`), the band
and each filter's order, delay and sign (:mod:`.plan`), the losses (:mod:`.loss`), the chains'
poles (:mod:`.fitting`), the strike and pick-up filters and the loop's resonances
(:mod:`.injection`). Here they are put together (losses redesigned for the group delays the
fit gave and the fit refined, ``LOSS_PASSES`` times), and the result is reported.

Signature::

    allpass_design(*, youngs_modulus_pa, density_kg_m3, length_m, thickness_m, width_m=0.04,
                   bc="free-free", allpass_order=16, q=300.0, sample_rate=48000.0,
                   strike_position=0.1, pickup_position=0.0) -> AllpassDesign

``AllpassDesign.modes`` is the report: one :class:`ModeFit` per resonance of the loop from
the first mode up to Nyquist, with the physics frequency, the model's, their difference in
cents, the target and the model's T60, the gain, and whether it lies in the fitted band;
``AllpassDesign.spurious`` lists the loop's resonances below the first mode with their (tiny)
gains and T60s.

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

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from ...errors import ParameterError
from ..constraints import check_constraints
from .fitting import Chain, fit, fit_band
from .injection import HIGH_PASS_FRACTION, group_delay, high_pass, injection_filter, resonances
from .loss import Loss, filter_losses
from .plan import BAND_BOTTOM, Plan, band_top_hz, first_mode_refusal, first_turn, make_plans
from .table import CONSTRAINTS, AllpassParams
from .targets import Bar, Targets

__all__ = ["AllpassDesign", "Filter", "ModeFit", "allpass_design", "design_for"]

LOSS_PASSES = 2  # losses redesigned for the fitted group delays, and the fit refined, this often


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
    band_hz: tuple[float, float]
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


SOURCES = ("barsynth.models.allpass", "barsynth.physics", "barsynth.numerics")
"""The code a design comes from (the on-disk cache's key covers it: :mod:`barsynth.designcache`)."""


@lru_cache(maxsize=32)
def _design(e: float, rho: float, length: float, thickness: float, width: float, bc: str, order: int,
            q: float, rate: float, strike: float, pickup: float) -> AllpassDesign:
    """The design (kept in memory, and on disk for the program: :mod:`barsynth.designcache`)."""
    from ... import designcache

    inputs = [*(float.hex(v) for v in (e, rho, length, thickness, width)), bc, order,
              *(float.hex(v) for v in (q, rate, strike, pickup))]
    return designcache.cached("allpass", inputs, SOURCES,
                              lambda: _fitted(e, rho, length, thickness, width, bc, order, q, rate, strike, pickup),
                              _record, _from_record)


def _fitted(e: float, rho: float, length: float, thickness: float, width: float, bc: str, order: int,
            q: float, rate: float, strike: float, pickup: float) -> AllpassDesign:
    from ...physics import bar_frequencies, bending_wave_constant

    bar = Bar(bending_wave_constant(e, rho, thickness), length, rho * length * thickness * width, bc, rate)
    f_1 = float(bar_frequencies(youngs_modulus_pa=e, density_kg_m3=rho, length_m=length, thickness_m=thickness,
                                bc=bc, count=1)[0])
    refusal = first_mode_refusal(f_1, rate, youngs_modulus_pa=e, density_kg_m3=rho, length_m=length,
                                 thickness_m=thickness)
    if refusal:
        raise ParameterError(refusal)
    top_hz = band_top_hz(rate)
    w_1, w_top = 2 * math.pi * f_1 / rate, 2 * math.pi * top_hz / rate
    a, b = sorted((strike, pickup))
    targets = Targets(bar, a, b, float(bar.lam(math.pi)))
    w_all = bar.w_of_lam(targets.lam_n)
    below_top = w_all < w_top
    # each filter loses its share (its length) of lambda_n / (2 q) nepers per round trip
    round_trip = targets.lam_n[below_top] / (2.0 * q)
    losses = filter_losses(w_all[below_top], round_trip, a, b)
    plans = make_plans(targets, losses, a, b)
    w_lo = BAND_BOTTOM * w_1
    count, xs, w_hi = fit_band(plans, bar, order, w_lo, w_all[below_top], w_top, targets.lam_n)
    filters = _refine_losses(plans, targets, bar, xs, losses, w_all[below_top], count, (w_lo, w_hi), q, (a, b))
    injection = injection_filter(bar, w_1, w_top, w_all[:count])
    pickup_rows = high_pass(HIGH_PASS_FRACTION * w_1)
    strike_at_a = strike <= pickup
    pickup_at_a = pickup <= strike
    modes, spurious = _report(filters, injection, pickup_rows, strike_at_a, pickup_at_a, bar, w_all, count,
                              first_turn(plans, targets, w_all[0]), q)
    return AllpassDesign(rate, bc, (w_lo * rate / (2 * math.pi), w_hi * rate / (2 * math.pi)),
                         strike_at_a, pickup_at_a, filters, injection, pickup_rows, modes, spurious)


def _refine_losses(plans, targets, bar, xs, losses, w_modes, count, band, q, points):
    """The filters, with their losses redesigned for the group delays the fit gave at the
    fitted modes and the fit refined for the losses' (slightly different) phase,
    ``LOSS_PASSES`` times."""
    def build(xs, losses):
        return _loop_filters({p.name: _make_filter(p.name, p, Chain(p.order), x, losses[p.name])
                              for p, x in zip(plans, xs)})

    filters = build(xs, losses)
    fitted = w_modes[:count]  # the modes the loop has; above them its resonances are not the bar's
    for _ in range(LOSS_PASSES):
        losses = filter_losses(fitted, fitted * group_delay(filters, fitted) / (2.0 * q), *points)
        for plan, again in zip(plans, make_plans(targets, losses, *points)):
            plan.lag = again.lag
        xs = fit(plans, bar, w_modes[:count], targets.lam_n[:count], *band, warm=xs)[0]
        filters = build(xs, losses)
    return filters


def _make_filter(name: str, plan: Plan, chain: Chain, x: np.ndarray, loss: Loss | None) -> Filter:
    poles = chain.poles(x) if plan.order else ()
    rows = chain.rows(x) if plan.order else np.zeros((0, 5))
    if loss is not None:
        rows = np.vstack([rows, loss.rows()])
    return Filter(name, plan.delay, -1.0 if plan.offset % 2 else 1.0, poles, rows, loss)


def _loop_filters(made: dict) -> tuple[Filter, Filter, Filter, Filter]:
    """end0, right, endL, left: in the order a wave goes round."""
    def renamed(f, name):
        return Filter(name, f.delay, f.sign, f.poles, f.sections, f.loss)

    end0 = made.get("end0", made.get("ends"))
    end_l = made.get("endL", made.get("ends"))
    return (renamed(end0, "end0"), renamed(made["middle"], "right"), renamed(end_l, "endL"),
            renamed(made["middle"], "left"))


def _report(filters, injection, pickup, strike_at_a, pickup_at_a, bar, w_all, count, first, q):
    """Each resonance against the bar's mode of the same number, and those below mode 1."""
    w, turns, t60, gain = resonances(filters, injection, pickup, strike_at_a, pickup_at_a, 1e-4 * w_all[0], bar)
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


def _record(design: AllpassDesign) -> dict:
    """``design`` as a JSON object, every float exact (:func:`_from_record` reads it back)."""
    from ...designcache import array_record

    h = float.hex
    filters = [{"name": f.name, "delay": int(f.delay), "sign": h(f.sign),
                "poles": [[h(p.real), h(p.imag)] for p in f.poles], "sections": array_record(f.sections),
                "loss": None if f.loss is None else {"gain": h(f.loss.gain),
                                                     "shelves": [[h(b), h(c)] for b, c in f.loss.shelves]}}
               for f in design.filters]
    modes = [[int(m.number), *(h(v) for v in (m.physics_hz, m.model_hz, m.cents, m.target_t60_s, m.model_t60_s,
                                              m.gain)), bool(m.fitted)] for m in design.modes]
    return {"sample_rate": h(design.sample_rate), "bc": design.bc, "band_hz": [h(v) for v in design.band_hz],
            "strike_at_a": bool(design.strike_at_a), "pickup_at_a": bool(design.pickup_at_a), "filters": filters,
            "injection": array_record(design.injection), "pickup": array_record(design.pickup), "modes": modes,
            "spurious": [[h(v) for v in s] for s in design.spurious]}


def _from_record(record: dict) -> AllpassDesign:
    """The :class:`AllpassDesign` of :func:`_record` (raises on a malformed record)."""
    from ...designcache import array_from

    x = float.fromhex

    def rows(data: dict) -> np.ndarray:
        array = array_from(data)
        if array.ndim != 2 or array.shape[1] != 5:
            raise ValueError(f"sections of shape {array.shape}")
        return array

    def loss(data: dict | None) -> Loss | None:
        return None if data is None else Loss(x(data["gain"]), tuple((x(b), x(c)) for b, c in data["shelves"]))

    filters = tuple(Filter(str(f["name"]), int(f["delay"]), x(f["sign"]),
                           tuple(complex(x(re), x(im)) for re, im in f["poles"]), rows(f["sections"]), loss(f["loss"]))
                    for f in record["filters"])
    if [f.name for f in filters] != ["end0", "right", "endL", "left"]:
        raise ValueError("not the loop's four filters")
    modes = tuple(ModeFit(int(m[0]), *(x(v) for v in m[1:7]), bool(m[7])) for m in record["modes"])
    low, high = (x(v) for v in record["band_hz"])
    return AllpassDesign(x(record["sample_rate"]), str(record["bc"]), (low, high),
                         bool(record["strike_at_a"]), bool(record["pickup_at_a"]), filters,
                         rows(record["injection"]), rows(record["pickup"]), modes,
                         tuple(tuple(x(v) for v in s) for s in record["spurious"]))


def design_for(p: AllpassParams, sample_rate: float) -> AllpassDesign:
    """The waveguide for the model's parameters ``p`` at ``sample_rate`` (Hz); cached. Refuses
    (ParameterError, one line) a bar its declared constraints refuse (its first mode below
    ``LOWEST_FIRST_MODE_HZ`` or above the fitted band: :data:`.table.CONSTRAINTS`), before any
    fit, and an order that gives no stable design."""
    check_constraints(CONSTRAINTS, p, sample_rate)
    design = allpass_design(youngs_modulus_pa=p.youngs_modulus_pa, density_kg_m3=p.density_kg_m3,
                            length_m=p.length_m, thickness_m=p.thickness_m, width_m=p.width_m, bc=p.bc,
                            allpass_order=p.allpass_order, q=p.q, sample_rate=sample_rate,
                            strike_position=p.strike_position, pickup_position=p.pickup_position)
    if not all(np.all(np.isfinite(f.sections)) for f in design.filters):
        raise ParameterError(f"parameter allpass_order = {p.allpass_order} gave no stable design for this bar; "
                             "allowed: another order from 1 to 64, or another bar")
    return design
