"""One parameter set's undamped modes: its family's unit modes (:mod:`ebb_model.modal.mode_family`) scaled for its
values, with what a realisation reads of them — the shapes where its loads and sensors are, the modal damping's
structure (diagonal, low-rank or full) and, when asked, the finer grid's dense beam.

``ω² = (EI/ρA) ω̃²`` and ``Ψ = ψ̃/√ρA``; the damping ``C = c V + η EI C̃`` gives ``ΨᵀCΨ = (c/ρA) ψ̃ᵀVψ̃ +
(η EI/ρA) ψ̃ᵀC̃ψ̃`` from the unit matrices the family keeps.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..config import BeamConfig
from .coupled_modes import MAX_RANK, LowRankDamping
from ..space.discretisation import SemiDiscreteBeam, check_attachments, grid, load_rows
from ..theta.modal_form import DIAGONAL_RTOL, is_diagonal
from .mode_family import UnitModes, family_key, unit_modes
from ..space.richardson_pair import companion_nodes

__all__ = ["scaled_beam", "check_pair", "FamilyModes", "family_modes"]


def scaled_beam(unit: SemiDiscreteBeam, config: BeamConfig, p: Mapping[str, float],
                loads: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> SemiDiscreteBeam:
    """The beam of ``config`` with the resolved values ``p`` on the grid of its family's ``unit`` beam:
    ``M = ρA M̃``, ``K = EI K̃``, ``C = c V + η EI C̃`` (``V`` the control lengths), the loads and sensor rows of
    ``config``'s actuators and sensors on that grid (``loads`` when already built:
    :func:`~ebb_model.space.discretisation.load_rows`)."""
    EI = p["EI"]
    nodes = unit.x.size - 2
    C = (p["eta"] * EI) * unit.C
    V = grid(config.beam.length, nodes, config.beam.left, config.beam.right).V
    C[np.diag_indices_from(C)] += p["c"] * V
    F, S, _ = load_rows(config, nodes) if loads is None else loads
    return SemiDiscreteBeam(M=p["rhoA"] * unit.M, C=C, K=EI * unit.K, F=F, S=S,
                            sensor_kinds=tuple(s.kind for s in config.sensors), x=unit.x, unknown=unit.unknown,
                            input_names=config.input_names, output_names=config.output_names)


def check_pair(config: BeamConfig, p: Mapping[str, float]) -> None:
    """Raise :class:`~ebb_model.errors.ParameterError` for a point mass too heavy or a spring too stiff for
    either grid of the Richardson pair (:func:`~ebb_model.space.discretisation.check_attachments`)."""
    for nodes in (config.beam.nodes, companion_nodes(config.beam.nodes)):
        check_attachments(config, p, nodes)


@dataclass(frozen=True, eq=False)
class FamilyModes:
    """The undamped modes of a parameter set (:func:`family_modes`): the extrapolated ``frequencies2`` (``ω²``)
    and the mass-normalised ``shapes`` ``Ψ`` (finer grid × as many modes as the config's grid has unknowns) of
    the family's ``unit`` modes scaled for the resolved values ``p`` of ``config``.  What only some models need
    is built when first read: the shapes whole (a model reads their rows at its loads and sensors,
    :meth:`shape_rows`), the finer grid's dense ``beam`` and the modal damping matrix."""

    config: BeamConfig
    p: Mapping[str, float]
    unit: UnitModes
    frequencies2: np.ndarray

    @functools.cached_property
    def shapes(self) -> np.ndarray:
        """``Ψ = ψ̃/√ρA`` (unknowns of the finer grid × modes), formed when first read."""
        return self.unit.shapes / math.sqrt(self.p["rhoA"])

    def shape_rows(self, J: np.ndarray) -> np.ndarray:
        """``Ψ[J]`` (:meth:`UnitModes.shape_rows`)."""
        return self.unit.shape_rows(J) / math.sqrt(self.p["rhoA"])

    @functools.cached_property
    def loads(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(F, S, J)``: the actuators' load columns and the sensors' rows on the finer grid, and the unknowns
        where either has an entry (:func:`~ebb_model.space.discretisation.load_rows`)."""
        unit = self.unit
        return load_rows(self.config, unit.x.size - 2)

    @functools.cached_property
    def beam(self) -> SemiDiscreteBeam:
        """The finer grid's beam for these values (:func:`scaled_beam`)."""
        return scaled_beam(self.unit.fine, self.config, self.p, self.loads)

    def _damping_weights(self) -> tuple[float, float]:
        """``ΨᵀCΨ = a ψ̃ᵀVψ̃ + b ψ̃ᵀC̃ψ̃``: ``(a, b) = (c/ρA, η EI/ρA)``."""
        p = self.p
        return p["c"] / p["rhoA"], p["eta"] * p["EI"] / p["rhoA"]

    @functools.cached_property
    def damping(self) -> np.ndarray:
        """The modal damping ``Ψᵀ C Ψ`` (before any symmetrisation)."""
        a, b = self._damping_weights()
        return a * self.unit.viscous + b * self.unit.bending

    def diagonal_damping(self, rtol: float = DIAGONAL_RTOL) -> np.ndarray | None:
        """The modal damping's diagonal when it is diagonal to ``rtol`` of its largest diagonal entry
        (:func:`~ebb_model.theta.modal_form.is_diagonal`), else ``None``.  Decided from the unit matrices' largest
        off-diagonal magnitudes where they bound it (no ``k × k`` matrix formed), else on the matrix.  Viscous
        damping alone on a beam without point masses or rotary inertia is ``C = (c/ρA) M``: its diagonal is
        returned whatever ``ΨᵀMΨ``'s round-off (9e-10 off the identity at 200 nodes), as
        :meth:`low_rank_damping` finds rank 0 for it."""
        a, b = self._damping_weights()
        unit = self.unit
        if b == 0.0 and unit.viscous_is_mass:
            return a * unit.viscous_diagonal
        diag = a * np.diagonal(unit.viscous) + b * np.diagonal(unit.bending)    # as the matrix's, bit for bit
        scale = max(float(np.max(np.abs(diag), initial=0.0)), 1e-300)
        # |fl(a v + b w)| <= (|a v| + |b w|)(1 + 2 eps): the bound's own rounding is covered by the factor
        bound = (abs(a) * unit.viscous_off + abs(b) * unit.bending_off) * (1.0 + 4.0 * np.finfo(float).eps)
        if bound <= rtol * scale:
            return diag
        diagonal, d = is_diagonal(self.damping, rtol=rtol)
        return d if diagonal else None

    def low_rank_damping(self) -> LowRankDamping | None:
        """The modal damping as ``diag(d⁰) + G E Gᵀ`` (:mod:`ebb_model.modal.coupled_modes`), or ``None``.

        ``V = M̃ − R_M`` and ``C̃ = K̃ − R_K`` with ``R_M``, ``R_K`` on a few unknowns ``J``
        (:attr:`UnitModes.mass_excess`, :attr:`UnitModes.stiffness_excess`) give, with ``ψ̃ᵀM̃ψ̃ = I`` and
        ``ψ̃ᵀK̃ψ̃ = diag(ω̃²_f)``, ``ΨᵀCΨ = a ψ̃ᵀVψ̃ + b ψ̃ᵀC̃ψ̃ = diag(a + b ω̃²_f) − ψ̃_Jᵀ (a R_M + b R_K)_JJ ψ̃_J``
        (the modes' orthogonality taken as exact).  ``None`` when a term with a non-zero weight differs on more
        than :data:`~ebb_model.modal.coupled_modes.MAX_RANK` unknowns (rotary inertia with viscous damping; axial load
        or a foundation with Kelvin–Voigt damping): the caller decides on the matrix."""
        a, b = self._damping_weights()
        unit = self.unit
        nothing = (np.zeros(0, dtype=np.intp), np.zeros((0, 0)))      # a term with no weight leaves nothing out
        masses = unit.mass_excess if a != 0.0 else nothing
        springs = unit.stiffness_excess if b != 0.0 else nothing
        if masses is None or springs is None:
            return None
        if masses[0].size == 0 and springs[0].size == 0:      # C = α M + β K exactly: rank 0
            return LowRankDamping(a + b * unit.fine_frequencies2, np.zeros((unit.frequencies2.size, 0)),
                                  np.zeros((0, 0)))
        rows = np.union1d(masses[0], springs[0])
        if rows.size > MAX_RANK:
            return None
        E = np.zeros((rows.size, rows.size))
        for w, (J, R) in ((a, masses), (b, springs)):
            at = np.searchsorted(rows, J)
            E[np.ix_(at, at)] -= w * R
        return LowRankDamping(a + b * unit.fine_frequencies2, unit.shape_rows(rows).T.copy(), E)


def family_modes(config: BeamConfig, p: Mapping[str, float]) -> FamilyModes:
    """The undamped modes of ``config`` with the resolved values ``p``: the family's unit modes scaled (module
    docstring).

    Raises
    ------
    ParameterError
        A point mass too heavy or a spring too stiff for either grid (:func:`check_pair`).
    """
    check_pair(config, p)
    unit = unit_modes(family_key(config, p))
    EI, rhoA = p["EI"], p["rhoA"]
    return FamilyModes(config, p, unit, (EI / rhoA) * unit.frequencies2)
