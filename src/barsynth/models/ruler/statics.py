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
        _, d, second = _laws(eta, contacts)
        gradient = stiffness @ u - external + rows.T @ (sign * d)
        hessian = stiffness + (rows.T * second) @ rows + 1e-12 * scale * np.eye(n)
        if held_at is None:
            step = -np.linalg.solve(hessian, gradient)
        else:
            kkt = np.block([[hessian, held_at[:, None]], [held_at[None, :], np.zeros((1, 1))]])
            solution = np.linalg.solve(kkt, np.concatenate([-gradient, [0.0]]))
            step, multiplier = solution[:n], float(solution[n])
        if not np.all(np.isfinite(step)):
            break
        size = float(np.max(np.abs(step)))
        reach = float(np.max(np.abs(u)))
        if size <= 1e-14 + 1e-8 * reach:
            return u + step, -multiplier if held_at is not None else 0.0
        before = energy(u)
        t = 1.0
        slope = float(gradient @ step)
        while t > 1e-12 and energy(u + t * step) > before + 1e-4 * t * slope + 1e-15 * abs(before):
            t *= 0.5
        rounding = 64.0 * np.finfo(float).eps * float(0.5 * np.abs(u) @ np.abs(stiffness) @ np.abs(u)
                                                       + np.abs(external) @ np.abs(u))
        if t < 1.0 and -slope <= rounding:  # the decrease left is below the energy's rounding (u K u
            # cancels: a stiff bridge under a smooth tine), so the line search cannot see it: Newton's step
            return u + step, -multiplier if held_at is not None else 0.0
        moved = u + t * step
        if t <= 1e-12 or np.array_equal(moved, u):  # no decrease left to find: flat to rounding here
            if size <= 1e-12 + 1e-6 * reach:
                return u + step, -multiplier if held_at is not None else 0.0
            break
        u = moved
    raise ParameterError("the bar has no rest on these supports (the finger cannot hold it down, or it is not "
                         "supported at all); allowed: a larger finger_force_n or a smaller displacement")
