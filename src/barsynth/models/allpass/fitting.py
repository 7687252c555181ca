"""The fit of the all-pass waveguide's chains: their poles, refined together.

Each filter starts from the equation-error least-squares all-pass of its target (M. Lang and
T. I. Laakso, "Simple and robust method for the design of allpass filters using least-squares
phase error criterion", IEEE Trans. CAS II 41, 1994; one pole pair per ``2 pi`` of phase, after
J. S. Abel and J. O. Smith, Proc. DAFx 2006, if that is unstable), then all are refined
together by Levenberg-Marquardt (:mod:`barsynth.numerics`) on, in order of weight: every fitted
mode's round-trip error (10 per cent), the round trip's group delay there (100 per relative
error: it sets each mode's level and decay), each filter's phase at the modes (10 per radian:
the mode shapes at the strike and pick-up points) and between them (0.1 per radian, RMS). If a
mode is left more than 1 cent out (or its group delay 50 %), the top mode is given up and the
fit repeated (at most 5 times; the best attempt is kept: :func:`fit_band`).

Sections are second order (poles anywhere inside radius ``R_MAX``, reached through
``a2 = R^2 tanh u``, ``a1 = R (1 + tanh u) tanh v``) and one first-order section when the
order is odd, so every design is stable. Frequencies ``w`` in rad/sample.
"""

from __future__ import annotations

import math

import numpy as np

from ...numerics import levenberg_marquardt
from .plan import Plan, band_grid, band_top, fitted_band
from .targets import Bar

CENTS_PER_NEPER = 1200.0 / math.log(2.0)
R_MAX = 0.99995  # largest pole radius of a dispersion section
MAX_CENTS, MAX_SLOPE_ERROR = 1.0, 0.5  # a fit worse than this at a mode gives up the band's top mode
MAX_RETRIES = 5
W_CENTS, W_SLOPE, W_AT_MODES, W_BETWEEN, W_ABOVE = 10.0, 100.0, 10.0, 0.1, 0.1  # weights of the fit
W_STAY = 1e-3  # a weak pull towards the starting poles, for parameters the modes leave free


def _real_lag(p: np.ndarray, w: np.ndarray):
    """Lag (rad) of first-order all-passes with real poles ``p`` (shape (k, 1)), and d/dp."""
    c, s = np.cos(w), np.sin(w)
    return w + 2.0 * np.arctan2(p * s, 1.0 - p * c), 2.0 * s / (1.0 - 2.0 * p * c + p * p)


class Chain:
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


def _initial_poles(chain: Chain, target, w_lo: float, w_hi: float, order: int) -> np.ndarray:
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


def _start(chain: Chain, plan: Plan, target: np.ndarray, w: np.ndarray, w_lo: float, w_hi: float) -> np.ndarray:
    """Starting parameters of one filter: the equation-error fit, or (if that is unstable)
    one pole pair per 2 pi of phase."""
    start = chain.from_poles(_equation_error_poles(target, plan.order, w)) if plan.order else None
    return start if start is not None else _initial_poles(chain, plan.chain_target, w_lo, w_hi, plan.order)


def fit(plans: list[Plan], bar: Bar, w_modes: np.ndarray, lam_modes: np.ndarray, w_lo: float, w_hi: float,
         warm: list[np.ndarray] | None = None):
    """Refine every filter's poles together (see the module notes for the weights), from
    ``warm`` (parameters of an earlier fit) if given. Returns each filter's parameters, and
    each mode's round-trip error in cents and the relative error of the round trip's group
    delay there."""
    grid, above = band_grid(bar, w_lo, w_hi), np.linspace(w_hi, math.pi, 42)[1:-1]
    m, n_grid, n_above = w_modes.size, grid.size, above.size
    h = 1e-5 * w_modes
    points = np.concatenate([grid, above, w_modes, w_modes - h, w_modes + h])
    n_free = n_grid + n_above
    targets = [p.fit_target(points, w_hi) for p in plans]
    chains = [Chain(p.order) for p in plans]
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
            x = levenberg_marquardt(fun, x, iterations=60)
        to_slope = slope
        x = levenberg_marquardt(fun, x, iterations=30 if warm else 80)
    r, _ = fun(x)
    r = r[:r.size - x.size]
    cents = r[-2 * m:-m] / W_CENTS
    slope_error = r[-m:] / W_SLOPE
    return [x[cuts[k]:cuts[k + 1]] for k in range(len(chains))], cents, slope_error


def fit_band(plans, bar, order, w_lo, w_modes, w_top, lam_n):
    """Fit as many modes as the order allows; if the fit misses ``MAX_CENTS`` or
    ``MAX_SLOPE_ERROR`` at a mode, try again without the top mode (at most ``MAX_RETRIES``
    times) and keep the best attempt. Returns the number of fitted modes, the filters'
    parameters and the band's top (rad/sample); ``plans`` are left as fitted."""
    count, attempts = w_modes.size, []
    for _ in range(MAX_RETRIES):
        count = fitted_band(plans, bar, order, w_lo, w_modes, w_top, count)
        w_hi = band_top(w_modes, count, w_top)
        xs, cents, slope_error = fit(plans, bar, w_modes[:count], lam_n[:count], w_lo, w_hi)
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
