"""Static shapes of the bar on its contacts: at rest, and held down by the hand before it lets go.

A static shape minimises the energy ``u^T K u / 2 - f_gravity . u + sum_e V_e(eta_e(u))`` (the
contacts' penalty potentials of :mod:`.kernel`), held at a point if asked (``J_p . u = -d``,
a Lagrange multiplier). The energy is convex, so Newton's method with a backtracking line search
on it finds the one minimum; its Hessian is ``K + sum_e V_e'' J_e J_e^T``. Dense NumPy: a few
hundred unknowns at most, solved once per note.
"""

from __future__ import annotations

import numpy as np

from ...errors import ParameterError
from . import kernel as K

MAX_STEPS = 200


def _rows(contacts: K.Contacts, n: int) -> np.ndarray:
    """Each contact's row ``J_e`` over the unpadded unknowns (contacts x n)."""
    rows = np.zeros((contacts.first.size, n + 2 * K.PAD))
    for e, q in enumerate(contacts.first):
        rows[e, q] += contacts.w0[e]
        rows[e, q + 1] += contacts.w1[e]
    return rows[:, K.PAD:K.PAD + n]


def _laws(eta: np.ndarray, c: K.Contacts) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """V, V' and V'' of every contact at penetrations ``eta`` (V'' at 0 counts a one-sided
    contact as touching: the Hessian of the bar lying on the desk stays definite)."""
    k, a, two = c.stiffness, c.exponent, c.two_sided
    p = np.where(two, np.abs(eta), np.maximum(eta, 0.0))
    v = k * p ** (a + 1.0) / (a + 1.0)
    d = np.where(two, k * np.sign(eta) * np.abs(eta) ** a, k * p ** a)
    touching = two | (eta >= 0.0)
    second = np.where(touching, k * a * np.where(a == 1.0, 1.0, np.maximum(p, 0.0) ** np.maximum(a - 1.0, 0.0)), 0.0)
    return v, d, second


def static_shape(stiffness: np.ndarray, gravity: np.ndarray, contacts: K.Contacts, *,
                 force_at: np.ndarray | None = None, force_n: float = 0.0,
                 held_at: np.ndarray | None = None, held_m: float = 0.0) -> tuple[np.ndarray, float]:
    """The static shape (m, unpadded) and the holding force (N, up; 0 without ``held_at``).

    ``force_at``/``force_n``: a constant force pressing down at a point (a finger as a force);
    ``held_at``/``held_m``: the point held at the displacement ``held_m`` (m, up).
    """
    n = stiffness.shape[0]
    rows = _rows(contacts, n)
    sign, offset = contacts.sign, contacts.offset
    external = gravity.copy()
    if force_at is not None:
        external = external - force_n * force_at

    def energy(u: np.ndarray) -> float:
        eta = sign * (rows @ u - offset)
        return float(0.5 * u @ stiffness @ u - external @ u + np.sum(_laws(eta, contacts)[0]))

    u = np.zeros(n)
    if held_at is not None:
        u = held_at * (held_m / float(held_at @ held_at))  # feasible: J_p . u = held_m
    scale = float(np.max(np.diag(stiffness)))
    multiplier = 0.0
    for _ in range(MAX_STEPS):
        eta = sign * (rows @ u - offset)
        potential, d, second = _laws(eta, contacts)
        gradient = stiffness @ u - external + rows.T @ (sign * d)
        # a touch of regularisation keeps the step defined where nothing holds the bar yet (a Hertzian
        # contact has no stiffness at first touch); it biases the step, not where it ends: the stop is
        # on the energy Newton's step would still gain
        hessian = stiffness + (rows.T * second) @ rows + 1e-12 * scale * np.eye(n)
        solved = _newton_step(hessian, gradient, held_at)
        if solved is None:
            break
        step, multiplier = solved
        size = float(np.max(np.abs(step)))
        reach = float(np.max(np.abs(u)))
        decrement = -float(gradient @ step)  # what Newton's step would still lower the energy by, twice (J)
        rounding = 64.0 * np.finfo(float).eps * (float(0.5 * np.abs(u) @ np.abs(stiffness) @ np.abs(u)
                                                       + np.abs(external) @ np.abs(u)) + float(np.sum(potential)))
        if size <= 1e-14 + 1e-10 * reach or decrement <= rounding:
            return u + step, -multiplier
        before = energy(u)
        t = 1.0
        while t > 1e-12 and energy(u + t * step) > before - 1e-4 * t * decrement + rounding:
            t *= 0.5
        if t <= 1e-12:  # no decrease the energy's rounding lets us see
            if decrement <= 1e3 * rounding:
                return u + step, -multiplier
            break
        u = u + t * step
    raise NoRest("the bar has no rest on these supports; allowed: supports that hold it")


def _newton_step(hessian: np.ndarray, gradient: np.ndarray,
                 held_at: np.ndarray | None) -> tuple[np.ndarray, float] | None:
    """Newton's step (and the holding point's multiplier, 0 when nothing is held), or None when
    the system is singular."""
    n = gradient.size
    try:
        if held_at is None:
            step, multiplier = -np.linalg.solve(hessian, gradient), 0.0
        else:
            kkt = np.block([[hessian, held_at[:, None]], [held_at[None, :], np.zeros((1, 1))]])
            solution = np.linalg.solve(kkt, np.concatenate([-gradient, [0.0]]))
            step, multiplier = solution[:n], float(solution[n])
    except np.linalg.LinAlgError:
        return None
    return (step, multiplier) if np.all(np.isfinite(step)) and np.isfinite(multiplier) else None


class NoRest(ParameterError):
    """The bar finds no static rest on its supports (the model's voice says which settings)."""
