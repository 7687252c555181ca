"""Refining partials together: Gauss-Newton sweeps over all of them against one residual.

All models are subtracted from the sound and each partial is corrected against
what is left in its band (:meth:`.demodulation.Engine.newton_step`), its neighbours
taking part in the solve; this is repeated over all partials until none moves (a
space-alternating, SAGE-like iteration). On a sum of exponentially decaying
cosines the exact parameters are the fixed point, whatever the filters, the
onsets or the neighbours. Each demodulation cutoff is at most half the distance to
the nearest other partial.

Reference: J. A. Fessler and A. O. Hero, "Space-alternating generalized
expectation-maximization algorithm", IEEE Trans. Signal Process. 42 (1994).
"""

from __future__ import annotations

import math

from .demodulation import Engine, Mode

_MAX_SWEEPS = 14  # sweeps over all partials at the most


def neighbour_cutoff(
    freqs: list[float], i: int, fs: float, duration: float, sigma: float | None
) -> float:
    """Demodulation cutoff for partial i: at most half the distance to anything else."""
    f = freqs[i]
    # a DC offset, and the partial's own mirror images beyond 0 Hz and Nyquist
    d = min(f, 2.0 * (0.5 * fs - f))
    for j, g in enumerate(freqs):
        if j != i:
            d = min(d, abs(g - f))
    cap = 100.0 if sigma is None else max(5.0, 3.0 * max(sigma, 0.0) / math.pi)
    b = min(0.5 * d, cap)
    return max(b, 0.7 / duration, 1e-3)


def refine(
    engine: Engine,
    modes: list[Mode],
    *,
    prune=None,
    max_sweeps: int = _MAX_SWEEPS,
    pending: tuple[float, ...] = (),
) -> list[Mode]:
    """Fit every partial, then iterate Gauss-Newton steps against the common residual.

    A partial that has settled (its last step changed nothing that matters) rests
    until one of its neighbours moves or its band changes. ``pending`` are
    frequencies of candidates still to come: bands stay clear of them too.
    """
    fs = engine.fs
    full = False  # was the last sweep a step of every partial?
    state = None  # the residual, kept up to date
    for sweep in range(max_sweeps + 1):
        freqs = [m.frequency_hz for m in modes]
        others = freqs + [f for f in pending if all(abs(f - g) > 1e-9 * f for g in freqs)]
        for i, m in enumerate(modes):
            if not m.fixed_cutoff:
                sigma = m.sigma if m.fitted else None
                cutoff = neighbour_cutoff(others, i, fs, engine.duration, sigma)
                if abs(cutoff - m.cutoff_hz) > 0.01 * cutoff:
                    m.settled = False
                m.cutoff_hz = cutoff
            if not m.fixed_centre:
                m.centre_hz = m.frequency_hz
        if sweep == 0 or engine.npad == 0:
            engine.prepare(modes)
        if all(m.settled for m in modes):
            if full:
                break
            # all resting: one step of every partial confirms (small changes of a
            # strong partial can matter to a weak neighbour)
            for m in modes:
                m.settled = False
        full = not any(m.settled for m in modes)
        residual, state = engine.residual(modes, state)
        state["residual"] = residual
        spec = engine.spectrum(residual)
        new: list[Mode] = []
        fitted = sorted((m for m in modes if m.fitted), key=lambda m: m.frequency_hz)
        for m in modes:
            if m.fitted:
                below = [o for o in fitted if o.frequency_hz < m.frequency_hz]
                above = [o for o in fitted if o.frequency_hz > m.frequency_hz]
                neighbours = below[-1:] + above[:1]
                if m.settled and not any(o.moved for o in neighbours):
                    new.append(m.copy(moved=False))
                    continue
                upd = engine.newton_step(m, spec, neighbours)
                upd.settled = (
                    abs(upd.frequency_hz - m.frequency_hz) <= 2e-8 * upd.frequency_hz + 1e-7
                    and abs(upd.sigma - m.sigma) <= 2e-5 * abs(upd.sigma) + 1e-5 / engine.duration
                    and abs(abs(upd.amp) - abs(m.amp)) <= 1e-5 * abs(upd.amp)
                )
            else:
                upd = engine.initial_fit(m, spec)
                upd.settled = False
            upd.moved = not upd.settled
            # a partial that wandered out of its band belongs to something else
            if upd.ok and abs(upd.frequency_hz - m.centre_hz) > 1.5 * m.cutoff_hz:
                upd.ok = False
            if upd.ok and not (0.0 < upd.frequency_hz < 0.5 * fs):
                upd.ok = False
            if upd.pinned and not upd.ok and m.fitted:
                # measure_partial's partial: start afresh where it was asked for
                upd = Mode(
                    frequency_hz=m.centre_hz,
                    centre_hz=m.centre_hz,
                    cutoff_hz=m.cutoff_hz,
                    fixed_cutoff=m.fixed_cutoff,
                    fixed_centre=m.fixed_centre,
                    pinned=True,
                )
            new.append(upd)
        before = len(new)
        modes = prune(new, final=False) if prune is not None else [m for m in new if m.ok]
        if len(modes) != before:
            # partials were dropped: their neighbours' bands and residual change
            for m in modes:
                m.moved = True
    return modes
