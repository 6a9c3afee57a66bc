r"""The few lowest ``ω²`` of a banded pencil, by Lanczos' iteration on the inverted problem.

A modal comparison needs the lowest few natural frequencies of a new parameter set — a point mass or a spring
moved, a different axial load — on both grids of the Richardson pair, eigenvalues only.  The dense
generalised solver reduces the whole ``n × n`` pencil first (``O(n³)``: 0.5 ms at 81 unknowns, 1.2 ms at 121),
though ``K`` and ``M`` are banded (the finite differences reach two neighbours; point masses, springs and weak
segments stay inside that band).

With ``K = L Lᵀ`` (banded Cholesky, ``O(n k²)``) the inverted problem ``M ψ = μ K ψ`` is the standard
symmetric ``C y = μ y``, ``C = L⁻¹ M L⁻ᵀ``, ``μ = 1/ω²``: the lowest modes are its *largest* eigenvalues, well
separated (``μ₁/μ₂ = (ω₂/ω₁)²``), which Lanczos' iteration finds first.  ``C`` is applied, never formed: two
banded triangular solves and a banded product, ``O(n k)`` per step.  Full re-orthogonalisation (twice) keeps the
Krylov basis orthogonal, so the Ritz values converge without ghosts; each is accepted when its residual ``r``
bounds its error far below round-off, ``r²/gap ≤ ε θ`` (Kato–Temple, the gap to the other Ritz values) and
``r ≤ √ε θ``.  As with the dense solver on the inverted pencil, the lowest ``ω²`` are not subject to the
``ε κ(K)`` of the direct problem; what is left is the factor's rounding.  Measured against 32-digit arithmetic on
the same matrices (the cantilever's grids of 42 and 122 unknowns, modes 1–4): Lanczos 7e-12 and 3e-10 on mode 1,
≤ 3e-12 on the others; LAPACK's dense solver on the inverted pencil 3.5e-11 and 1.6e-9, the direct one 1.9e-10 and
7.7e-9.  The start vector is fixed, so the values are a pure function of the pencil (no dependence on what was
computed before).

``None`` — the caller uses the dense solver — when the pencil is not banded narrowly, ``K`` is not positive
definite (compression beyond buckling, free ends' rigid-body modes), or the iteration has not converged within
:data:`MAX_STEPS`.
"""
from __future__ import annotations

import numba
import numpy as np

__all__ = ["inverse_eigenvalues", "MAX_BANDWIDTH", "MAX_STEPS"]

#: Widest band (off-diagonals on each side) taken as narrow: the finite differences' five-point stencil is 2.
MAX_BANDWIDTH = 4

#: Most Lanczos steps before the dense solver decides (the lowest few modes converge in 20–40 on the benches).
MAX_STEPS = 120

#: Seed of the fixed start vector.
_SEED = 20261128


def inverse_eigenvalues(K: np.ndarray, M: np.ndarray, n_modes: int) -> np.ndarray | None:
    """The ``n_modes`` largest ``μ = 1/ω²`` of ``M ψ = μ K ψ`` — the lowest modes — in ascending order (as
    LAPACK's), or ``None`` (module docstring).

    Parameters
    ----------
    K, M
        Symmetric, ``M`` positive definite; dense arrays whose non-zeros lie in a narrow band.
    n_modes
        How many (at least 1, at most a quarter of the unknowns: beyond, the dense solver is as fast).
    """
    n = K.shape[0]
    if n_modes < 1 or 4 * n_modes > n:
        return None
    kd = _bandwidth(K, M)
    if kd > MAX_BANDWIDTH:
        return None
    start = np.random.default_rng(_SEED).standard_normal(n)
    mu, ok = _lanczos(np.ascontiguousarray(K, dtype=float), np.ascontiguousarray(M, dtype=float), kd, n_modes,
                      start, min(MAX_STEPS, n))
    return mu if ok else None


def _bandwidth(K: np.ndarray, M: np.ndarray) -> int:
    """The largest ``|i − j|`` of a non-zero of ``K`` or ``M``."""
    i, j = np.nonzero((K != 0.0) | (M != 0.0))
    return int(np.max(np.abs(i - j), initial=0))


@numba.njit(cache=True, nogil=True)
def _cholesky(K, kd):  # pragma: no cover - compiled
    """``L`` (band storage ``L[i, d] = L_{i, i−d}``) with ``K = L Lᵀ``, and whether ``K`` is positive definite."""
    n = K.shape[0]
    L = np.zeros((n, kd + 1))
    for i in range(n):
        for j in range(max(0, i - kd), i + 1):
            s = K[i, j]
            for p in range(max(0, i - kd), j):
                s -= L[i, i - p] * L[j, j - p]
            if j == i:
                if not s > 0.0:
                    return L, False
                L[i, 0] = np.sqrt(s)
            else:
                L[i, i - j] = s / L[j, 0]
    return L, True


@numba.njit(cache=True, nogil=True)
def _apply(L, M, kd, v, w, y):  # pragma: no cover - compiled
    """``y = L⁻¹ M L⁻ᵀ v`` (``w`` work)."""
    n = v.size
    for i in range(n - 1, -1, -1):          # Lᵀ w = v
        s = v[i]
        for q in range(i + 1, min(n, i + kd + 1)):
            s -= L[q, q - i] * w[q]
        w[i] = s / L[i, 0]
    for i in range(n):                      # L y = M w
        s = 0.0
        for q in range(max(0, i - kd), min(n, i + kd + 1)):
            s += M[i, q] * w[q]
        for q in range(max(0, i - kd), i):
            s -= L[i, i - q] * y[q]
        y[i] = s / L[i, 0]


@numba.njit(cache=True, nogil=True)
def _lanczos(K, M, kd, m, start, steps):  # pragma: no cover - compiled
    """The ``m`` largest eigenvalues of ``C = L⁻¹ M L⁻ᵀ`` (ascending) and whether they converged (module
    docstring)."""
    n = K.shape[0]
    L, ok = _cholesky(K, kd)
    mu = np.zeros(m)
    if not ok:
        return mu, False
    eps = np.finfo(np.float64).eps
    Q = np.zeros((steps + 1, n))
    alpha = np.zeros(steps)
    beta = np.zeros(steps)
    Q[0] = start / np.sqrt(np.dot(start, start))
    w = np.zeros(n)
    y = np.zeros(n)
    for j in range(steps):
        _apply(L, M, kd, Q[j], w, y)
        alpha[j] = np.dot(Q[j], y)
        for _ in range(2):                  # full re-orthogonalisation, twice
            for i in range(j + 1):
                y -= np.dot(Q[i], y) * Q[i]
        b = np.sqrt(np.dot(y, y))
        beta[j] = b
        size = j + 1
        if size >= m + 2 and (size % 4 == 0 or size == steps or b == 0.0):
            T = np.zeros((size, size))
            for i in range(size):
                T[i, i] = alpha[i]
                if i + 1 < size:
                    T[i, i + 1] = T[i + 1, i] = beta[i]
            theta, S = np.linalg.eigh(T)
            top = theta[size - 1]
            done = True
            for i in range(size - m, size):
                r = b * abs(S[size - 1, i])
                gap = np.inf
                for q in range(size):
                    if q != i:
                        gap = min(gap, abs(theta[q] - theta[i]))
                if not (r <= np.sqrt(eps) * theta[i] and r * r <= eps * theta[i] * gap and theta[i] > 0.0):
                    done = False
                    break
            if done or b <= eps * top:
                if done:
                    mu[:] = theta[size - m:]
                return mu, done
        if b == 0.0:
            return mu, False
        Q[j + 1] = y / b
    return mu, False
