"""Small numerical solvers the models' designs share.

:func:`levenberg_marquardt` minimises a sum of squares ``|r(x)|^2`` by damped Gauss-Newton
steps: K. Levenberg, "A method for the solution of certain non-linear problems in least
squares", Quart. Appl. Math. 2 (1944); D. W. Marquardt, "An algorithm for least-squares
estimation of nonlinear parameters", J. SIAM 11 (1963) (the damping scaled by the diagonal of
``J^T J``, so it does not depend on the parameters' units); the damping's update follows
K. Madsen, H. B. Nielsen and O. Tingleff, *Methods for Non-Linear Least Squares Problems*
(DTU, 2004), sec. 3.2, with fixed factors. :func:`numeric_jacobian` adds forward-difference
derivatives to a residual that has none (:func:`numeric_jacobian_rows` to one that takes many
points at once).

Why not :func:`scipy.optimize.least_squares` (``method="lm"``, MINPACK's ``lmder``)? Measured
on the all-pass waveguide's design (16 designs: four boundary conditions, orders 8 and 24, two
pairs of points): it refuses the problems with fewer residuals than parameters (48 of the
calls there: a loss fitted to two modes with three parameters, which Marquardt's damping
solves), and on the rest it took 7.3 s against 4.9 s and fitted worse (the worst mode 0.87 cent
out against 0.15, the worst T60 6.2 % against 3.8 %), because the design asks for a fixed,
small number of steps from a good start, not for convergence. This solver also stays bit for
bit what it was: the golden sounds pin the designs it makes.

Examples
--------
>>> t = np.linspace(0.0, 1.0, 20)
>>> y = 2.0 * np.exp(-3.0 * t)
>>> fit = levenberg_marquardt(numeric_jacobian(lambda x: x[0] * np.exp(-x[1] * t) - y), np.array([1.0, 1.0]))
>>> np.round(fit, 6)
array([2., 3.])
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

Residual = Callable[[np.ndarray], np.ndarray]
ResidualAndJacobian = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]

FIRST_DAMPING = 1e-3
SMALLEST_DAMPING = 1e-9
LARGEST_DAMPING = 1e8  # a step refused at more damping than this ends the search
SOFTER, HARDER, SINGULAR = 0.3, 5.0, 10.0  # damping after an accepted, a refused and an unsolvable step
RELATIVE_GAIN = 1e-9  # an accepted step that lowers the cost by less than this (relative) ends the search
DIFFERENCE_STEP = 1e-6  # numeric_jacobian's step, relative to max(1, |x_i|)


def levenberg_marquardt(fun: ResidualAndJacobian, x0: np.ndarray, iterations: int = 80) -> np.ndarray:
    """Minimise ``|r(x)|^2`` from ``x0``, where ``fun(x) = (r, J)`` (residuals, shape (m,), and
    their Jacobian, shape (m, n)): at most ``iterations`` damped Gauss-Newton steps.

    Each step solves ``(J^T J + mu diag(J^T J)) dx = -J^T r``. A step that lowers the cost (and
    gives finite residuals) is taken and ``mu`` shrinks; otherwise ``mu`` grows and the step is
    tried again, shorter. The search ends after ``iterations`` attempts, once a step gains less
    than ``RELATIVE_GAIN`` of the cost, or once ``mu`` passes ``LARGEST_DAMPING``. Works with
    fewer residuals than parameters (the damping keeps the system solvable). Returns the best
    ``x`` found (``x0`` if no step lowered the cost).
    """
    x = np.asarray(x0, dtype=float).copy()
    r, jac = fun(x)
    cost = float(r @ r)
    mu = FIRST_DAMPING
    for _ in range(iterations):
        jtj, g = jac.T @ jac, jac.T @ r
        scale = np.diag(jtj) + 1e-12
        try:
            step = np.linalg.solve(jtj + mu * np.diag(scale), -g)
        except np.linalg.LinAlgError:
            mu *= SINGULAR
            continue
        r_new, jac_new = fun(x + step)
        new = float(r_new @ r_new)
        if np.isfinite(new) and new < cost:
            done = cost - new < RELATIVE_GAIN * cost
            x, r, jac, cost = x + step, r_new, jac_new, new
            mu = max(mu * SOFTER, SMALLEST_DAMPING)
            if done:
                break
        else:
            mu *= HARDER
            if mu > LARGEST_DAMPING:
                break
    return x


def numeric_jacobian(residual: Residual) -> ResidualAndJacobian:
    """``residual`` (``x -> r``) as :func:`levenberg_marquardt` takes it (``x -> (r, J)``), with
    ``J`` by forward differences (step ``DIFFERENCE_STEP x max(1, |x_i|)``)."""
    def fun(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r = residual(x)
        jac = np.empty((r.size, x.size))
        for i in range(x.size):
            h = DIFFERENCE_STEP * max(1.0, abs(x[i]))
            dx = x.copy()
            dx[i] += h
            jac[:, i] = (residual(dx) - r) / h
        return r, jac
    return fun


def numeric_jacobian_rows(residuals: Residual) -> ResidualAndJacobian:
    """As :func:`numeric_jacobian`, for a residual that takes many points at once:
    ``residuals(xs)`` maps points (rows of ``xs``, shape (k, n)) to their residuals (rows,
    shape (k, m)). The point and its ``n`` steps go in one call (one NumPy operation on
    ``n + 1`` rows instead of ``n + 1`` on one), with the same steps and differences, so a
    ``residuals`` that computes each row as the one-point residual would gives the very same
    ``(r, J)``."""
    def fun(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        steps = np.array([DIFFERENCE_STEP * max(1.0, abs(x[i])) for i in range(x.size)])
        points = np.repeat(x[None, :], x.size + 1, axis=0)
        for i in range(x.size):
            points[1 + i, i] += steps[i]
        rows = residuals(points)
        r = rows[0].copy()
        jac = np.ascontiguousarray(((rows[1:] - r) / steps[:, None]).T)
        return r, jac
    return fun
