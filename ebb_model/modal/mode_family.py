r"""The beam's undamped modes: every parameter set's modes as one family.

The modes of a beam are those of its Richardson pair of grids (:mod:`ebb_model.space.richardson_pair`).

**The family.**  The undamped problem ``K ψ = ω² M ψ`` depends on the parameters through ratios only
(:mod:`ebb_model.space.discretisation`): ``K = EI K̃`` with ``K̃`` a function of ``U = N/EI`` (times ``L²``), the
foundation's ``k_f/EI``, the springs' ``k/EI`` and the ends' ``k_t/EI``, ``k_r/EI``; ``M = ρA M̃`` with ``M̃`` a
function of ``ρI/ρA`` and the point masses' ``m/ρA``.  Hence

.. math::  ω² = \frac{EI}{ρA}\,\tilde ω²,\qquad ψ = \tilde ψ / \sqrt{ρA},

``(ω̃², ψ̃)`` the modes of the *unit* beam (``EI = ρA = 1``, the same ratios).  The damping (``c``, ``η``) and the
positions of sensors and actuators do not enter.  So every parameter set with the same ratios — the
:class:`FamilyKey` — shares one eigen-decomposition of the Richardson pair: :func:`unit_modes`, a pure function
of the key memoised per process (the least recently used dropped beyond a budget of bytes), so a result never
depends on which evaluations came before (a resumed run, another worker, compute the same numbers).  An identification
with ``N`` known and no attached mass needs one decomposition for all its evaluations (the difference Jacobians'
steps in ``EI``, ``ρA``, ``c``, ``η`` and positions included); :func:`~ebb_model.modal.parameter_modes.family_modes`
scales it and builds the finer grid's damping, load and sensor rows for the parameter set at hand.

**The continuation.**  With ``N`` unknown every evaluation is a new member.  On a beam without attachments
(:func:`continuation_stem`) the members differ only in ``U = N L²/EI`` and ``k_f/EI``: their modes are taken
from a Chebyshev panel in ``U`` of the family without load (:func:`continuation_panel`,
:mod:`ebb_model.modal.mode_continuation`), shifted by ``k_f/EI``; a refused panel, ``U = 0`` and every other family are
decomposed directly.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from ..beam import End, PointMass, PointSpring, WeakSegment
from ..config import BeamConfig
from .attached_modes import MAX_ATTACHMENTS, Basis, BasisPanel, basis_panel, updated_modes
from .coupled_modes import MAX_RANK
from ..memo import memoised
from .mode_continuation import PANEL_DEGREE, Combination, Panel, chebyshev_panel, panel_index
from ..theta.modal_form import off_diagonal_magnitude
from ..space.richardson_pair import companion_nodes, extrapolated, lowest_modes, richardson_with_fine
from ..space.discretisation import (Grid, SemiDiscreteBeam, assemble_matrices, grid, grid_nodes, hat_weights,
                                   unknown_nodes)

__all__ = ["FamilyKey", "family_key", "UnitModes", "unit_pair", "unit_modes", "continuation_stem",
           "continuation_panel", "attachment", "attached_panel"]


@dataclass(frozen=True)
class FamilyKey:
    """What the undamped modes depend on besides ``EI`` and ``ρA`` (module docstring): the geometry, the ends
    with their springs per ``EI``, ``N``, ``k_f`` per ``EI`` and ``ρI`` per ``ρA``, the point masses per ``ρA``,
    the springs per ``EI`` (names dropped) and the weak segments."""

    length: float
    nodes: int
    left: End
    right: End
    N: float
    kf: float
    rhoI: float
    masses: tuple[PointMass, ...]
    springs: tuple[PointSpring, ...]
    segments: tuple[WeakSegment, ...]
    #: the fields' hash, computed once (a memo looks a key up a few times per evaluation)
    digest: int = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "digest", hash((self.length, self.nodes, self.left, self.right, self.N, self.kf,
                                                 self.rhoI, self.masses, self.springs, self.segments)))

    def __hash__(self) -> int:
        return self.digest

    def __reduce__(self) -> tuple[type, tuple]:
        # built again where it is unpickled (a worker): a string's hash differs from process to process, so the
        # digest must be that process's — a pickled one never matched that process's own keys
        return (FamilyKey, (self.length, self.nodes, self.left, self.right, self.N, self.kf, self.rhoI, self.masses,
                            self.springs, self.segments))


def family_key(config: BeamConfig, p: Mapping[str, float]) -> FamilyKey:
    """The :class:`FamilyKey` of ``config`` with the (resolved) parameter values ``p``."""
    EI, rhoA = p["EI"], p["rhoA"]
    g = config.beam

    def end(e: End) -> End:
        return End(e.kind, e.kt / EI, e.kr / EI)

    return FamilyKey(g.length, g.nodes, end(g.left), end(g.right), p["N"] / EI, p["kf"] / EI, p["rhoI"] / rhoA,
                     tuple(PointMass("", m.x, m.mass / rhoA) for m in config.masses),
                     tuple(PointSpring("", s.x, s.k / EI) for s in config.springs),
                     tuple(replace(w, name="") for w in config.weak_segments))


@dataclass(frozen=True, eq=False)
class UnitModes:
    """The Richardson modes of a family's unit beam (``EI = ρA = 1``): ``frequencies2`` (``ω̃²``, as many as the
    config's grid has unknowns) and ``shapes`` (``ψ̃``, mass-normalised, on the ``fine`` unit beam of the pair;
    continued modes keep them as their panel's :class:`~ebb_model.modal.mode_continuation.Combination`, formed whole
    when first read, by rows in :meth:`shape_rows`).  Read-only arrays (shared by every caller).  The modal
    damping's unit matrices are formed when first read (a beam without Kelvin–Voigt damping and with
    ``M̃ = diag(V)`` needs the diagonal of the viscous one only); the memo's budget counts the fields and the
    shapes, not these."""

    frequencies2: np.ndarray
    #: the shapes, or the combination of a panel's that forms them
    source: np.ndarray | Combination
    #: the ``ω̃²`` of the ``fine`` grid itself, as many (``ψ̃ᵀ K̃ ψ̃``)
    fine_frequencies2: np.ndarray
    #: the family
    key: FamilyKey
    #: ``V`` the fine grid's control lengths
    lengths: np.ndarray
    #: ``M̃ = diag(V)`` exactly (no point masses, no rotary inertia): viscous damping alone is mass-proportional
    viscous_is_mass: bool
    #: the ``fine`` unit beam when the decomposition built it, else ``None`` (built when first read)
    built: SemiDiscreteBeam | None = field(default=None, repr=False)

    @functools.cached_property
    def fine(self) -> SemiDiscreteBeam:
        """The finer grid's unit beam (:func:`_unit_beam`)."""
        return self.built if self.built is not None else _unit_beam(self.key, _fine_nodes(self.key))

    @property
    def x(self) -> np.ndarray:
        """The finer grid's nodes, ends included."""
        return _fine_grid(self.key).x

    @property
    def unknown(self) -> np.ndarray:
        """The finer grid's unknown nodes (:func:`~ebb_model.space.discretisation.unknown_nodes`)."""
        return _fine_grid(self.key).unknown

    @property
    def nbytes(self) -> int:
        """The bytes of the arrays it holds (what a memo counts; the grid's are the grid memo's): the shapes
        counted whole, formed or not, and a combination's panel stack too — it stays alive with the member even
        when the panel memo has dropped it, so the memo's budget bounds what it keeps."""
        source = self.source if isinstance(self.source, np.ndarray) else self.source.stack
        return self.frequencies2.nbytes + max(source.nbytes, 8 * math.prod(self.source.shape)) \
            + self.fine_frequencies2.nbytes

    @functools.cached_property
    def shapes(self) -> np.ndarray:
        """``ψ̃`` (unknowns of the finer grid × modes)."""
        return self.source if isinstance(self.source, np.ndarray) else _read_only(self.source.full())

    def shape_rows(self, J: np.ndarray) -> np.ndarray:
        """``ψ̃[J]`` — from the panel's combination for continued modes (the same numbers whether
        :attr:`shapes` was formed or not)."""
        return self.source[J] if isinstance(self.source, np.ndarray) else self.source.rows(J)

    @functools.cached_property
    def viscous(self) -> np.ndarray:
        """``ψ̃ᵀ diag(V) ψ̃``: the modal damping of ``c`` per unit ``ρA``."""
        psi = self.shapes
        return _read_only(psi.T @ (self.lengths[:, None] * psi))

    @functools.cached_property
    def viscous_diagonal(self) -> np.ndarray:
        """The diagonal of :attr:`viscous`, ``O(n k)``."""
        psi = self.shapes
        return _read_only(np.einsum("ij,ij->j", psi, self.lengths[:, None] * psi))

    @functools.cached_property
    def bending(self) -> np.ndarray:
        """``ψ̃ᵀ C̃ ψ̃``: the modal damping of ``η EI`` per unit ``ρA``."""
        return _read_only(self.shapes.T @ self.fine.C @ self.shapes)

    @functools.cached_property
    def mass_excess(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(J, R_J)``: the unknowns ``J`` where ``M̃`` differs from ``diag(V)`` (the point masses) and ``M̃ − diag(V)``
        on them, or ``None`` when more than :data:`~ebb_model.modal.coupled_modes.MAX_RANK` do (rotary inertia).
        Nothing when :attr:`viscous_is_mass` (``M̃`` is assembled as ``diag(V)`` then)."""
        if self.viscous_is_mass:
            return _read_only(np.zeros(0, dtype=np.intp)), _read_only(np.zeros((0, 0)))
        return _excess(self.fine.M, self.fine.M - np.diag(self.lengths))

    @functools.cached_property
    def stiffness_excess(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(J, R_J)``: the unknowns ``J`` where ``K̃`` differs from the Kelvin–Voigt ``C̃`` (springs to ground; an
        elastic end's springs enter both through the same ghost rows) and ``K̃ − C̃`` on them, or ``None`` when more
        than :data:`~ebb_model.modal.coupled_modes.MAX_RANK` do (axial load, a foundation)."""
        return _excess(self.fine.K, self.fine.K - self.fine.C)

    @functools.cached_property
    def viscous_off(self) -> float:
        """The largest magnitude off the diagonal of :attr:`viscous` (bounds the modal damping's)."""
        return off_diagonal_magnitude(self.viscous)

    @functools.cached_property
    def bending_off(self) -> float:
        """The largest magnitude off the diagonal of :attr:`bending`."""
        return off_diagonal_magnitude(self.bending)


#: Relative size (to the largest entry of the matrix) below which an entry of ``M̃ − diag(V)`` or ``K̃ − C̃`` counts as
#: zero: both sides are assembled from the same lengths and stiffnesses, equal up to one rounding per entry.
_EXCESS_RTOL = 1e-12


def _excess(A: np.ndarray, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(J, delta_JJ)`` for the rows ``J`` of ``delta`` with an entry above :data:`_EXCESS_RTOL` of ``A``'s
    largest, or ``None`` beyond :data:`~ebb_model.modal.coupled_modes.MAX_RANK` rows."""
    scale = max(float(np.max(np.abs(A), initial=0.0)), float(np.finfo(float).tiny))
    J = np.flatnonzero(np.max(np.abs(delta), axis=1, initial=0.0) > _EXCESS_RTOL * scale)
    if J.size > MAX_RANK:
        return None
    return _read_only(J), _read_only(delta[np.ix_(J, J)])


def _read_only(a: np.ndarray) -> np.ndarray:
    """``a``, made read-only (shared by every caller of a memoised result)."""
    a.setflags(write=False)
    return a


def _unit_beam(key: FamilyKey, nodes: int) -> SemiDiscreteBeam:
    """The family's unit beam on ``nodes`` interior points: ``M̃``, ``K̃`` and, as ``C``, the Kelvin–Voigt damping
    per unit ``η EI`` (``c = 0``, ``η = 1``); no loads, no sensors.  Read-only arrays."""
    values = {"EI": 1.0, "rhoA": 1.0, "c": 0.0, "eta": 1.0, "N": key.N, "rhoI": key.rhoI, "kf": key.kf}
    M, C, K, unknown = assemble_matrices(key.length, nodes, key.left, key.right, key.masses, key.springs,
                                         key.segments, values)
    nu = unknown.size
    beam = SemiDiscreteBeam(M, C, K, np.zeros((nu, 0)), np.zeros((0, nu)), (), grid_nodes(key.length, nodes),
                            unknown, (), ())
    for a in (beam.M, beam.C, beam.K, beam.x, beam.unknown):
        a.setflags(write=False)
    return beam


@memoised
def unit_pair(key: FamilyKey) -> tuple[SemiDiscreteBeam, SemiDiscreteBeam]:
    """The family ``key``'s unit beams on the config's grid and on its companion grid (memoised per process)."""
    return _unit_beam(key, key.nodes), _unit_beam(key, companion_nodes(key.nodes))


def _solve_pair(own: SemiDiscreteBeam, companion: SemiDiscreteBeam
                ) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], SemiDiscreteBeam]:
    """``((ω²_R, ω²_f, Ψ), fine)``: the Richardson pair's eigen-decompositions and its finer beam."""
    coarse, fine = sorted((own, companion), key=lambda b: b.n_unknowns)
    return richardson_with_fine(coarse, fine, own.n_unknowns), fine


def _direct_modes(key: FamilyKey) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(ω²_R, ω²_f, Ψ)`` of the family ``key`` by the Richardson pair's eigen-decompositions (not memoised)."""
    return _solve_pair(_unit_beam(key, key.nodes), _unit_beam(key, companion_nodes(key.nodes)))[0]


def _fine_nodes(key: FamilyKey) -> int:
    """Interior nodes of the finer grid of ``key``'s Richardson pair."""
    return max(key.nodes, companion_nodes(key.nodes))


def _lengths(key: FamilyKey, nodes: int) -> np.ndarray:
    """The control lengths ``V`` of ``key``'s beam on ``nodes`` interior points (read-only)."""
    return grid(key.length, nodes, key.left, key.right).V


def _fine_grid(key: FamilyKey) -> Grid:
    """The finer grid of ``key``'s Richardson pair."""
    return grid(key.length, _fine_nodes(key), key.left, key.right)


#: Largest panel (:mod:`ebb_model.modal.mode_continuation`) in bytes: beyond it (a finer grid of about 400 unknowns) a
#: family is solved directly at every ``U``.
_MAX_PANEL_BYTES = 16 * 2 ** 20


def continuation_stem(key: FamilyKey) -> FamilyKey | None:
    """``key`` without its axial load and foundation (``N = k_f = 0``) when its modes are continued in ``U``
    (:mod:`ebb_model.modal.mode_continuation`: no point masses or springs, no weak segments, no rotary inertia, each
    end's springs zero or rigid, a panel within :data:`_MAX_PANEL_BYTES`), else ``None``."""
    if key.masses or key.springs or key.segments or key.rhoI != 0.0:
        return None
    if any(k not in (0.0, math.inf) for e in (key.left, key.right) for k in (e.kt, e.kr)):
        return None
    fine = _fine_nodes(key)
    if 8 * (PANEL_DEGREE + 1) * (fine + 2) * key.nodes > _MAX_PANEL_BYTES:
        return None
    return FamilyKey(key.length, key.nodes, key.left, key.right, 0.0, 0.0, key.rhoI, key.masses, key.springs,
                     key.segments)


@memoised
def continuation_panel(where: tuple[FamilyKey, int]) -> Panel | None:
    """The Chebyshev panel (:func:`~ebb_model.modal.mode_continuation.chebyshev_panel`) of the stem
    (:func:`continuation_stem`) and panel index ``where``, or ``None`` when it is refused (memoised per process)."""
    stem, index = where
    L2 = stem.length ** 2
    return chebyshev_panel(lambda U: _direct_modes(replace(stem, N=U / L2)), index,
                           _lengths(stem, _fine_nodes(stem)))


def _continued(key: FamilyKey) -> tuple[np.ndarray, np.ndarray, np.ndarray | Combination] | None:
    """``(ω²_R, ω²_f, Ψ)`` of ``key`` from its stem's panel (at ``U = 0``, a panel point, the stem's own modes),
    shifted by the foundation's ``k_f/EI``; ``None`` when ``key`` is solved directly (not continued, a refused
    panel, or the stem itself)."""
    stem = continuation_stem(key)
    if stem is None:
        return None
    U = key.N * key.length ** 2
    psi: np.ndarray | Combination
    if U == 0.0:
        if key.kf == 0.0:
            return None
        base = unit_modes(stem)
        w2, w2_f, psi = base.frequencies2, base.fine_frequencies2, base.shapes
    else:
        panel = continuation_panel((stem, panel_index(U)))
        if panel is None:
            return None
        w2, w2_f, psi = panel.interpolant(U)
    return w2 + key.kf, w2_f + key.kf, psi


def attachment(key: FamilyKey) -> tuple[FamilyKey, tuple[tuple[str, float, float], ...]] | None:
    """``(stem, changes)`` when ``key`` is a continued beam (:func:`continuation_stem`, the stem) with one or
    :data:`~ebb_model.modal.attached_modes.MAX_ATTACHMENTS` point masses or springs of positive size added — ``changes``
    their ``(kind, x, size)``, ``kind`` ``"mass"`` or ``"spring"``, masses first —, whose modes are then rank-one
    updates of the stem's (:mod:`ebb_model.modal.attached_modes`); else ``None``."""
    changes = tuple(("mass", m.x, m.mass) for m in key.masses) + tuple(("spring", k.x, k.k) for k in key.springs)
    if not 1 <= len(changes) <= MAX_ATTACHMENTS or not all(size > 0.0 for _, _, size in changes):
        return None
    stem = continuation_stem(replace(key, masses=(), springs=()))
    if stem is None or 8 * (PANEL_DEGREE + 1) * _fine_nodes(stem) ** 2 * 2 > _MAX_PANEL_BYTES:
        return None
    return stem, changes


def _full_bases(key: FamilyKey) -> tuple[Basis, Basis]:
    """Every mode of ``key``'s unit beam on the finer and on the coarser grid of its Richardson pair (direct)."""
    own, companion = unit_pair(key)
    coarse, fine = sorted((own, companion), key=lambda b: b.n_unknowns)
    return Basis(*lowest_modes(fine, fine.n_unknowns)), Basis(*lowest_modes(coarse, coarse.n_unknowns))


@memoised
def attached_panel(where: tuple[FamilyKey, int]) -> BasisPanel | None:
    """The full bases' Chebyshev panel (:func:`~ebb_model.modal.attached_modes.basis_panel`) of the stem and panel index
    ``where``, or ``None`` when it is refused (memoised per process)."""
    stem, index = where
    L2 = stem.length ** 2
    grids = sorted((stem.nodes, companion_nodes(stem.nodes)), reverse=True)
    return basis_panel(lambda U: _full_bases(replace(stem, N=U / L2)), index,
                       (_lengths(stem, grids[0]), _lengths(stem, grids[1])),
                       unknown_nodes(stem.nodes, stem.left, stem.right).size)


def _attached(key: FamilyKey) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(ω²_R, ω²_f, Ψ)`` of ``key`` by rank-one updates of its stem's full bases (:func:`attachment`,
    :mod:`ebb_model.modal.attached_modes`), shifted by the foundation's ``k_f/EI``; ``None`` when ``key`` is decomposed
    directly (not one or two attachments on a continued beam, a refused panel, coinciding poles)."""
    found = attachment(key)
    if found is None:
        return None
    stem, changes = found
    U = key.N * key.length ** 2
    panel = attached_panel((stem, panel_index(U)))
    if panel is None:
        return None
    bases = panel.at(U)
    (fine_nodes, coarse_nodes) = sorted((key.nodes, companion_nodes(key.nodes)), reverse=True)
    n_modes = grid(key.length, key.nodes, key.left, key.right).unknown.size
    solved = []
    for basis, nodes in zip(bases, (fine_nodes, coarse_nodes)):
        unknown = grid(key.length, nodes, key.left, key.right).unknown
        wanted = n_modes if nodes == fine_nodes else min(unknown.size, n_modes)
        shifted = Basis(basis.frequencies2 + key.kf, basis.shapes)
        solved.append(updated_modes(shifted, [(kind, size, hat_weights(x, key.length, nodes)[unknown])
                                              for kind, x, size in changes], wanted, nodes == fine_nodes))
    fine, coarse = solved
    if fine is None or fine[1] is None or coarse is None:
        return None
    w2 = extrapolated(fine[0], coarse[0], grid(key.length, coarse_nodes, key.left, key.right).x,
                      grid(key.length, fine_nodes, key.left, key.right).x, coarse[0].size)
    return w2, fine[0], fine[1]


@memoised
def unit_modes(key: FamilyKey) -> UnitModes:
    """The Richardson modes of the family ``key``'s unit beam (memoised per process; module docstring), continued
    from a panel in ``U`` where :func:`continuation_stem` allows (:mod:`ebb_model.modal.mode_continuation`),
    updated from a continued beam's full bases where :func:`attachment` allows
    (:mod:`ebb_model.modal.attached_modes`)."""
    continued = _continued(key)
    if continued is None:
        continued = _attached(key)
    psi: np.ndarray | Combination
    if continued is None:
        (w2, w2_f, psi), fine = _solve_pair(*unit_pair(key))
    else:
        w2, w2_f, psi = continued
        fine = None
    return UnitModes(_read_only(w2), psi if isinstance(psi, Combination) else _read_only(psi), _read_only(w2_f),
                     key, _lengths(key, _fine_nodes(key)), not key.masses and key.rhoI == 0.0, fine)
