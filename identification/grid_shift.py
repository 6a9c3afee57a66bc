"""What refining the grid does to the identified unknowns, in their Cramér–Rao deviations.

At the identified point ``x`` the whitened residual vector ``r(x)`` on the model's grid and ``r_f(x)`` on the refined
grid (the same rows: the records', the measured modes', the priors') differ by ``d = r_f − r``.  A fit on the
refined grid starts where ``Jᵀ r = 0`` (``J = ∂r/∂x`` on the model's grid) and takes the Gauss–Newton step

.. math::

    Δ = −(JᵀJ)^{-1} Jᵀ d ,

whose ``j``-th component in the Cramér–Rao deviations ``√((JᵀJ)⁻¹_jj)`` is the grid's bias of ``x_j`` in units of
what the noise leaves (:class:`ebb_model.space.adequacy.ParameterShift`).  One step is the refit's answer to first
order in ``d``: the grid's error moves the unknowns by fractions of a per cent, where ``J`` is constant
(``tests/test_grid_shift.py`` compares it with the polish on the refined grid).  ``identify`` and ``diagnose`` read
it at their answer, so that "grid: adequate" means what a user takes it to mean: the answer would not move.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any, Callable, Sequence

import numpy as np

from ebb_model.config import BeamConfig
from ebb_model.space.adequacy import ParameterShift

from .fisher import REL_STEP
from .objectives import PENALTY

__all__ = ["difference_jacobian", "on_the_grid_of", "parameter_shift", "residual_difference", "shift_between"]


#: A Jacobian whose smallest singular value is below this share of its largest has a direction the records do not
#: see: no deviation to count the shift in.
RANK_TOL = 1e-9

Residuals = Callable[[np.ndarray], np.ndarray]


def _refused(r: np.ndarray) -> bool:
    return not np.all(np.isfinite(r)) or bool(np.all(r == PENALTY))


def difference_jacobian(residuals: Residuals, x: np.ndarray, lower: np.ndarray, upper: np.ndarray
                        ) -> np.ndarray | None:
    """``∂r/∂x`` per relative change of each unknown (central differences of the Fisher information's step,
    :data:`identification.fisher.REL_STEP`, one-sided three-point into the box at a bound), ``None`` when the model
    refuses a point of the stencil.  The step matters: with 1e-4 the strip of ``tests/test_grid_shift.py`` had the
    predicted shift of c 0.25 deviations from the refit's, with 1e-5 0.005."""
    x = np.asarray(x, dtype=float)
    lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    scale = _scale(x, lo, hi)
    r0 = residuals(x)
    if _refused(r0):
        return None
    J = np.empty((r0.size, x.size))
    for j in range(x.size):
        h = REL_STEP * scale[j]
        step = np.zeros_like(x)
        step[j] = h
        if lo[j] <= x[j] - h and x[j] + h <= hi[j]:
            a, b = residuals(x + step), residuals(x - step)
            col = (a - b) / (2.0 * REL_STEP)
        else:
            sign = 1.0 if x[j] - h < lo[j] else -1.0      # into the box: (∓3 r₀ ± 4 r₁ ∓ r₂)/(2h)
            a, b = residuals(x + sign * step), residuals(x + 2.0 * sign * step)
            col = sign * (-3.0 * r0 + 4.0 * a - b) / (2.0 * REL_STEP)
        if _refused(a) or _refused(b):
            return None
        J[:, j] = col
    return J


def _scale(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    width = hi - lo
    return np.where(np.abs(x) > 1e-12 * width, np.abs(x), width)


def parameter_shift(names: Sequence[str], x: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                    residuals: Residuals, difference: np.ndarray, nodes: int, refined_nodes: int
                    ) -> ParameterShift | None:
    """The refined grid's Gauss–Newton step from ``x`` (module docstring).

    Parameters
    ----------
    names, x, lower, upper
        The unknowns, the identified point and the bounds (physical units).
    residuals
        ``x → r``: whitened residual vectors (for the Jacobian; on the model's grid or one near it).
    difference
        ``d``: the refined grid's residual vector at ``x`` less the model's (the same rows).
    nodes, refined_nodes
        The two grids (for the report).

    Returns
    -------
    ParameterShift or None
        ``None`` when ``d`` is not finite, the model refuses a point next to ``x`` (unstable) or the Jacobian is
        rank deficient.
    """
    x = np.asarray(x, dtype=float)
    d = np.asarray(difference, dtype=float)
    J = difference_jacobian(residuals, x, lower, upper) if np.all(np.isfinite(d)) else None
    if J is None or J.shape[0] != d.size:
        return None
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    if s.size == 0 or s[-1] <= RANK_TOL * s[0]:
        return None
    step_scaled = -Vt.T @ ((U.T @ d) / s)
    crb_scaled = np.sqrt(np.sum((Vt.T / s[None, :]) ** 2, axis=1))
    # the refit's χ² below the fit's at x: ‖r‖² − ‖r + d + JΔ‖², J Δ = −P d (P the projector on J's columns)
    r0 = residuals(x)
    after = r0 + d - U @ (U.T @ d)
    gain = float(r0 @ r0 - after @ after)
    step = step_scaled * _scale(x, np.asarray(lower, dtype=float), np.asarray(upper, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = np.where(x != 0.0, step / x, np.nan)
    return ParameterShift(tuple(names), step_scaled / crb_scaled, relative, int(nodes), int(refined_nodes), step,
                          gain)


def residual_difference(residuals: Residuals, fine_residuals: Residuals, x: np.ndarray) -> np.ndarray:
    """``r_f(x) − r(x)``; ``nan`` where either model refuses ``x``."""
    r, rf = residuals(x), fine_residuals(x)
    if _refused(r) or _refused(rf) or r.size != rf.size:
        return np.full(r.size, np.nan)
    return rf - r


def shift_between(space: Any, x: np.ndarray, residuals: Residuals, fine_residuals: Residuals, nodes: int,
                  refined_nodes: int) -> ParameterShift | None:
    """:func:`parameter_shift` of the unknowns ``space`` (names and bounds) at ``x`` between the residuals on the
    model's grid (``nodes``) and on the refined one (``refined_nodes``)."""
    d = residual_difference(residuals, fine_residuals, x)
    return parameter_shift(space.names, x, space.lower, space.upper, residuals, d, nodes, refined_nodes)


def on_the_grid_of(config: BeamConfig, fine: BeamConfig) -> BeamConfig:
    """``config`` with the grid (nodes, sub-steps) of ``fine`` — the refined grid of
    :func:`ebb_model.space.adequacy.adequacy_grid`, found at the identified point's config."""
    return replace(config, beam=replace(config.beam, nodes=fine.beam.nodes),
                   time=replace(config.time, substeps=fine.time.substeps))
