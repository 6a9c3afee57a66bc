r"""A family's undamped modes continued in the axial load: Chebyshev panels in ``U = N L²/EI``.

On a beam without attachments (no point masses or springs, no weak segments, no rotary inertia, each end's
springs zero or rigid) the unit beam's stiffness is ``K̃ = B₄ − U A₂ + κ M̃`` with ``M̃ = diag(V)``
(:mod:`ebb_model.space.discretisation`, ``κ = k_f/EI``): the foundation only shifts every ``ω̃²`` by ``κ`` (the shapes do
not move, and the Richardson extrapolation keeps the shift), and the modes are analytic in ``U`` away from buckling.
An identification with ``N`` unknown asks a new ``U`` at every evaluation (``N/EI`` moves with both); instead of
one eigen-decomposition of the Richardson pair each, the modes on a panel ``[jW, (j+1)W]`` of ``U``
(:data:`PANEL_WIDTH`) are interpolated in barycentric form from :data:`PANEL_DEGREE` ``+ 1`` Chebyshev points
(:func:`chebyshev_panel`), the shapes' signs aligned from point to point.

Measured on the blind bench's 60-node clamped–pinned grid (121 unknowns on the finer grid): degree 6 on a width
of 12 already meets the direct decomposition's own round-off (``ω²`` 1.7e-10 relative, shapes 1.5e-9 of each
mode's largest entry); degree 10 on a width of 48 does too.  What is left is that round-off, carried by the
barycentric weights (Lebesgue constant 2.4 for :data:`PANEL_DEGREE`): on pinned–pinned beams, whose FD modes are
sines with closed-form ``ω²``, the simulated outputs are as far from the closed form's either way (1e-9–1e-7
over 3000 samples, direct or continued).  But the continued modes are smooth in ``U`` where the direct ones are
not: an ``N`` moved by 1e-12 of itself moved the outputs by up to 2e-8 (noise), now by 1e-12 (the physics) —
difference Jacobians in ``EI`` and ``N`` no longer see the eigen-solver.

A panel is only taken when its points' modes are clearly positive (:data:`SMALLEST_FREQUENCY`: not a free–free
beam's rigid-body modes, not at buckling) and two further direct solves inside it agree with the interpolant to
:data:`CHECK_FREQUENCIES` and :data:`CHECK_SHAPES` times the direct route's own round-off; else every ``U`` in
it is solved directly.  Which route a ``U`` takes depends on its panel alone, so a result never depends on the
evaluations before it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["PANEL_WIDTH", "PANEL_DEGREE", "CHECK_FREQUENCIES", "CHECK_SHAPES", "SMALLEST_FREQUENCY", "Panel",
           "Combination", "panel_index", "chebyshev_points", "lebesgue_constant", "chebyshev_panel", "aligned",
           "positive", "barycentric", "combined", "check_points"]

#: Width of a panel in ``U = N L²/EI`` (the pinned–pinned beam's first mode moves by ``U/π²`` of itself).
PANEL_WIDTH = 8.0

#: Degree of a panel's interpolant (``PANEL_DEGREE + 1`` direct solves per panel).
PANEL_DEGREE = 10

#: Largest relative difference of an ``ω²`` (Richardson or the finer grid's) between the interpolant and a direct
#: solve at a panel's check points, in units of the direct route's own round-off bound ``eps·κ``
#: (``κ = ω²_max/ω²_min`` of the finer grid's modes; a backward-stable solve is off by about that): measured up to
#: 1.7 (tension, compression, cantilevers, 30–200 nodes).
CHECK_FREQUENCIES = 8.0

#: Largest difference of a shape between the interpolant and a direct solve at a check point, relative to the
#: mode's largest entry, in the same units: measured up to 2.2 where the finer grid keeps half its modes, up to
#: 35 where it keeps all (a grid above 100 nodes pairs with a coarser one), from the highest modes' shapes.
CHECK_SHAPES = 100.0

#: Smallest ``ω²`` of a panel point relative to its largest for which the panel is taken: a free–free beam's
#: rigid-body modes (``ω² ≈ ±1e-7`` of round-off) or a mode near buckling are solved directly.
SMALLEST_FREQUENCY = 1e-8

#: ``(ω²_R, ω²_f, Ψ)``: the Richardson values, the finer grid's own and its mass-normalised shapes.
Modes = tuple[np.ndarray, np.ndarray, np.ndarray]


def panel_index(U: float) -> int:
    """The panel of ``U``: ``⌊U / W⌋``."""
    return math.floor(U / PANEL_WIDTH)


@dataclass(frozen=True)
class Panel:
    """The modes at a panel's Chebyshev points (``nodes``, with their barycentric ``weights``), the shapes'
    signs aligned from point to point."""

    nodes: np.ndarray
    weights: np.ndarray
    frequencies2: np.ndarray        # (points, modes)
    fine_frequencies2: np.ndarray   # (points, modes)
    shapes: np.ndarray              # (points, unknowns, modes)

    def at(self, U: float) -> Modes:
        """The interpolated modes at ``U`` (inside the panel; at a point, its own values)."""
        w2, w2_f, shapes = self.interpolant(U)
        return w2, w2_f, shapes.full()

    def interpolant(self, U: float) -> tuple[np.ndarray, np.ndarray, Combination]:
        """:meth:`at` with the shapes left as their :class:`Combination` (formed whole or by rows when read)."""
        c = barycentric(U, self.nodes, self.weights)
        if isinstance(c, int):
            own = Combination(None, self.shapes[c].copy())    # (a view would keep the whole stack alive)
            return self.frequencies2[c].copy(), self.fine_frequencies2[c].copy(), own
        return c @ self.frequencies2, c @ self.fine_frequencies2, Combination(c, self.shapes)


@dataclass(frozen=True, eq=False)
class Combination:
    """``Σ_j c_j stack[j]`` of a panel's shapes at one ``U`` (``c`` ``None``: ``stack`` is the point's own
    shapes), formed whole (:meth:`full`) or on a few rows (:meth:`rows`: a model reads the shapes where its loads
    and sensors are, ``O(rows · modes)`` of the ``O(unknowns · modes)``).  Two roundings of one combination (they
    may differ in the last bit); each a pure function of its arguments, whatever was formed before."""

    c: np.ndarray | None
    stack: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        """``(unknowns, modes)`` of the shapes."""
        return self.stack.shape[-2], self.stack.shape[-1]

    def full(self) -> np.ndarray:
        """The shapes (unknowns × modes), a new array."""
        return self.stack.copy() if self.c is None else combined(self.c, self.stack)

    def rows(self, J: np.ndarray) -> np.ndarray:
        """The shapes' rows ``J`` (len(J) × modes), a new array."""
        return self.stack[J] if self.c is None else combined(self.c, self.stack[:, J])


def barycentric(U: float, nodes: np.ndarray, weights: np.ndarray) -> int | np.ndarray:
    """The panel point that ``U`` is (its index), else the weights of the points' values in the barycentric
    interpolant at ``U``."""
    diff = U - nodes
    if not diff.all():
        return int(np.flatnonzero(diff == 0.0)[0])
    c = weights / diff
    c /= c.sum()
    return c


def combined(c: np.ndarray, stack: np.ndarray) -> np.ndarray:
    """``Σ_j c_j stack[j]`` for a stack of matrices (the product ``np.tensordot(c, stack, axes=1)`` forms)."""
    return np.dot(c[None, :], stack.reshape(c.size, -1)).reshape(stack.shape[1:])


def check_points(nodes: np.ndarray) -> tuple[float, float]:
    """Where a panel is checked against direct solves: the midpoints of its outermost and of its central
    interval between points."""
    middle = PANEL_DEGREE // 2
    return float(0.5 * (nodes[0] + nodes[1])), float(0.5 * (nodes[middle] + nodes[middle + 1]))


def chebyshev_points(a: float, b: float, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Chebyshev points of the second kind on ``[a, b]`` and their barycentric weights."""
    j = np.arange(degree + 1)
    nodes = 0.5 * (a + b) + 0.5 * (b - a) * np.cos(np.pi * j / degree)
    weights = (-1.0) ** j
    weights[[0, -1]] *= 0.5
    return nodes, weights


def lebesgue_constant(degree: int = PANEL_DEGREE) -> float:
    """``Λ = max Σ|ℓ_j|`` over a panel of the Chebyshev points' Lagrange basis (:func:`chebyshev_points`): how
    much the interpolant can magnify its points' round-off (2.42 for :data:`PANEL_DEGREE`)."""
    nodes, w = chebyshev_points(0.0, 1.0, degree)
    x = np.linspace(0.0, 1.0, 4001)
    x = x[np.min(np.abs(x[:, None] - nodes[None, :]), axis=1) > 1e-9]
    c = w[None, :] / (x[:, None] - nodes[None, :])
    return float(np.max(np.sum(np.abs(c), axis=1) / np.abs(np.sum(c, axis=1))))


def aligned(psi: np.ndarray, reference: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """``psi`` with each column's sign that of ``reference``'s (by their ``diag(V)`` product)."""
    sign = np.where(np.einsum("ij,i,ij->j", reference, lengths, psi) < 0.0, -1.0, 1.0)
    return psi * sign


def _agree(interpolated: Modes, direct: Modes, lengths: np.ndarray) -> bool:
    """Whether the interpolant meets a direct solve to :data:`CHECK_FREQUENCIES` and :data:`CHECK_SHAPES`."""
    w2_f = direct[1]
    scale = np.finfo(float).eps * float(np.max(w2_f) / np.min(w2_f))
    for w_i, w_d in zip(interpolated[:2], direct[:2]):
        if np.max(np.abs(w_i / w_d - 1.0)) > CHECK_FREQUENCIES * scale:
            return False
    psi_i, psi_d = interpolated[2], aligned(direct[2], interpolated[2], lengths)
    return bool(np.max(np.abs(psi_i - psi_d) / np.max(np.abs(psi_d), axis=0)) <= CHECK_SHAPES * scale)


def positive(w2_f: np.ndarray) -> bool:
    """Whether every ``ω²`` exceeds :data:`SMALLEST_FREQUENCY` of the largest."""
    return bool(np.min(w2_f) > SMALLEST_FREQUENCY * np.max(w2_f))


def chebyshev_panel(solve: Callable[[float], Modes], panel: int, lengths: np.ndarray) -> Panel | None:
    """The interpolant of ``solve`` (``U`` → the direct modes) on ``panel``, or ``None`` when a mode is not
    clearly positive at a point (:data:`SMALLEST_FREQUENCY`) or the interpolant misses a direct solve at a check
    point (the midpoints of the outermost and of the central interval between points).

    ``lengths`` are the finer grid's control lengths ``V`` (``M̃ = diag(V)``), for the shapes' signs.
    """
    a = panel * PANEL_WIDTH
    nodes, weights = chebyshev_points(a, a + PANEL_WIDTH, PANEL_DEGREE)
    w2, w2_f = [], []
    psi: list[np.ndarray] = []
    for U in nodes:
        r, f, s = solve(float(U))
        if not positive(f):
            return None
        w2.append(r)
        w2_f.append(f)
        psi.append(s if not psi else aligned(s, psi[-1], lengths))
    out = Panel(nodes, weights, np.array(w2), np.array(w2_f), np.array(psi))
    for arr in (out.nodes, out.weights, out.frequencies2, out.fine_frequencies2, out.shapes):
        arr.setflags(write=False)
    for U in check_points(nodes):
        direct = solve(U)
        if not positive(direct[1]) or not _agree(out.at(U), direct, lengths):
            return None
    return out
