r"""Poles and eigenvectors of modes coupled by a low-rank part of the damping, without a dense eigensolver.

When a point mass (a transducer, a shaker's armature, a lumped attachment) sits on a beam with viscous damping
per unit length, the damping is proportional to the beam's distributed mass but not to the attached mass:
``C = α M + ΔC`` with ``ΔC`` non-zero only on the few unknowns the masses are spread over (the hat functions'
two nodes each).  In the mass-normalised undamped modes ``Ψ`` the modal damping is then the identity times ``α``
plus a matrix of small rank ``r``:

.. math::  C_m = Ψᵀ C Ψ = α I + G E Gᵀ,\qquad G = Ψ_Jᵀ\ (k × r),\quad E = ΔC_{JJ}\ (r × r),

``J`` the unknowns where ``ΔC`` is not zero.  The modal system ``q̈ + C_m q̇ + Λ q = F_m u`` couples every mode
with every other, and its poles and eigenvectors came from the dense eigenproblem of the ``2k × 2k`` state
matrix (``O(k³)``: 4.5 ms at 60 modes, plus 1.7 ms for its basis' condition — 30 % of the diagnosis of the rig
family's shaker armature on the compressed pinned bench).  With the structure each pole is a root of a scalar
function, found by Newton's iteration from its decoupled value, ``O(k r²)`` per pole and iteration (compiled:
1.3 → 0.28 ms for 60 modes and a point mass, against the same iteration as NumPy array operations):

* the pole of mode ``i`` is the root of ``f_i(s) = s² + s d_i + ω_i² − s² e_iᵀ Q_rr(s)⁻¹ e_i`` near
  ``−d_i/2 + i√(ω_i² − d_i²/4)`` (``Q(s) = s² I + s C_m + Λ``, ``r`` the other modes, ``e_i = C_m[r, i]``,
  ``d_i = C_m[i, i]``): ``det Q = det Q_rr · f_i``;
* with ``D_j(s) = s² + α s + ω_j²`` and ``P = Σ_{j≠i} g_j g_jᵀ / D_j`` (``g_j`` the rows of ``G``),
  ``Q_rr⁻¹ e_i = D_r⁻¹ G_r y`` with ``y = (I + s E P)⁻¹ E g_i`` (Woodbury), so ``f_i`` and its derivative
  ``f_i' = 2s + d_i − 2s e_iᵀx + s² xᵀ(2s I + C_rr)x`` (``x = Q_rr⁻¹ e_i``; ``Q`` is symmetric) need only
  ``r × r`` algebra per mode;
* the right eigenvector of the pole is ``v`` with ``v_i = 1``, ``v_r = −s x``; the left one of the linearised
  system is ``((sI + C_m) v, v)`` (``Q`` symmetric), so the pole's input weights are ``vᵀ F_m / vᵀ Q'(s) v``.

Each is exact to round-off like the dense route (checked against it in the tests).  ``None`` — the caller uses
the dense eigenproblem — when the damping has no such structure, a mode is not underdamped, an iteration does not
converge, or a root left the half-gap around its start (it might have converged to a neighbour's pole).
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

__all__ = ["LowRankDamping", "low_rank_damping", "coupled_poles", "coupled_modes", "MAX_RANK"]

#: Relative size (to the largest entry of ``C``) below which an entry of ``C − α M`` counts as zero: the two are
#: assembled from the same lumped lengths, equal up to one rounding per entry.
_ZERO_RTOL = 1e-12

#: Largest rank ``r`` taken as low (a point mass spreads over two unknowns; a few masses stay far below ``k``).
MAX_RANK = 8

#: Newton iterations allowed per pole (quadratic from the decoupled value, off by the coupling squared).
NEWTON_STEPS = 10

#: Smallest ``Im s / |s|`` of a pole (``√(1 − ζ²)``) the eigenvector basis is formed for: a mode nearer critical
#: damping has its two eigenvectors nearly parallel (the basis' condition grows as ``|s| / Im s``), and the
#: dense route, with its condition check, decides (:data:`~ebb_model.modal_form.MAX_BASIS_CONDITION`).
CRITICAL_MARGIN = 1e-5


@dataclass(frozen=True, eq=False)
class LowRankDamping:
    """``C_m = α I + G E Gᵀ`` (module docstring): ``alpha``, ``G`` (k × r), ``E`` (r × r, symmetric)."""

    alpha: float
    G: np.ndarray
    E: np.ndarray

    @property
    def rank(self) -> int:
        """``r``: 0 when ``C = α M`` exactly (mass-proportional damping)."""
        return int(self.G.shape[1])

    def matrix(self) -> np.ndarray:
        """The modal damping ``C_m`` (k × k, symmetric)."""
        Cm = self.G @ self.E @ self.G.T
        Cm = 0.5 * (Cm + Cm.T)
        Cm[np.diag_indices_from(Cm)] += self.alpha
        return Cm


def low_rank_damping(M: np.ndarray, C: np.ndarray, psi: np.ndarray) -> LowRankDamping | None:
    """The structure ``C_m = α I + G E Gᵀ`` of ``Ψᵀ C Ψ`` for mass-normalised modes ``psi`` (columns), or ``None``
    when ``C − α M`` is not zero outside at most :data:`MAX_RANK` unknowns for the ``α`` of most unknowns.
    Rank 0 is mass-proportional damping: ``C_m = α I`` exactly, however far the computed modes' ``Ψᵀ M Ψ`` is
    from the identity (2.5e-10 on the rig family's bench half-way to buckling)."""
    dM, dC = np.diag(M), np.diag(C)
    if not np.all(dM > 0):
        return None
    alpha = float(np.median(dC / dM))
    delta = C - alpha * M
    scale = max(float(np.max(np.abs(C), initial=0.0)), float(np.finfo(float).tiny))
    J = np.flatnonzero(np.max(np.abs(delta), axis=1) > _ZERO_RTOL * scale)
    if J.size > MAX_RANK:
        return None
    return LowRankDamping(alpha, psi[J].T.copy(), delta[np.ix_(J, J)])


def _others(s: np.ndarray, alpha: float, w2: np.ndarray) -> np.ndarray:
    """``1/D_j(s_i)`` for the other modes ``j ≠ i`` of each pole ``s_i`` (``i < s.size``), zero for ``j = i`` (whose
    ``D_i`` vanishes at a decoupled root)."""
    den = s[:, None] ** 2 + alpha * s[:, None] + w2[None, :]
    idx = np.arange(s.size)
    den[idx, idx] = 1.0
    inv = 1.0 / den
    inv[idx, idx] = 0.0
    return inv


def _start(w2: np.ndarray, d: np.ndarray) -> np.ndarray | None:
    if np.any(w2 <= 0) or np.any(d * d / 4 >= w2):
        return None
    return -d / 2 + 1j * np.sqrt(w2 - d * d / 4)


def coupled_poles(w2: np.ndarray, damping: LowRankDamping, n: int | None = None
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """The upper poles of the ``n`` lowest modes (all with ``None``) to round-off and, for each, the vector
    ``y`` of the module docstring at the root, or ``None`` (module docstring)."""
    k = w2.size
    n = k if n is None else n
    if n > k or not np.all(np.diff(w2[:min(n + 1, k)]) > 0):
        return None
    G, E, a = damping.G, damping.E, damping.alpha
    d = a + np.einsum("ia,ab,ib->i", G, E, G)                 # diag C_m
    s0 = _start(w2[:min(n + 1, k)], d[:min(n + 1, k)])
    if s0 is None:
        return None
    w = np.sqrt(w2[:min(n + 1, k)])
    gaps = np.diff(w)
    below = np.concatenate([[w[0]], gaps])[:n]
    above = np.concatenate([gaps, [np.inf]])[:n]
    half_gap = 0.5 * np.minimum(below, above)
    u = G[:n] @ E                                               # E g_i (E symmetric), (n, r)
    s, y, converged = _newton(w2, np.ascontiguousarray(G, dtype=float), np.ascontiguousarray(E, dtype=float), a,
                              d[:n].copy(), s0[:n].copy(), np.ascontiguousarray(u, dtype=float), NEWTON_STEPS)
    if not converged:
        return None
    if not (np.all(np.abs(s - s0[:n]) < half_gap) and np.all(s.imag > CRITICAL_MARGIN * np.abs(s))):
        return None
    return s, y


@numba.njit(cache=True, nogil=True)
def _solve_small(A, b, x):  # pragma: no cover - compiled
    """``x = A⁻¹ b`` for a small complex ``A`` (r ≤ :data:`MAX_RANK`), Gaussian elimination with partial pivoting
    (``A`` overwritten): LAPACK's call costs more than the arithmetic at these sizes."""
    r = A.shape[0]
    for p in range(r):
        x[p] = b[p]
    for c in range(r):
        piv, best = c, abs(A[c, c])
        for p in range(c + 1, r):
            if abs(A[p, c]) > best:
                piv, best = p, abs(A[p, c])
        if piv != c:
            for q in range(r):
                A[c, q], A[piv, q] = A[piv, q], A[c, q]
            x[c], x[piv] = x[piv], x[c]
        for p in range(c + 1, r):
            f = A[p, c] / A[c, c]
            for q in range(c, r):
                A[p, q] -= f * A[c, q]
            x[p] -= f * x[c]
    for c in range(r - 1, -1, -1):
        acc = x[c]
        for q in range(c + 1, r):
            acc -= A[c, q] * x[q]
        x[c] = acc / A[c, c]


@numba.njit(cache=True, nogil=True)
def _newton_terms(s, i, w2, G, E, a, u_i, y, with_derivative):  # pragma: no cover - compiled
    """At the pole ``s`` of mode ``i``: ``y = (I + s E P)⁻¹ E g_i`` into ``y`` and, with ``with_derivative``,
    ``(e_iᵀx, xᵀx, xᵀC_rr x)`` (module docstring)."""
    k, r = G.shape
    P = np.zeros((r, r), dtype=np.complex128)
    S2 = np.zeros((r, r), dtype=np.complex128)
    for j in range(k):                          # P = Σ_{j≠i} g_j g_jᵀ / D_j(s), S2 the same over D_j²
        if j == i:
            continue
        inv = 1.0 / (s * s + a * s + w2[j])
        inv2 = inv * inv
        for p in range(r):
            gp = G[j, p]
            for q in range(r):
                P[p, q] += inv * gp * G[j, q]
                S2[p, q] += inv2 * gp * G[j, q]
    A = np.eye(r, dtype=np.complex128)
    for p in range(r):                          # I + s E P
        for q in range(r):
            acc = 0j
            for t in range(r):
                acc += E[p, t] * P[t, q]
            A[p, q] += s * acc
    _solve_small(A, u_i, y)
    if not with_derivative:
        return 0j, 0j, 0j
    Py = P @ y
    ex, xx, ePy = 0j, 0j, 0j
    for p in range(r):
        ex += u_i[p] * Py[p]
        for q in range(r):
            xx += y[p] * S2[p, q] * y[q]
            ePy += Py[p] * E[p, q] * Py[q]
    return ex, xx, a * xx + ePy


@numba.njit(cache=True, nogil=True)
def _newton(w2, G, E, a, d, s, u, steps):  # pragma: no cover - compiled
    """Newton's iteration on ``f_i`` for each pole, until its step is below 1e-14 of it; the poles, the ``y`` at
    them and whether every pole converged within ``steps``."""
    n, r = s.size, G.shape[1]
    y = np.zeros((n, r), dtype=np.complex128)
    yi = np.zeros(r, dtype=np.complex128)
    for i in range(n):
        converged = False
        for _ in range(steps):
            ex, xx, xCx = _newton_terms(s[i], i, w2, G, E, a, u[i], yi, True)
            si = s[i]
            f = si * si + si * d[i] + w2[i] - si * si * ex
            df = 2.0 * si + d[i] - 2.0 * si * ex + si * si * (2.0 * si * xx + xCx)
            step = f / df
            s[i] = si - step
            if abs(step) <= 1e-14 * abs(s[i]):
                converged = True
                break
        if not converged:
            return s, y, False
        _newton_terms(s[i], i, w2, G, E, a, u[i], yi, False)     # y at the converged pole
        y[i] = yi
    return s, y, True


def coupled_modes(w2: np.ndarray, damping: LowRankDamping, Fm: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Every pole, the eigenvectors ``V`` (2k × 2k, on the state ``(q, q̇)``) and the input weights in pole
    coordinates (2k × m) of the modal system, in the layout of the dense route (upper poles first, then their
    conjugates), or ``None`` (module docstring)."""
    k = w2.size
    found = coupled_poles(w2, damping, None)
    if found is None:
        return None
    s, y = found
    G, E, a = damping.G, damping.E, damping.alpha
    inv = _others(s, a, w2)                                           # (pole i, mode j)
    idx = np.arange(k)
    X = -(s[:, None] * inv) * (y @ G.T)                               # row i: v_i over the modes j
    X[idx, idx] = 1.0
    # vᵀ Q'(s) v = 2s vᵀv + vᵀ C_m v, C_m v = α v + G E Gᵀ v
    Gv = X @ G
    norm = 2.0 * s * np.einsum("ij,ij->i", X, X) + a * np.einsum("ij,ij->i", X, X) \
        + np.einsum("ia,ab,ib->i", Gv, E, Gv)
    Bu = (X @ Fm) / norm[:, None]
    lam = np.concatenate([s, s.conj()])
    Vq = np.concatenate([X.T, X.T.conj()], axis=1)                   # columns v_i, then conj
    V = np.vstack([Vq, Vq * lam[None, :]])
    return lam, V, np.vstack([Bu, Bu.conj()])
