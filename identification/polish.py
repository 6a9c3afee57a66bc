"""Local polish of Pareto points with ``scipy.optimize.least_squares``.

The GA locates the basin; a trust-region least-squares fit of the stacked,
per-sensor normalised residuals ``(y_sim - y_meas)/‖y_meas - ȳ_meas‖`` (the
output-error objectives summed in squares) finishes it.  Unknowns are scaled
to [0, 1] by their bounds; bounds are respected.  The number of model
evaluations (including the finite-difference Jacobian's) is reported.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from .native import NativeEvaluator

__all__ = ["PolishResult", "polish"]


@dataclass(frozen=True)
class PolishResult:
    """Outcome of :func:`polish`."""

    x: np.ndarray
    cost: float
    n_evaluations: int
    success: bool
    message: str


def polish(evaluator: NativeEvaluator, x0: np.ndarray, *, max_evaluations: int = 400,
           xtol: float = 1e-10) -> PolishResult:
    """Least-squares refinement of candidate ``x0`` (native backend)."""
    sp = evaluator.space
    lo, hi = np.asarray(sp.lower), np.asarray(sp.upper)
    span = hi - lo
    meas = [e.outputs for e in evaluator.experiments]
    scale = np.sqrt(sum(np.sum((m - m.mean(axis=0)) ** 2, axis=0) for m in meas))
    scale = np.where(scale > 0, scale, 1.0)
    count = [0]
    n_res = sum(m.size for m in meas)

    def residuals(s: np.ndarray) -> np.ndarray:
        count[0] += 1
        sims, _ = evaluator.simulate(lo + s * span)
        if not sims:
            return np.full(n_res, 1e3)
        r = np.concatenate([((y - m) / scale).ravel() for y, m in zip(sims, meas)])
        return r if np.all(np.isfinite(r)) else np.full(n_res, 1e3)

    s0 = np.clip((np.asarray(x0, dtype=float) - lo) / span, 0.0, 1.0)
    res = least_squares(residuals, s0, bounds=(0.0, 1.0), x_scale="jac", xtol=xtol, ftol=1e-12,
                        gtol=1e-12, max_nfev=max_evaluations, diff_step=1e-7)
    return PolishResult(lo + res.x * span, float(2 * res.cost), count[0], bool(res.success), res.message)
