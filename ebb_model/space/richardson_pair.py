r"""The Richardson pair of grids: a beam's lowest undamped modes to ``O(h⁴)``.

The FD beam's eigenvalues ``ω_i²`` converge as ``h²``; discretised on the config's grid and on a
:func:`companion_config` grid (half the spacing, or twice it above :data:`_MAX_REFINED_NODES`), the extrapolation
``ω²_f + (ω²_f − ω²_c)/((h_c/h_f)² − 1)`` is ``O(h⁴)`` (:func:`richardson_modes`); the shapes come from the finer
grid.  The eigenvalues themselves come from :func:`lowest_modes`, which resolves the lowest ones to relative
accuracy.  What depends on the parameters only through ratios — the family of a parameter set — is
:mod:`ebb_model.modal.mode_family`.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..config import BeamConfig
from .discretisation import SemiDiscreteBeam
from .few_modes import inverse_eigenvalues

__all__ = ["companion_nodes", "companion_config", "refined_config", "lowest_modes", "richardson_modes",
           "richardson_with_fine", "extrapolated"]

#: Largest refined grid: the eigen-solver's round-off grows with the stiffness matrix's condition number
#: (``∝ n⁴``: 4e7 at 199 nodes), and beyond this it shows as noise in the identification's difference
#: Jacobians; larger configs pair their grid with a coarsened one instead.
_MAX_REFINED_NODES = 201


#: Smallest ``ω²`` relative to ``tr K / tr M`` (about the grid's largest ``ω²``) for which ``K`` counts as
#: positive definite in :func:`lowest_modes` (the clamped 199-node grid's lowest mode: 3e-7).
_SINGULAR_K = 1e-11


def companion_nodes(n: int) -> int:
    """Interior points of the second grid of the Richardson pair of a grid of ``n``: half the spacing
    (``2n + 1``) while that grid has at most :data:`_MAX_REFINED_NODES` nodes, else twice the spacing
    (``(n − 1)//2``)."""
    return 2 * n + 1 if 2 * n + 1 <= _MAX_REFINED_NODES else (n - 1) // 2


def companion_config(config: BeamConfig) -> BeamConfig:
    """The config on the second grid of the Richardson pair (:func:`companion_nodes`)."""
    return replace(config, beam=replace(config.beam, nodes=companion_nodes(config.beam.nodes)))


def refined_config(config: BeamConfig) -> BeamConfig:
    """The finer grid of the Richardson pair, which gives the mode shapes and the damping."""
    other = companion_config(config)
    return other if other.beam.nodes > config.beam.nodes else config


def lowest_modes(beam: SemiDiscreteBeam, n_modes: int, *, vectors: bool = True):
    """The ``n_modes`` lowest ``ω²`` (and mass-normalised modes) of ``K ψ = ω² M ψ``, to relative accuracy.

    ``eigh(K, M)`` resolves ``ω²`` only to ``eps·‖K‖`` absolutely, i.e. ``eps·κ(K)`` relatively for the
    lowest modes (``κ ≈ 6e8`` on a 399-node grid: jitter that spoils difference Jacobians).  When ``K`` is
    positive definite the inverted problem ``M ψ = μ K ψ`` (``μ = 1/ω²``, largest first) resolves the lowest
    ``ω²`` far better (measured against 32-digit arithmetic on the same matrices, the 122-unknown cantilever grid's
    mode 1: 1.6e-9 relative, the direct problem 7.7e-9; the values-only route by Lanczos 3e-10, mode 2 on 5e-13
    — :mod:`ebb_model.space.few_modes`); otherwise (compression, free ends) the direct problem is used.
    LAPACK's Cholesky of a numerically singular ``K`` (a free–free beam's rigid-body modes) need not fail;
    an inverted problem whose smallest ``ω²`` is below :data:`_SINGULAR_K` of the grid's scale
    ``tr K / tr M`` is such a case (it put a 24-node free–free beam's mode 3 2e-4 off) and goes direct too.
    """
    import scipy.linalg as sla     # here: an FMU whose model needs none of scipy starts without it
    size = beam.n_unknowns
    try:   # all pairs by divide and conquer ("gvd"): twice as fast as a subset by "gvx" at these sizes
        if vectors:
            mu, psi = sla.eigh(beam.M, beam.K, driver="gvd")
            mu, psi = mu[-n_modes:], psi[:, -n_modes:]
        elif 4 * n_modes <= size:   # a few values: Lanczos on the banded pencil (0.09 ms at 81 unknowns), else
            # bisection (measured at 119: 0.60 ms, all by "gvd" 0.62 ms)
            mu = inverse_eigenvalues(beam.K, beam.M, n_modes)
            if mu is None:
                mu = sla.eigh(beam.M, beam.K, eigvals_only=True, subset_by_index=(size - n_modes, size - 1))
        else:
            mu = sla.eigh(beam.M, beam.K, eigvals_only=True, driver="gvd")[-n_modes:]
    except np.linalg.LinAlgError:     # K not positive definite
        mu = None
    if mu is None or np.any(mu <= 0) or 1.0 / mu.max() < _SINGULAR_K * np.trace(beam.K) / np.trace(beam.M):
        return sla.eigh(beam.K, beam.M, eigvals_only=not vectors, subset_by_index=(0, n_modes - 1))
    w2 = 1.0 / mu[::-1]
    if not vectors:
        return w2
    psi = psi[:, ::-1]
    m = np.diagonal(beam.M)
    # M ψ: by the diagonal where M is diagonal (the product's numbers and layout, without its n² k work)
    Mpsi = np.ascontiguousarray(m[:, None] * psi) if np.count_nonzero(beam.M) == np.count_nonzero(m) \
        else beam.M @ psi
    psi /= np.sqrt(np.einsum("ij,ij->j", psi, Mpsi))[None, :]   # mass-normalised (eigh gave K-normalised)
    return w2, psi


def richardson_modes(coarse: SemiDiscreteBeam, fine: SemiDiscreteBeam, n_modes: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Extrapolated eigenvalues ``ω²`` and fine-grid mass-normalised modes ``Ψ`` (n_fine × n_modes).

    With spacings ``h_f < h_c`` and ``ω²(h) = ω² + a h² + O(h⁴)``:
    ``ω²_R = ω²_f + (ω²_f − ω²_c) / ((h_c/h_f)² − 1)``.  The coarse grid has fewer modes; the upper half of
    them is faded out of the extrapolation by mode index (continuous in the parameters), and modes beyond
    keep the fine grid's values — they lie far above any band the grids resolve.

    Parameters
    ----------
    coarse, fine
        The FD beam on the two grids.
    n_modes
        How many of the lowest modes to return (at most the fine grid's unknowns).
    """
    w2, _, psi = richardson_with_fine(coarse, fine, n_modes)
    return w2, psi


def richardson_with_fine(coarse: SemiDiscreteBeam, fine: SemiDiscreteBeam, n_modes: int
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`richardson_modes` with the fine grid's own ``ω²`` between them: ``(ω²_R, ω²_f, Ψ)``."""
    w2_f, psi = lowest_modes(fine, n_modes)
    m = min(coarse.n_unknowns, n_modes)
    return extrapolated(w2_f, lowest_modes(coarse, m, vectors=False), coarse.x, fine.x, m), w2_f, psi


def extrapolated(w2_f: np.ndarray, w2_c: np.ndarray, coarse_x: np.ndarray, fine_x: np.ndarray, m: int
                 ) -> np.ndarray:
    """The Richardson values of :func:`richardson_modes` from the fine grid's lowest ``ω²`` (``w2_f``) and the
    coarse grid's lowest ``w2_c`` (at most as many) on the grids of nodes ``coarse_x`` and ``fine_x``, ``m``
    being how many the pair extrapolates (the fade's scale): the lowest modes come out the same whether all or a
    few of them are computed."""
    h_f, h_c = np.diff(fine_x[:2])[0], np.diff(coarse_x[:2])[0]
    j = w2_c.size
    weight = np.clip(2.0 * (1.0 - np.arange(j) / m), 0.0, 1.0)   # 1 for the lower half, fading to 0
    w2 = w2_f.copy()
    w2[:j] += weight * (w2_f[:j] - w2_c) / ((h_c / h_f) ** 2 - 1.0)
    return w2
