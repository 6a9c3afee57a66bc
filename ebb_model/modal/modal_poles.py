"""The continuous-time poles of the accurate realisation, without its state space.

What a modal comparison needs (:func:`ebb_model.modal.modal.discrete_frequencies`: frequencies and damping ratios, often
of the few lowest modes only) is the poles of :func:`~ebb_model.exact.exact_modal.modal_matrices`' modal system
``q̈ + C_m q̇ + Λ q = 0``, not its input and output rows.  Three routes, each exact to round-off:

* **mass-proportional damping, a few modes** (``C = α M``: viscous damping per unit mass, no Kelvin–Voigt term,
  every mass distributed like the damping — the modes are then decoupled, each with ``d_i = α``): the Richardson
  values ``ω_i²`` of those modes alone (eigenvalues only, bisection for the wanted ones on both grids), no
  eigenvectors; the poles in closed form.  This is the modal-pattern search's common case, and about half the
  full route's cost (measured 0.55× on the family's bench, the eigenvectors being what it saves);
* **damping coupling the modes through a low-rank part** (point masses on a viscously damped beam): every
  mode's shape is needed for ``C_m``; the wanted poles by Newton's iteration on ``r × r`` algebra
  (:func:`ebb_model.modal.coupled_modes.coupled_poles`);
* **other damping coupling the modes, a few modes**: the lowest poles are refined by Newton's iteration from
  their decoupled values with the full coupling (:func:`_coupled_poles`);
* otherwise every pole: closed form when ``C_m`` is diagonal, else the ``2k × 2k`` eigenvalue problem.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..config import BeamConfig
from .coupled_modes import coupled_poles
from ..exact.exact_modal import modal_matrices, modal_state_matrix
from .mode_family import family_key, unit_pair
from .parameter_modes import check_pair
from ..space.richardson_pair import extrapolated, lowest_modes
from ..parameter_values import resolve_parameters

__all__ = ["modal_poles"]

#: Newton iterations allowed per pole (quadratic from the decoupled value, off by the coupling squared).
_NEWTON_STEPS = 8


def modal_poles(config: BeamConfig, params: Mapping[str, float], lowest: int | None = None) -> np.ndarray:
    """The continuous-time poles of :func:`~ebb_model.exact.exact_modal.modal_matrices` (module docstring).

    Unlike :func:`~ebb_model.exact.exact_modal.continuous_modes` this needs no eigenvector basis of the state, so it
    never fails for an ill-conditioned one.  With ``lowest``, only the poles of the ``lowest`` lowest modes are
    needed: for mass-proportional damping and for damping that couples the modes only they are returned (both
    poles of each mode), otherwise all of them.

    Raises
    ------
    ParameterError
        Invalid parameter values (from the discretisation).
    """
    p = resolve_parameters(config, params)
    if lowest is not None:
        check_pair(config, p)
        s = _mass_proportional_poles(config, p, lowest)
        if s is not None:
            return s
    mm = modal_matrices(config, p)
    if mm.damping is not None:
        root = np.sqrt((mm.damping ** 2 / 4 - mm.frequencies2).astype(complex))
        return np.concatenate([-mm.damping / 2 + root, -mm.damping / 2 - root])
    if mm.low_rank is not None:
        k = mm.frequencies2.size
        found = coupled_poles(mm.frequencies2, mm.low_rank, None if lowest is None else min(lowest, k))
        if found is not None:
            return found[0]
    if lowest is not None:
        s = _coupled_poles(mm.frequencies2, mm.Cm, lowest)
        if s is not None:
            return np.concatenate([s, s.conj()])
    return np.linalg.eigvals(modal_state_matrix(mm.frequencies2, mm.Cm))


def _mass_proportional_rate(config: BeamConfig, p: Mapping[str, float]) -> float | None:
    """``α`` when ``C = α M`` (then ``Ψᵀ C Ψ = α I`` for mass-normalised modes), else ``None``; ``p`` resolved.

    Read from the structure (:func:`~ebb_model.modal.parameter_modes.scaled_beam`: ``C = c V + η EI C̃``, ``M = ρA M̃``):
    no Kelvin–Voigt term, and the viscous damping where the mass is, ``M̃ = diag(V)`` — no point mass with a
    mass, no rotary inertia — or no damping at all."""
    if p["eta"] * p["EI"] != 0.0:
        return None
    if p["c"] == 0.0:
        return 0.0
    if p["rhoI"] != 0.0 or any(m.mass != 0.0 for m in config.masses):
        return None
    return p["c"] / p["rhoA"]


def _mass_proportional_poles(config: BeamConfig, p: Mapping[str, float], n: int) -> np.ndarray | None:
    """Both poles of each of the ``n`` lowest modes when the damping is mass-proportional and those modes are
    underdamped (then so is every higher one, ``d`` being the same for all), else ``None``; ``p`` resolved.

    The values are :func:`~ebb_model.exact.exact_modal.modal_matrices`' (the same unit beams of the family
    (:mod:`ebb_model.modal.mode_family`), the same extrapolation, the fade scaled by the full count), computed for these
    modes alone.
    """
    alpha = _mass_proportional_rate(config, p)
    if alpha is None:
        return None
    own, companion = unit_pair(family_key(config, p))
    k = own.n_unknowns                            # the realisation's mode count (modal_matrices)
    if n >= k:
        return None
    coarse, fine = sorted((own, companion), key=lambda b: b.n_unknowns)
    m = min(coarse.n_unknowns, k)
    w2_f = lowest_modes(fine, n, vectors=False)
    w2 = (p["EI"] / p["rhoA"]) * extrapolated(w2_f, lowest_modes(coarse, min(n, m), vectors=False), coarse.x, fine.x, m)
    if not (np.all(np.diff(w2) > 0) and w2[0] > 0 and alpha * alpha / 4 < w2[0]):
        return None
    s = -alpha / 2 + 1j * np.sqrt(w2 - alpha * alpha / 4)
    return np.concatenate([s, s.conj()])


def _coupled_poles(w2: np.ndarray, Cm: np.ndarray, n: int) -> np.ndarray | None:
    r"""The upper poles of the ``n`` lowest modes of ``q̈ + C_m q̇ + Λ q = 0`` to round-off, or ``None``.

    Each is a root of ``det Q(s)``, ``Q(s) = s² I + s C_m + Λ``: with the mode ``i`` split from the rest ``r``
    (``e`` the column ``C_m[r, i]``), ``det Q = det Q_rr · f_i`` and the pole of mode ``i`` is the root of
    ``f_i(s) = s² + s d_i + ω_i² − s² eᵀ Q_rr(s)⁻¹ e`` near the decoupled pole ``−d_i/2 + i√(ω_i² − d_i²/4)``
    (``d_i`` the diagonal of ``C_m``), found by Newton's iteration — one solve with one right-hand side per step
    (``x = Q_rr⁻¹ e``, ``f_i' = 2s + d_i − 2s eᵀx + s² xᵀ(2s I + C_rr) x``, ``Q`` being symmetric).
    ``None`` — the caller solves the full eigenvalue problem — when a wanted mode is not
    underdamped, when an iteration does not converge, or when a root left the half-gap around its start
    (it might have converged to a neighbour's pole).
    """
    k = w2.size
    if n >= k or not np.all(np.diff(w2[:n + 1]) > 0):
        return None
    d = np.diag(Cm)
    if np.any(d[:n + 1] ** 2 / 4 >= w2[:n + 1]) or np.any(w2[:n + 1] <= 0):
        return None
    start = -d[:n] / 2 + 1j * np.sqrt(w2[:n] - d[:n] ** 2 / 4)
    w = np.sqrt(w2[:n + 1])
    gap = 0.5 * np.minimum(np.diff(w)[:n], np.concatenate([[w[0]], np.diff(w)[:n - 1]]))
    out = np.empty(n, dtype=complex)
    for i, s in enumerate(start):
        rest = np.delete(np.arange(k), i)
        e, C_rr, diag_r = Cm[rest, i], Cm[np.ix_(rest, rest)], np.diag_indices(k - 1)
        for _ in range(_NEWTON_STEPS):
            Q_rr = s * C_rr
            Q_rr[diag_r] += s * s + w2[rest]
            try:
                x = np.linalg.solve(Q_rr, e)
            except np.linalg.LinAlgError:      # another mode's pole: not this mode's root
                return None
            ex = e @ x
            f = s * s + s * d[i] + w2[i] - s * s * ex
            df = 2.0 * s + d[i] - 2.0 * s * ex + s * s * (x @ (2.0 * s * x + C_rr @ x))
            step = f / df
            s = s - step
            if abs(step) <= 1e-14 * abs(s):
                break
        else:
            return None
        if not abs(s - start[i]) < gap[i]:
            return None
        out[i] = s
    return out
