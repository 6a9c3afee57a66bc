"""Eigenpairs of ``diag(d) + ρ w wᵀ`` by the secular equation (:mod:`ebb_model.modal.secular`), against LAPACK and
against 40-digit arithmetic."""
from __future__ import annotations

import mpmath
import numpy as np
import pytest

from ebb_model.modal.secular import rank_one_eigen

EPS = np.finfo(float).eps


def _problem(rng: np.random.Generator, n: int, zeros: bool):
    d = np.unique(np.sort(rng.standard_normal(n) * 10 ** rng.uniform(-3, 3, n)))
    w = rng.standard_normal(d.size)
    if zeros:
        w[rng.random(d.size) < 0.3] = 0.0
    return d, w, 10 ** rng.uniform(-4, 3)


@pytest.mark.parametrize("zeros", [False, True])
def test_eigenpairs_are_those_of_the_matrix(zeros):
    """Against LAPACK's dense solver on 100 random problems (1–130 poles spread over six decades, some components
    zero: deflated): eigenvalues, orthogonality and residual to a few eps of the matrix's norm — budget 1e-13
    (450 eps; measured at most 2.5e-15 on each)."""
    rng = np.random.default_rng(11 if zeros else 12)
    for _ in range(100):
        d, w, rho = _problem(rng, int(rng.integers(1, 130)), zeros)
        A = np.diag(d) + rho * np.outer(w, w)
        ref = np.linalg.eigvalsh(A)
        lam, Y = rank_one_eigen(d, w, rho, 0, d.size)
        norm = np.max(np.abs(ref))
        assert np.max(np.abs(lam - ref)) <= 1e-13 * norm
        assert np.max(np.abs(Y.T @ Y - np.eye(d.size))) <= 1e-13
        assert np.max(np.abs(A @ Y - Y * lam)) <= 1e-13 * norm


def test_each_eigenvalue_to_relative_accuracy():
    """A beam-like spectrum (``d = 1/λ``, ``λ ∝ n⁴``: eleven decades): every eigenvalue, the smallest included, to a
    few eps of itself against 40-digit arithmetic (measured 4.4e-16); LAPACK's dense solver is off by up to 3e-9
    on the smallest (``eps`` of the largest) — why :mod:`ebb_model.modal.attached_modes` solves it this way."""
    rng = np.random.default_rng(3)
    n = 60
    d = np.sort(1.0 / ((np.arange(1, n + 1) * np.pi) ** 4 * (1 + 0.01 * np.arange(n))))
    w = rng.standard_normal(n) * np.sqrt(d)
    rho = 0.3
    lam, _ = rank_one_eigen(d, w, rho, 0, 0)
    mpmath.mp.dps = 40
    A = mpmath.matrix(n, n)
    for i in range(n):
        for j in range(n):
            A[i, j] = mpmath.mpf(rho) * mpmath.mpf(w[i]) * mpmath.mpf(w[j]) + (mpmath.mpf(d[i]) if i == j else 0)
    exact = np.array(sorted(float(x) for x in mpmath.eigsy(A, eigvals_only=True)))
    assert np.max(np.abs(lam / exact - 1.0)) <= 4 * EPS
    lapack = np.linalg.eigvalsh(np.diag(d) + rho * np.outer(w, w))
    assert np.max(np.abs(lapack / exact - 1.0)) > 1e4 * EPS      # the dense solver's relative error, for contrast


def test_a_zero_component_leaves_its_pole_an_eigenpair():
    d = np.array([1.0, 2.0, 3.0, 4.0])
    w = np.array([0.5, 0.0, 1.0, 0.25])
    lam, Y = rank_one_eigen(d, w, 2.0, 0, 4)
    k = int(np.flatnonzero(lam == 2.0)[0])
    assert np.array_equal(Y[:, k], [0.0, 1.0, 0.0, 0.0])
    np.testing.assert_allclose(lam, np.linalg.eigvalsh(np.diag(d) + 2.0 * np.outer(w, w)), rtol=1e-14)


def test_coinciding_poles_are_reported_not_solved():
    """Two equal poles with weight on both would need a rotation to deflate; the caller decomposes instead."""
    assert rank_one_eigen(np.array([1.0, 2.0, 2.0, 3.0]), np.ones(4), 1.0, 0, 4) is None


def test_a_subset_of_vectors():
    rng = np.random.default_rng(5)
    d, w, rho = _problem(rng, 40, False)
    lam, Y = rank_one_eigen(d, w, rho, 0, d.size)
    lam2, Y2 = rank_one_eigen(d, w, rho, 10, 25)
    assert np.array_equal(lam, lam2) and np.array_equal(Y[:, 10:25], Y2)
