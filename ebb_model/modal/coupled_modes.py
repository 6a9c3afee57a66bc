r"""Poles and eigenvectors of modes coupled by a low-rank part of the damping, without a dense eigensolver.

When a point mass (a transducer, a shaker's armature, a lumped attachment) sits on a beam with viscous damping
per unit length, the damping is proportional to the beam's distributed mass but not to the attached mass; when a
spring (to ground, at an elastic end) holds a beam with Kelvin–Voigt damping, the damping is proportional to the
beam's bending stiffness but not to the spring's.  Without axial load, foundation or rotary inertia
(:meth:`ebb_model.modal.parameter_modes.FamilyModes.low_rank_damping`) ``C = α M + β K + ΔC`` with ``ΔC`` non-zero only
on the few unknowns the attachments are spread over (the hat functions' two nodes each).  In the mass-normalised
undamped modes ``Ψ`` (``ΨᵀKΨ = Λ_f``, the grid's own eigenvalues) the modal damping is then diagonal plus a
matrix of small rank ``r``:

.. math::  C_m = Ψᵀ C Ψ = \mathrm{diag}(d^0) + G E Gᵀ,\qquad d^0 = α + β Λ_f,\quad G = Ψ_Jᵀ\ (k × r),\quad
           E = ΔC_{JJ}\ (r × r),

``J`` the unknowns where ``ΔC`` is not zero.  The modal system ``q̈ + C_m q̇ + Λ q = F_m u`` couples every mode
with every other, and its poles and eigenvectors came from the dense eigenproblem of the ``2k × 2k`` state
matrix (``O(k³)``: 4.5 ms at 60 modes, plus 1.7 ms for its basis' condition — 30 % of the diagnosis of the rig
family's shaker armature on the compressed pinned bench).  With the structure each pole is a root of a scalar
function, found by Newton's iteration from its decoupled value, ``O(k r²)`` per pole and iteration (compiled:
1.3 → 0.28 ms for 60 modes and a point mass, against the same iteration as NumPy array operations):

* the pole of mode ``i`` is the root of ``f_i(s) = s² + s d_i + ω_i² − s² e_iᵀ Q_rr(s)⁻¹ e_i`` near
  ``−d_i/2 + i√(ω_i² − d_i²/4)`` (``Q(s) = s² I + s C_m + Λ``, ``r`` the other modes, ``e_i = C_m[r, i]``,
  ``d_i = C_m[i, i]``): ``det Q = det Q_rr · f_i``;
* with ``D_j(s) = s² + d⁰_j s + ω_j²`` and ``P = Σ_{j≠i} g_j g_jᵀ / D_j`` (``g_j`` the rows of ``G``),
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

__all__ = ["LowRankDamping", "coupled_poles", "coupled_modes", "MAX_RANK"]

#: Largest rank ``r`` taken as low (a point mass spreads over two unknowns; a few masses stay far below ``k``).
MAX_RANK = 8

#: Newton iterations allowed per pole (quadratic from the decoupled value, off by the coupling squared).
NEWTON_STEPS = 10

#: Smallest ``Im s / |s|`` of a pole (``√(1 − ζ²)``) the eigenvector basis is formed for: a mode nearer critical
#: damping has its two eigenvectors nearly parallel (the basis' condition grows as ``|s| / Im s``), and the
#: dense route, with its condition check, decides (:data:`~ebb_model.theta.modal_form.MAX_BASIS_CONDITION`).
CRITICAL_MARGIN = 1e-5


@dataclass(frozen=True, eq=False)
class LowRankDamping:
    """``C_m = diag(d⁰) + G E Gᵀ`` (module docstring): ``diagonal`` (``d⁰``, k), ``G`` (k × r), ``E`` (r × r,
    symmetric)."""

    diagonal: np.ndarray
    G: np.ndarray
    E: np.ndarray

    @property
    def rank(self) -> int:
        """``r``: 0 when ``C = α M + β K`` exactly (the modes decoupled)."""
        return int(self.G.shape[1])

    def matrix(self) -> np.ndarray:
        """The modal damping ``C_m`` (k × k, symmetric)."""
        Cm = self.G @ self.E @ self.G.T
        Cm = 0.5 * (Cm + Cm.T)
        Cm[np.diag_indices_from(Cm)] += self.diagonal
        return Cm


def _others(s: np.ndarray, mode: np.ndarray, d0: np.ndarray, w2: np.ndarray) -> np.ndarray:
    """``1/D_j(s_p)`` for every mode ``j`` other than the pole's own ``mode[p]``, zero for it (whose ``D_j``
    vanishes at a decoupled root)."""
    den = s[:, None] ** 2 + d0[None, :] * s[:, None] + w2[None, :]
    rows = np.arange(s.size)
    den[rows, mode] = 1.0
    inv = 1.0 / den
    inv[rows, mode] = 0.0
    return inv


def coupled_poles(w2: np.ndarray, damping: LowRankDamping, n: int | None = None
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """Both poles of each of the ``n`` lowest modes (all with ``None``) to round-off — every ``s₁``, then every
    ``s₂``, as the decoupled modes' ``−d/2 ± √(d²/4 − ω²)`` they start from (an underdamped mode's ``s₂`` is its
    ``s₁``'s conjugate) — and, for each, the vector ``y`` of the module docstring at the root; or ``None``
    (module docstring).

    An underdamped root must stay within half the gap in ``ω`` to the neighbouring modes and away from the real
    axis (:data:`CRITICAL_MARGIN`); an overdamped mode's two real roots (a stiff mode under Kelvin–Voigt damping)
    each within half the distance from its start to the nearest other decoupled pole, and apart by the same
    margin."""
    k = w2.size
    n = k if n is None else n
    if n > k or not np.all(np.diff(w2[:min(n + 1, k)]) > 0) or np.any(w2[:n] <= 0):
        return None
    G, E, d0 = damping.G, damping.E, damping.diagonal
    d = d0 + np.einsum("ia,ab,ib->i", G, E, G)                # diag C_m
    over = d * d / 4 >= w2                                    # overdamped (or critical): two real poles
    first = np.where(over, -d / 2 + np.sqrt(np.abs(d * d / 4 - w2)), -d / 2 + 1j * np.sqrt(np.abs(w2 - d * d / 4)))
    second = np.where(over, -d / 2 - np.sqrt(np.abs(d * d / 4 - w2)), first.conj())
    twice = np.flatnonzero(over[:n])
    starts = np.concatenate([first[:n], second[twice]])
    mode = np.concatenate([np.arange(n), twice])
    u = G[:n] @ E                                               # E g_i (E symmetric), (n, r)
    s, y, converged = _newton(w2, np.ascontiguousarray(G, dtype=float), np.ascontiguousarray(E, dtype=float),
                              np.ascontiguousarray(d0, dtype=float), d[:n].copy(), starts.astype(complex), mode,
                              np.ascontiguousarray(u, dtype=float), NEWTON_STEPS)
    if not converged:
        return None
    # how far each root may move: the ω gap to the neighbours (underdamped), half the distance to the nearest
    # other decoupled pole of any mode (overdamped)
    w = np.sqrt(np.abs(w2[:min(n + 1, k)]))
    gaps = np.diff(w)
    half_gap = 0.5 * np.minimum(np.concatenate([[w[0]], gaps])[:n], np.concatenate([gaps, [np.inf]])[:n])
    every = np.concatenate([first, second])
    if twice.size:
        distance = np.abs(starts[:, None] - every[None, :])
        distance[np.arange(starts.size), np.concatenate([mode[:n], k + twice])] = np.inf     # itself
        half_gap = np.where(np.concatenate([over[:n], np.ones(twice.size, bool)]),
                            0.5 * distance.min(axis=1), np.concatenate([half_gap, np.zeros(twice.size)]))
    if not np.all(np.abs(s - starts) < half_gap):
        return None
    s1, s2 = s[:n], s[:n].conj()
    y1, y2 = y[:n], y[:n].conj()
    s2[twice], y2[twice] = s[n:], y[n:]
    if not (np.all(s1.imag[~over[:n]] > CRITICAL_MARGIN * np.abs(s1[~over[:n]]))
            and np.all(np.abs(s1 - s2)[over[:n]] > 2 * CRITICAL_MARGIN * np.abs(s1[over[:n]]))):
        return None
    return np.concatenate([s1, s2]), np.concatenate([y1, y2])


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
def _newton_terms(s, i, w2, G, E, d0, u_i, y, with_derivative):  # pragma: no cover - compiled
    """At the pole ``s`` of mode ``i``: ``y = (I + s E P)⁻¹ E g_i`` into ``y`` and, with ``with_derivative``,
    ``(e_iᵀx, xᵀx, xᵀC_rr x)`` (module docstring)."""
    k, r = G.shape
    P = np.zeros((r, r), dtype=np.complex128)
    S2 = np.zeros((r, r), dtype=np.complex128)
    S3 = np.zeros((r, r), dtype=np.complex128)
    for j in range(k):       # P = Σ_{j≠i} g_j g_jᵀ / D_j(s), S2 the same over D_j², S3 over D_j² / d⁰_j
        if j == i:
            continue
        inv = 1.0 / (s * s + d0[j] * s + w2[j])
        inv2 = inv * inv
        inv3 = d0[j] * inv2
        for p in range(r):
            gp = G[j, p]
            for q in range(r):
                P[p, q] += inv * gp * G[j, q]
                S2[p, q] += inv2 * gp * G[j, q]
                S3[p, q] += inv3 * gp * G[j, q]
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
    ex, xx, xdx, ePy = 0j, 0j, 0j, 0j
    for p in range(r):
        ex += u_i[p] * Py[p]
        for q in range(r):
            xx += y[p] * S2[p, q] * y[q]
            xdx += y[p] * S3[p, q] * y[q]
            ePy += Py[p] * E[p, q] * Py[q]
    return ex, xx, xdx + ePy


@numba.njit(cache=True, nogil=True)
def _newton(w2, G, E, d0, d, s, mode, u, steps):  # pragma: no cover - compiled
    """Newton's iteration on ``f_i`` (``i = mode[p]``) from each start ``s[p]``, until its step is below 1e-14 of
    it; the roots, the ``y`` at them and whether every root converged within ``steps``."""
    n, r = s.size, G.shape[1]
    y = np.zeros((n, r), dtype=np.complex128)
    yi = np.zeros(r, dtype=np.complex128)
    for p in range(n):
        i = mode[p]
        converged = False
        for _ in range(steps):
            ex, xx, xCx = _newton_terms(s[p], i, w2, G, E, d0, u[i], yi, True)
            si = s[p]
            f = si * si + si * d[i] + w2[i] - si * si * ex
            df = 2.0 * si + d[i] - 2.0 * si * ex + si * si * (2.0 * si * xx + xCx)
            step = f / df
            s[p] = si - step
            if abs(step) <= 1e-14 * abs(s[p]):
                converged = True
                break
        if not converged:
            return s, y, False
        _newton_terms(s[p], i, w2, G, E, d0, u[i], yi, False)    # y at the converged root
        y[p] = yi
    return s, y, True


def coupled_modes(w2: np.ndarray, damping: LowRankDamping, Fm: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Every pole, the eigenvectors ``V`` (2k × 2k, on the state ``(q, q̇)``) and the input weights in pole
    coordinates (2k × m) of the modal system, in the layout of the decoupled route (every ``s₁``, then every
    ``s₂``: an underdamped mode's conjugate), or ``None`` (module docstring)."""
    k = w2.size
    found = coupled_poles(w2, damping, None)
    if found is None:
        return None
    lam, y = found
    X, Bu = _vectors(lam[:k], np.arange(k), y[:k], damping, w2, Fm)
    X2, Bu2 = X.conj(), Bu.conj()
    twice = np.flatnonzero(lam[k:] != lam[:k].conj())         # overdamped: the second real root's own
    if twice.size:
        X2[twice], Bu2[twice] = _vectors(lam[k:][twice], twice, y[k:][twice], damping, w2, Fm)
    Vq = np.concatenate([X.T, X2.T], axis=1)                  # columns v_p
    V = np.vstack([Vq, Vq * lam[None, :]])
    return lam, V, np.vstack([Bu, Bu2])


def _vectors(s: np.ndarray, mode: np.ndarray, y: np.ndarray, damping: LowRankDamping, w2: np.ndarray,
             Fm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The right eigenvectors (rows, over the modes) of the roots ``s`` of the modes ``mode`` with their ``y``,
    and their input weights (module docstring)."""
    G, E, d0 = damping.G, damping.E, damping.diagonal
    rows = np.arange(s.size)
    X = -(s[:, None] * _others(s, mode, d0, w2)) * (y @ G.T)     # row p: v_p over the modes j
    X[rows, mode] = 1.0
    # vᵀ Q'(s) v = 2s vᵀv + vᵀ C_m v, C_m v = d⁰ ∘ v + G E Gᵀ v
    Gv = X @ G
    norm = 2.0 * s * np.einsum("ij,ij->i", X, X) + np.einsum("ij,j,ij->i", X, d0, X) \
        + np.einsum("ia,ab,ib->i", Gv, E, Gv)
    return X, (X @ Fm) / norm[:, None]
