r"""A beam with one or two point masses or springs: its modes from the beam without them, by rank-one updates.

A point mass ``m`` or a spring to ground ``k`` at ``x`` adds ``m v vᵀ`` to ``M̃`` or ``k v vᵀ`` to ``K̃``
(:mod:`ebb_model.space.discretisation`: ``v`` the hat weights of ``x`` over the unknowns).  With *every* mode of the
beam without it (``K̃₀ Φ = M̃₀ Φ Λ``, ``ΦᵀM̃₀Φ = I``) and ``z = Φᵀ v``, the inverted problem ``M̃ ψ = μ K̃ ψ``
(``μ = 1/ω²``, the form that resolves the lowest ``ω²`` to relative accuracy,
:func:`~ebb_model.space.richardson_pair.lowest_modes`) becomes a diagonal matrix plus a rank-one term:

* a spring: ``(Λ + k z zᵀ)⁻¹ = Λ⁻¹ − τ w wᵀ`` with ``w = Λ⁻¹ z``, ``τ = k/(1 + k zᵀΛ⁻¹z)`` (Sherman–Morrison); its
  unit eigenvectors ``y`` give ``ψ = Φ y``;
* a point mass: ``Λ^{-1/2}(I + m z zᵀ)Λ^{-1/2} = Λ⁻¹ + m w wᵀ`` with ``w = Λ^{-1/2} z``; its unit eigenvectors
  ``t`` give ``ψ = Φ Λ^{-1/2} t / √μ``.

Both are solved by their secular equation (:mod:`ebb_model.modal.secular`: every eigenvalue to relative accuracy,
orthogonal vectors), ``O(n²)`` instead of a decomposition's ``O(n³)``.  The beam without the attachment has
the axial load of the member: its full bases on both grids of the Richardson pair come from a Chebyshev panel in
``U = N L²/EI`` (:class:`BasisPanel`, as :mod:`ebb_model.modal.mode_continuation` continues the lowest modes), a
foundation shifting every ``ω²``.

Two attachments are two updates (:func:`updated_modes`: every mode after the first).  Measured on the blind bench's
grid (60 nodes, clamped–pinned, 121 unknowns on the finer grid), springs of 0.1–1000 and masses of 0.001–0.3 per
unit ``EI``, ``ρA`` anywhere, ``U`` 0.4–5: the Richardson ``ω²`` within 1.5e-10 of the direct decompositions', the
shapes within 2.4e-9 of each mode's largest entry — the direct route's own round-off (``eps·ω²_max/ω²_min`` =
7e-10); 0.46 ms a member against 1.67 ms decomposed (two attachments 0.81 against 1.81).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from .mode_continuation import (CHECK_FREQUENCIES, PANEL_DEGREE, PANEL_WIDTH, aligned, barycentric, check_points,
                                chebyshev_points, combined, positive)
from .secular import rank_one_eigen

__all__ = ["Basis", "BasisPanel", "basis_panel", "rank_one_modes", "updated_modes", "CHECK_BASIS_SHAPES",
           "MAX_ATTACHMENTS"]

#: Most attachments updated one after the other (each but the last needs every updated mode: ``O(n³)``, a few
#: times cheaper than a decomposition at these sizes); beyond, the beam is decomposed directly.
MAX_ATTACHMENTS = 2

#: Largest difference of a shape between a :class:`BasisPanel`'s interpolant and a direct solve at a check point,
#: relative to the mode's largest entry, in units of ``eps·ω²_max/ω²_min`` of the finer grid: the highest modes'
#: shapes are resolved by a direct solve only to tens of that (measured up to 95: 30–150 nodes, clamped, pinned,
#: free ends); they enter the lowest modes of the beam with its attachment by their small share of it.
CHECK_BASIS_SHAPES = 1e3


@dataclass(frozen=True)
class Basis:
    """Every mode of one grid's unit beam: ``frequencies2`` (``ω̃²``, ascending) and the mass-normalised ``shapes``
    (unknowns × modes)."""

    frequencies2: np.ndarray
    shapes: np.ndarray


@dataclass(frozen=True)
class BasisPanel:
    """The full bases of both grids of the Richardson pair at a panel's Chebyshev points (``nodes``, barycentric
    ``weights``), the shapes' signs aligned from point to point: ``(points, modes)`` values and
    ``(points, unknowns, modes)`` shapes of the finer grid, then of the coarser."""

    nodes: np.ndarray
    weights: np.ndarray
    fine_frequencies2: np.ndarray
    fine_shapes: np.ndarray
    coarse_frequencies2: np.ndarray
    coarse_shapes: np.ndarray

    def at(self, U: float) -> tuple[Basis, Basis]:
        """The interpolated bases ``(fine, coarse)`` at ``U`` (inside the panel; at a point, its own)."""
        c = barycentric(U, self.nodes, self.weights)
        if isinstance(c, int):
            return (Basis(self.fine_frequencies2[c], self.fine_shapes[c]),
                    Basis(self.coarse_frequencies2[c], self.coarse_shapes[c]))
        return (Basis(c @ self.fine_frequencies2, combined(c, self.fine_shapes)),
                Basis(c @ self.coarse_frequencies2, combined(c, self.coarse_shapes)))


def _agree(interpolated: tuple[Basis, Basis], direct: tuple[Basis, Basis],
           lengths: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether every ``ω²`` agrees to :data:`~ebb_model.modal.mode_continuation.CHECK_FREQUENCIES` and every shape to
    :data:`CHECK_BASIS_SHAPES` times ``eps·ω²_max/ω²_min`` of the finer grid."""
    w2_f = direct[0].frequencies2
    scale = np.finfo(float).eps * float(np.max(w2_f) / np.min(w2_f))
    for got, want, V in zip(interpolated, direct, lengths):
        if np.max(np.abs(got.frequencies2 / want.frequencies2 - 1.0)) > CHECK_FREQUENCIES * scale:
            return False
        psi = aligned(want.shapes, got.shapes, V)
        if np.max(np.abs(got.shapes - psi) / np.max(np.abs(psi), axis=0)) > CHECK_BASIS_SHAPES * scale:
            return False
    return True


def basis_panel(solve: Callable[[float], tuple[Basis, Basis]], panel: int,
                lengths: tuple[np.ndarray, np.ndarray], modes: int) -> BasisPanel | None:
    """The interpolant of ``solve`` (``U`` → the direct full bases ``(fine, coarse)``) on ``panel``, or ``None``
    when one of the finer grid's lowest ``modes`` is not clearly positive at a point or the interpolant misses a
    direct solve at a check point (as :func:`~ebb_model.modal.mode_continuation.chebyshev_panel`, whose rules for the
    lowest modes these are); ``lengths`` are both grids' control lengths."""
    a = panel * PANEL_WIDTH
    nodes, weights = chebyshev_points(a, a + PANEL_WIDTH, PANEL_DEGREE)
    points: list[tuple[Basis, Basis]] = []
    for U in nodes:
        pair = solve(float(U))
        if not positive(pair[0].frequencies2[:modes]):
            return None
        if points:
            pair = tuple(Basis(b.frequencies2, aligned(b.shapes, prev.shapes, V))   # type: ignore[assignment]
                         for b, prev, V in zip(pair, points[-1], lengths))
        points.append(pair)
    out = BasisPanel(nodes, weights, *(np.array([p[g].frequencies2 if f == 0 else p[g].shapes for p in points])
                                       for g in (0, 1) for f in (0, 1)))
    for arr in (out.nodes, out.weights, out.fine_frequencies2, out.fine_shapes, out.coarse_frequencies2,
                out.coarse_shapes):
        arr.setflags(write=False)
    for U in check_points(nodes):
        direct = solve(U)
        if not positive(direct[0].frequencies2[:modes]) or not _agree(out.at(U), direct, lengths):
            return None
    return out


def rank_one_modes(basis: Basis, v: np.ndarray, kind: str, size: float, count: int, vectors: bool
                   ) -> tuple[np.ndarray, np.ndarray | None] | None:
    """The ``count`` lowest ``ω²`` (and, with ``vectors``, the mass-normalised shapes) of the unit beam of
    ``basis`` with a spring of stiffness ``size`` (``kind = "spring"``) or a point mass ``size`` (``"mass"``) on the
    hat weights ``v`` (module docstring); ``None`` when the secular equation has two coinciding poles."""
    lam, Phi = basis.frequencies2, basis.shapes
    J = np.flatnonzero(v)
    z = Phi[J].T @ v[J]
    n = lam.size
    if kind == "spring":
        w = z / lam
        tau = size / (1.0 + size * float(np.sum(z * z / lam)))
        found = rank_one_eigen(-1.0 / lam, w, tau, 0, count if vectors else 0)   # −A: ascending, lowest ω² first
        if found is None:
            return None
        beta, Y = found
        return -1.0 / beta[:count], (Phi @ Y if vectors else None)
    root = np.sqrt(lam)
    found = rank_one_eigen((1.0 / lam)[::-1], (z / root)[::-1], size, n - count if vectors else n, n)
    if found is None:
        return None
    mu, T = found
    mu = mu[::-1][:count]                                   # the largest μ, the lowest ω² first
    if not vectors:
        return 1.0 / mu, None
    T = T[::-1, ::-1]                                       # back to the basis' order, lowest ω² first
    return 1.0 / mu, (Phi / root[None, :]) @ T / np.sqrt(mu)[None, :]


def updated_modes(basis: Basis, changes: Sequence[tuple[str, float, np.ndarray]], count: int, vectors: bool
                  ) -> tuple[np.ndarray, np.ndarray | None] | None:
    """:func:`rank_one_modes` for the attachments ``changes`` (``(kind, size, v)`` each) one after the other: every
    mode of the beam with the first (its full basis), then the ``count`` lowest with both; ``None`` as there."""
    for kind, size, v in changes[:-1]:
        step = rank_one_modes(basis, v, kind, size, basis.frequencies2.size, True)
        if step is None or step[1] is None:
            return None
        basis = Basis(step[0], step[1])
    kind, size, v = changes[-1]
    return rank_one_modes(basis, v, kind, size, count, vectors)
