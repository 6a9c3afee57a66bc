"""A modal pattern fit's polish (diagnosis/search/pattern_polish.py): the heats' secant Jacobian and the race.

Truth: closed-form residuals — a linear one, whose Jacobian is its matrix, and one with two basins of known depth.
"""
from __future__ import annotations

import numpy as np

from diagnosis.search.pattern_polish import SecantJacobian, least_squares_polish, raced

A = np.array([[2.0, -1.0], [0.5, 3.0], [1.0, 1.0]])
b = np.array([0.3, -1.0, 2.0])


def _two_basins(x: np.ndarray) -> np.ndarray:
    """Zero at x = (1, 1); a local minimum near x0 = −1 of cost ½·(0.2·(−2))² + … > 0."""
    return np.array([x[0] ** 2 - 1.0, 0.2 * (x[0] - 1.0), x[1] - x[0] ** 2])


def test_the_first_jacobian_is_a_forward_difference_and_a_linear_residual_keeps_it():
    """On ``A x + b`` the difference Jacobian is ``A`` to its truncation-free round-off (steps 1e-6 relative:
    errors ~1e-16/1e-6 = 1e-10), and Broyden's update leaves an exact Jacobian exact (Δr = A Δx)."""
    lo, hi = np.full(2, -10.0), np.full(2, 10.0)
    jac = SecantJacobian(lambda x: A @ x + b, lo, hi)
    J0 = jac(np.array([0.7, -2.0])).copy()
    np.testing.assert_allclose(J0, A, atol=1e-8)
    J1 = jac(np.array([1.5, 0.25]))
    np.testing.assert_allclose(J1, J0, atol=1e-12)


def test_the_update_satisfies_the_secant_condition_and_a_step_at_a_bound_turns_back():
    """After a step the Jacobian maps the step to the residual's change exactly; at the upper bound the
    difference step goes down, and the column is still the derivative (to the difference's truncation)."""
    lo, hi = np.array([-2.0, -2.0]), np.array([1.0, 2.0])
    res_calls = []

    def res(x: np.ndarray) -> np.ndarray:
        res_calls.append(x.copy())
        return _two_basins(x)

    jac = SecantJacobian(res, lo, hi)
    x0 = np.array([1.0, 0.5])                   # x0[0] on its upper bound
    J0 = jac(x0).copy()
    assert all(np.all(x <= hi) for x in res_calls)
    exact = np.array([[2.0, 0.0], [0.2, 0.0], [-2.0, 1.0]])
    np.testing.assert_allclose(J0, exact, atol=1e-5)
    x1 = np.array([0.6, 0.9])
    J1 = jac(x1)
    np.testing.assert_allclose(J1 @ (x1 - x0), _two_basins(x1) - _two_basins(x0), atol=1e-12)


def test_the_race_ends_in_the_deepest_basin_at_the_converged_polish():
    """Starts in both basins: the race's answer is the global minimum, as polished to convergence with
    difference Jacobians from there (the heats' secant Jacobians only rank the starts)."""
    lo, hi = np.full(2, -3.0), np.full(2, 3.0)
    starts = [np.array([-1.3, 1.5]), np.array([-0.8, 0.2]), np.array([1.4, 2.5]), np.array([2.5, -1.0])]
    best = raced(_two_basins, starts, lo, hi, 200)
    direct = least_squares_polish(_two_basins, best.x, lo, hi, 200)
    assert best.cost < 1e-10 and abs(best.x[0] - 1.0) < 1e-5, best
    assert best.cost <= direct.cost + 1e-12
    far = least_squares_polish(_two_basins, np.array([-1.3, 1.5]), lo, hi, 200)
    assert far.cost > 1e-3          # the shallow basin is a real trap for a polish alone
