"""barsynth.numerics on its own: Levenberg-Marquardt on problems with known answers
(Rosenbrock's valley, an exponential decay, an underdetermined system, a residual that blows
up), and forward-difference Jacobians against exact ones."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from barsynth.numerics import levenberg_marquardt, numeric_jacobian, numeric_jacobian_rows


def rosenbrock(x):
    """Residuals of Rosenbrock's function, 100 (x2 - x1^2)^2 + (1 - x1)^2, with their Jacobian."""
    r = np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])
    jac = np.array([[-20.0 * x[0], 10.0], [-1.0, 0.0]])
    return r, jac


def test_rosenbrock_from_the_classic_start_reaches_the_minimum():
    x = levenberg_marquardt(rosenbrock, np.array([-1.2, 1.0]), iterations=200)
    assert x == pytest.approx([1.0, 1.0], abs=1e-6)


def test_an_exponential_decay_is_fitted_as_scipy_fits_it():
    t = np.linspace(0.0, 2.0, 40)
    noise = 0.01 * np.random.default_rng(3).standard_normal(t.size)
    y = 2.5 * np.exp(-1.7 * t) + 0.3 + noise

    def residual(x):
        return x[0] * np.exp(-x[1] * t) + x[2] - y

    ours = levenberg_marquardt(numeric_jacobian(residual), np.array([1.0, 1.0, 0.0]))
    reference = least_squares(residual, np.array([1.0, 1.0, 0.0]), method="lm").x
    assert ours == pytest.approx(reference, rel=1e-5)
    assert ours == pytest.approx([2.5, 1.7, 0.3], rel=0.05)


def test_fewer_residuals_than_parameters_still_give_a_solution():
    """scipy's 'lm' refuses these; the damping keeps the system solvable."""
    def residual(x):
        return np.array([x[0] + 2.0 * x[1] - x[2] - 1.0])

    x = levenberg_marquardt(numeric_jacobian(residual), np.zeros(3))
    assert residual(x)[0] == pytest.approx(0.0, abs=1e-6)


def test_steps_that_give_no_finite_cost_are_refused():
    """A residual that overflows beyond x = 1 never takes the solution there."""
    def fun(x):
        r = np.array([np.inf if x[0] > 1.0 else (x[0] - 2.0) ** 2])
        return r, np.array([[2.0 * (x[0] - 2.0)]])

    x = levenberg_marquardt(fun, np.array([0.0]))
    assert 0.0 < x[0] <= 1.0
    assert np.isfinite(fun(x)[0]).all()


def test_nothing_better_than_the_start_returns_the_start():
    def fun(x):
        return np.array([1.0]), np.zeros((1, 2))  # flat: no step lowers the cost

    start = np.array([0.25, -3.0])
    x = levenberg_marquardt(fun, start, iterations=5)
    assert np.array_equal(x, start) and x is not start


def test_numeric_jacobian_matches_the_exact_one():
    x = np.array([0.7, -1.3])
    r, jac = numeric_jacobian(lambda x: rosenbrock(x)[0])(x)
    exact_r, exact_jac = rosenbrock(x)
    assert np.array_equal(r, exact_r)
    assert jac == pytest.approx(exact_jac, abs=1e-4)


def test_the_jacobian_of_many_points_at_once_is_the_one_point_jacobian_exactly():
    """numeric_jacobian_rows takes the same steps and differences as numeric_jacobian: for a
    residual computed row by row alike, (r, J) agree bit for bit (the all-pass losses' fits
    rely on it: the golden sounds pin their designs)."""
    t = np.linspace(0.0, 1.0, 7)

    def residual(x):
        return x[0] * np.exp(-x[1] * t) + np.log1p(x[2] ** 2 * t) - 1.0

    def residuals(xs):
        return np.array([residual(x) for x in xs])

    for x in (np.array([0.7, -1.3, 2.0]), np.array([1e-3, 4.5, -1e4])):
        r, jac = numeric_jacobian(residual)(x)
        r_rows, jac_rows = numeric_jacobian_rows(residuals)(x)
        assert np.array_equal(r, r_rows) and np.array_equal(jac, jac_rows)
        assert jac_rows.flags.c_contiguous and jac_rows.shape == (t.size, x.size)
