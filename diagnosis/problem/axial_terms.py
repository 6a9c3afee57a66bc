r"""The finite-difference beam's axial-force terms: geometric stiffness and the stretching integral.

An extra axial force :math:`\delta N` acts on the beam of :mod:`ebb_model.space.discretisation` through
:math:`K_g = \partial K/\partial N` (:func:`geometric_stiffness`); mid-plane stretching makes it
:math:`\frac{EA}{2L}\int_0^L w_x^2\,dx`, the integral taken exactly for the piecewise-linear interpolant of
the grid deflection (:func:`stretch_integral`, :func:`stretch_of_nodes`; as a quadratic form
:func:`stretch_matrix`).  Both axial simulations use them: the θ-scheme's (:mod:`diagnosis.problem.augmented`) and the
exact scheme's (:mod:`diagnosis.problem.axial_modal`).
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ebb_model.config import BeamConfig
from ebb_model.space.discretisation import discretise
from ebb_model.errors import DataError
from ebb_model.parameter_values import resolve_parameters

__all__ = ["geometric_stiffness", "stretch_integral", "stretch_of_nodes", "stretch_matrix"]


def geometric_stiffness(config: BeamConfig, params: Mapping[str, float] | None = None) -> np.ndarray:
    r"""The finite-difference geometric stiffness :math:`K_g = \partial K/\partial N` (n_u × n_u).

    ``K`` of :func:`ebb_model.space.discretisation.discretise` is affine in ``N``
    (the ghost-node relations included), so the difference quotient
    ``(K(N + s) - K(N))/s`` is exact up to round-off; ``s = EI/h²`` balances the
    two terms of ``K`` to keep that round-off at machine precision.
    """
    p = resolve_parameters(config, params)
    h = config.beam.length / (config.beam.nodes + 1)
    s = float(p["EI"]) / h ** 2
    K0 = discretise(config, p).K
    K1 = discretise(config, p | {"N": float(p["N"]) + s}).K
    return (K1 - K0) / s


def stretch_integral(config: BeamConfig, q: np.ndarray) -> np.ndarray:
    r"""``∫₀ᴸ w_x² dx`` of nodal deflections ``q`` (…, n_u), exact for their piecewise-linear interpolant."""
    beam = discretise(config)
    q = np.asarray(q, dtype=float)
    if q.ndim == 0 or q.shape[-1] != beam.n_unknowns:
        raise DataError(f"nodal deflections must have {beam.n_unknowns} values in the last axis, got {q.shape}")
    w = np.zeros(q.shape[:-1] + (beam.x.size,))
    w[..., beam.unknown] = q
    return stretch_of_nodes(w, config.beam.length / (config.beam.nodes + 1))


def stretch_of_nodes(w: np.ndarray, h: float) -> np.ndarray:
    r"""``∫₀ᴸ w_x² dx`` of deflections ``w`` (…, n_nodes) at every grid node, boundaries included, spacing ``h``."""
    return np.sum(np.diff(w, axis=-1) ** 2, axis=-1) / h


def stretch_matrix(config: BeamConfig) -> np.ndarray:
    """``G`` with ``qᵀ G q = ∫ w_x² dx`` of the piecewise-linear grid deflection (unknowns ``q``)."""
    beam = discretise(config)
    n_nodes = beam.x.size
    Dm = np.zeros((n_nodes - 1, beam.n_unknowns))
    for j, node in enumerate(beam.unknown):
        if node > 0:
            Dm[node - 1, j] += 1.0
        if node < n_nodes - 1:
            Dm[node, j] -= 1.0
    h = config.beam.length / (config.beam.nodes + 1)
    return Dm.T @ Dm / h
