r"""Eigenpairs of a diagonal matrix plus a rank-one term: ``diag(d) + ρ w wᵀ`` (``ρ > 0``) by its secular equation.

The eigenvalues ``λ`` of ``diag(d) + ρ w wᵀ`` (``d`` ascending) are the roots of the secular equation

.. math::  f(λ) = 1/ρ + \sum_j \frac{w_j^2}{d_j − λ} = 0,

one in each interval ``(d_i, d_{i+1})`` and the last in ``(d_n, d_n + ρ‖w‖²)``; the eigenvector of ``λ`` is
``(diag(d) − λ)⁻¹ w``, normalised.  Computed as in LAPACK's divide and conquer (``dlaed2``–``dlaed4``, Bunch,
Nielsen and Sorensen 1978; Gu and Eisenstat 1995), written here for its one use (a point mass or a spring added to
a beam whose modes are known, :mod:`ebb_model.modal.attached_modes`):

* **deflation**: a component with ``ρ‖w‖ |w_j| ≤ 8 eps · max(|d|, ρ‖w‖²)`` leaves ``(d_j, e_j)`` an eigenpair as it
  is;
* **roots** from the nearer pole as origin (``λ = d_K + τ``, the differences ``d_j − λ = (d_j − d_K) − τ`` formed
  without cancellation), by the "middle way" rational model of ``f`` (two poles, one either side, matched in value
  and slope), bisection when a step leaves the bracket, until ``|f|`` is below its rounding bound;
* **vectors** from the weights ``ŵ`` that make the computed roots exact (Gu–Eisenstat:
  ``ŵ_j² = Π_k (λ_k − d_j) / Π_{k≠j} (d_k − d_j)``), so that they are orthogonal to working precision whatever
  the roots' distances to the poles.

Two poles closer than the deflation tolerance (a double eigenvalue of the base) are not deflated by rotation here:
:func:`rank_one_eigen` reports failure and its caller decomposes directly.
"""
from __future__ import annotations

import numba
import numpy as np

__all__ = ["rank_one_eigen"]

#: Iterations allowed per root (quadratic convergence from the middle of its bracket takes 3–6).
_MAX_ITERATIONS = 60


def rank_one_eigen(d: np.ndarray, w: np.ndarray, rho: float, first: int, stop: int
                   ) -> tuple[np.ndarray, np.ndarray] | None:
    """Eigenvalues (ascending) of ``diag(d) + ρ w wᵀ`` and the unit eigenvectors of those with index
    ``first … stop − 1``; ``None`` when two poles coincide to the deflation tolerance (module docstring).

    Parameters
    ----------
    d
        Strictly ascending diagonal (n,).
    w
        The update's vector (n,).
    rho
        Its weight, ``> 0``.
    first, stop
        The eigenvectors wanted, by the eigenvalues' ascending index.

    Returns
    -------
    tuple of numpy.ndarray
        ``(λ (n,), Y (n, stop − first))``.
    """
    d = np.ascontiguousarray(d, dtype=float)
    w = np.ascontiguousarray(w, dtype=float)
    lam = np.empty(d.size)
    Y = np.zeros((d.size, max(stop - first, 0)))
    if not _solve(d, w, float(rho), first, stop, lam, Y):
        return None
    return lam, Y


@numba.njit(cache=True, nogil=True)
def _root(d, u2, r, i):  # pragma: no cover - compiled
    """Root ``i`` of ``1/r + Σ u2_j/(d_j − λ)`` (``d`` ascending, every ``u2_j > 0``): ``(K, τ)`` with
    ``λ = d_K + τ``."""
    n = d.size
    eps = np.finfo(np.float64).eps
    if i < n - 1:
        gap = d[i + 1] - d[i]
        mid = 0.5 * gap
        g = 1.0 / r
        for j in range(n):
            g += u2[j] / ((d[j] - d[i]) - mid)
        if g >= 0.0:
            K, lo, hi = i, 0.0, mid
        else:
            K, lo, hi = i + 1, -mid, 0.0
    else:
        total = 0.0
        for j in range(n):
            total += u2[j]
        K, lo, hi = n - 1, 0.0, r * total
    dK = d[K]
    tau = 0.5 * (lo + hi)
    for _ in range(_MAX_ITERATIONS):
        psi = dpsi = phi = dphi = 0.0
        for j in range(n):
            t = 1.0 / ((d[j] - dK) - tau)
            if j <= i:
                psi += u2[j] * t
                dpsi += u2[j] * t * t
            else:
                phi += u2[j] * t
                dphi += u2[j] * t * t
        g = 1.0 / r + psi + phi
        bound = 8.0 * (abs(psi) + abs(phi)) + 1.0 / r + abs(tau) * (dpsi + dphi)
        if abs(g) <= eps * bound or hi - lo <= 2.0 * eps * max(abs(lo), abs(hi)):
            return K, tau
        if g < 0.0:
            lo = tau
        else:
            hi = tau
        a = (d[i] - dK) - tau                 # to the pole below (< 0)
        if i < n - 1:
            b = (d[i + 1] - dK) - tau         # to the pole above (> 0)
            A = (a + b) * g - a * b * (dpsi + dphi)
            B = a * b * g
            C = g - a * dpsi - b * dphi
            disc = np.sqrt(abs(A * A - 4.0 * B * C))
            if C == 0.0:
                eta = B / A if A != 0.0 else -g / (dpsi + dphi)
            elif A <= 0.0:                    # the model's root between the poles (LAPACK's dlaed4)
                eta = (A - disc) / (2.0 * C)
            else:
                eta = 2.0 * B / (A + disc)
        else:
            C = g - a * dpsi
            eta = a + dpsi * a * a / C if C != 0.0 else -g / dpsi
        if g * eta >= 0.0:                    # the model stepped the wrong way: Newton's step instead
            eta = -g / (dpsi + dphi)
        step = tau + eta
        tau = step if lo < step < hi else 0.5 * (lo + hi)
    return K, tau


@numba.njit(cache=True, nogil=True)
def _solve(d, w, rho, first, stop, lam, Y):  # pragma: no cover - compiled
    """:func:`rank_one_eigen` into ``lam`` and ``Y`` (zeros on entry); ``False`` for coinciding poles."""
    n = d.size
    eps = np.finfo(np.float64).eps
    norm2 = 0.0
    for j in range(n):
        norm2 += w[j] * w[j]
    r = rho * norm2
    scale = max(abs(d[0]), abs(d[n - 1]), r)
    tol = 8.0 * eps * scale
    keep = np.zeros(n, dtype=np.bool_)
    m = 0
    for j in range(n):
        if r > 0.0 and r * abs(w[j]) / np.sqrt(norm2) > tol:
            keep[j] = True
            m += 1
    idx = np.empty(m, dtype=np.int64)
    q = 0
    for j in range(n):
        if keep[j]:
            idx[q] = j
            q += 1
    dk = np.empty(m)
    u2 = np.empty(m)
    for q in range(m):
        dk[q] = d[idx[q]]
        u2[q] = w[idx[q]] * w[idx[q]] / norm2
        if q > 0 and dk[q] - dk[q - 1] <= tol:
            return False
    # the kept problem: diag(dk) + r u uᵀ with ‖u‖ = 1; its roots and the differences d_j − λ_k
    delta = np.empty((m, m))
    roots = np.empty(m)
    for k in range(m):
        K, tau = _root(dk, u2, r, k)
        roots[k] = dk[K] + tau
        for j in range(m):
            delta[k, j] = (dk[j] - dk[K]) - tau
    # Gu–Eisenstat: the weights for which the computed roots are exact
    uh = np.empty(m)
    for j in range(m):
        t = -delta[j, j]
        for k in range(m):
            if k != j:
                t *= -delta[k, j] / (dk[k] - dk[j])
        uh[j] = np.sqrt(abs(t) / r)
        if w[idx[j]] < 0.0:
            uh[j] = -uh[j]
    # all eigenvalues, ascending: the deflated poles and the roots (each root lies above its own pole)
    values = np.empty(n)
    source = np.empty(n, dtype=np.int64)      # ≥ 0: root index; < 0: −1 − deflated component
    q = 0
    for j in range(n):
        if not keep[j]:
            values[q] = d[j]
            source[q] = -1 - j
            q += 1
    for k in range(m):
        values[q] = roots[k]
        source[q] = k
        q += 1
    order = np.argsort(values, kind="mergesort")
    for p in range(n):
        lam[p] = values[order[p]]
    for p in range(first, stop):
        s = source[order[p]]
        col = p - first
        if s < 0:
            Y[-1 - s, col] = 1.0
            continue
        total = 0.0
        for j in range(m):
            v = uh[j] / delta[s, j]
            Y[idx[j], col] = v
            total += v * v
        total = np.sqrt(total)
        for j in range(m):
            Y[idx[j], col] /= total
    return True
