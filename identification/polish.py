"""Local polish of Pareto points with ``scipy.optimize.least_squares``.

The GA locates the basin; a trust-region least-squares fit of the stacked,
per-sensor normalised residuals ``(y_sim - y_meas)/‖y_meas - ȳ_meas‖`` finishes
it.  The sum of squares of these residuals is ``Σ_s e_s²``, the output-error
objectives of :mod:`identification.objectives` (``per = "sensor"``) summed in
squares; the stabilising objective is not part of the fit.

Unknowns are scaled to [0, 1] by their bounds and the bounds are respected.
The Jacobian is a forward difference in the scaled unknowns (step
``diff_step``, taken inwards at a bound).  The default step, 1e-5 of each
range, balances the model's round-off against the truncation error: the
outputs of the beam carry noise of about 1e-8 relative from its
eigen-decomposition (cond K ≈ 4e7 at 199 nodes: a 1e-14 change of EI moves
the lowest eigenvalue by up to 5e-9), which makes columns of a
1e-6 step 0.2–0.9 % wrong in EI, ρA and N, so that the Gauss–Newton
prediction below never reaches its threshold; at 1e-5 every column is within
7e-4 of a central-difference reference (measured on the recovery case of
``tests/test_recovery.py``).  Its ``dim`` perturbed candidates are
evaluated as one batch through the run's runner, so a polish runs on the same
worker processes (or Dask cluster) and the same backend as the GA.  Every
model evaluation (residuals and Jacobian columns) is counted.

The fit stops as soon as the Gauss–Newton step from the current point would
lower χ² by less than :data:`CHI2_RESOLUTION` (χ² in units of the residual
variance estimated from the current residuals): the unknowns are then within a
few hundredths of their standard deviation of the local optimum, below
anything the data can tell apart, and further iterations only cost
evaluations.  Unknowns held at a bound by the gradient are left out of that
step.  ``least_squares``' own ``xtol``/``ftol`` tests still apply (noise-free
data, where the residual variance vanishes with the fit).

Candidates the model refuses (unstable, invalid parameters, an FMU refusing
them) get a constant large residual, so the trust region shrinks away from
them; they are never NaN.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from scipy.optimize import least_squares

from ebb_model.errors import ParameterError

from .runners import Runner, SerialRunner

__all__ = ["CHI2_RESOLUTION", "PolishResult", "ResidualEvaluator", "polish", "predicted_chi2_decrease",
           "residual_scale"]

#: Predicted decrease of χ² (in units of the residual variance) below which the polish has converged.
CHI2_RESOLUTION = 1.0e-3

#: Residual given to every sample of a candidate the model refuses.
FAILED_RESIDUAL = 1.0e3


@dataclass(frozen=True)
class PolishResult:
    """Outcome of :func:`polish`.

    Attributes
    ----------
    x
        Polished candidate (physical units, order of the unknowns).
    cost
        Sum of squared normalised residuals at ``x`` (``Σ_s e_s²``).
    n_evaluations
        Model evaluations used (residuals and finite-difference Jacobian).
    success, message
        As reported by ``least_squares``.
    """

    x: np.ndarray
    cost: float
    n_evaluations: int
    success: bool
    message: str


def residual_scale(experiments: Sequence[Any]) -> np.ndarray:
    """Per-sensor normaliser ``‖y_meas - ȳ_meas‖`` pooled over the experiments (1 where it is 0)."""
    scale = np.sqrt(sum(np.sum((e.outputs - e.outputs.mean(axis=0)) ** 2, axis=0) for e in experiments))
    return np.where(scale > 0, scale, 1.0)


@dataclass(frozen=True, eq=False)
class ResidualEvaluator:
    """Normalised residual vectors of candidates (picklable; runs through any runner).

    Parameters
    ----------
    evaluator
        Native or FMU evaluator: ``simulate(x) -> (outputs per experiment, info)``,
        an empty list when the model refuses the candidate.
    """

    evaluator: Any
    scale: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "scale", residual_scale(self.evaluator.experiments))

    @property
    def space(self) -> Any:
        """The unknowns of the wrapped evaluator."""
        return self.evaluator.space

    @property
    def n_residuals(self) -> int:
        """Length of a residual vector (all samples of all sensors of all experiments)."""
        return int(sum(e.outputs.size for e in self.evaluator.experiments))

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Residual vector of candidate ``x``; :data:`FAILED_RESIDUAL` everywhere when refused."""
        exps, scale = self.evaluator.experiments, self.scale
        try:
            sims, _ = self.evaluator.simulate(np.asarray(x, dtype=float))
        except ParameterError:
            sims = []
        if not sims:
            return np.full(self.n_residuals, FAILED_RESIDUAL)
        r = np.concatenate([((y - e.outputs) / scale).ravel() for y, e in zip(sims, exps)])
        return r if np.all(np.isfinite(r)) else np.full(self.n_residuals, FAILED_RESIDUAL)

    def close(self) -> None:
        """Release the wrapped evaluator's per-process resources, if it has any."""
        close = getattr(self.evaluator, "close", None)
        if callable(close):
            close()

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        """Residual vectors of a batch ``X`` (n, dim) → (n, n_residuals)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return np.array([self.residuals(x) for x in X])


def polish(evaluator: Any, x0: np.ndarray, *, runner: Runner | None = None, max_evaluations: int = 400,
           xtol: float = 1e-10, ftol: float = 1e-12, diff_step: float = 1e-5,
           chi2_resolution: float = CHI2_RESOLUTION) -> PolishResult:
    """Least-squares refinement of candidate ``x0``.

    Parameters
    ----------
    evaluator
        Native (:class:`~identification.native.NativeEvaluator`) or FMU
        (:class:`~identification.fmu_backend.FmuEvaluator`) evaluator.
    x0
        Start (physical units), clipped into the bounds.
    runner
        Where batches of candidates are evaluated (default: this process).
    max_evaluations
        Budget of residual evaluations passed to ``least_squares``
        (``max_nfev``; the Jacobian's evaluations come on top and are counted).
    xtol, ftol
        ``least_squares`` tolerances (``xtol`` relative to the scaled unknowns).
    diff_step
        Forward-difference step in the scaled unknowns (see the module
        docstring for the default).
    chi2_resolution
        Stop once a Gauss–Newton step would lower χ² by less than this many
        residual variances (see the module docstring); 0 disables the test.
    """
    run = runner or SerialRunner()
    res_ev = ResidualEvaluator(evaluator)
    sp = evaluator.space
    lo, hi = np.asarray(sp.lower, dtype=float), np.asarray(sp.upper, dtype=float)
    span = hi - lo
    count = [0]
    last: dict[bytes, np.ndarray] = {}
    jacobian: dict[bytes, np.ndarray] = {}

    def batch(S: np.ndarray) -> np.ndarray:
        count[0] += len(S)
        return np.asarray(run(res_ev, lo + S * span))

    def fun(s: np.ndarray) -> np.ndarray:
        key = s.tobytes()
        if key not in last:
            last.clear()
            last[key] = batch(s[None, :])[0]
        return last[key]

    def jac(s: np.ndarray) -> np.ndarray:
        steps = np.where(s + diff_step <= 1.0, diff_step, -diff_step)
        S = s[None, :] + np.diag(steps)
        key = s.tobytes()
        if key in last:
            r0, R = last[key], batch(S)
        else:
            both = batch(np.vstack([s[None, :], S]))
            r0, R = both[0], both[1:]
            last.clear()
            last[key] = r0
        J = ((R - r0[None, :]) / steps[:, None]).T
        jacobian.clear()
        jacobian[key] = J
        return J

    converged: list[float] = []

    def stop_when_resolved(intermediate_result: Any) -> None:
        s = np.asarray(intermediate_result.x, dtype=float)
        J = jacobian.get(s.tobytes())
        if J is None:
            return
        gain = predicted_chi2_decrease(J, np.asarray(intermediate_result.fun, dtype=float), s)
        if gain < chi2_resolution:
            converged.append(gain)
            raise StopIteration

    s0 = np.clip((np.asarray(x0, dtype=float) - lo) / span, 0.0, 1.0)
    res = least_squares(fun, s0, jac=jac, bounds=(0.0, 1.0), x_scale="jac", xtol=xtol, ftol=ftol,
                        gtol=1e-12, max_nfev=max_evaluations, callback=stop_when_resolved)
    if converged:
        return PolishResult(lo + res.x * span, float(2 * res.cost), count[0], True,
                            f"converged: a Gauss-Newton step would lower chi2 by {converged[0]:.1e} "
                            f"(< {chi2_resolution:g} residual variances)")
    return PolishResult(lo + res.x * span, float(2 * res.cost), count[0], bool(res.success), str(res.message))


def predicted_chi2_decrease(J: np.ndarray, r: np.ndarray, s: np.ndarray, *, at_bound: float = 1e-12) -> float:
    """χ² decrease a Gauss–Newton step from ``s`` would bring, in units of the residual variance.

    Parameters
    ----------
    J, r
        Jacobian (n, dim) and residuals (n,) at the scaled unknowns ``s`` (in [0, 1]).
    s
        Scaled unknowns; one at a bound whose gradient ``Jᵀr`` pushes it outwards is held.

    Returns
    -------
    float
        ``‖J δ‖² / σ²`` with ``δ`` the least-squares step on the free unknowns and
        ``σ² = ‖r‖² / (n - dim)``; ``inf`` when the residual variance is zero
        and the step is not (noise-free data).
    """
    g = J.T @ r
    held = ((s <= at_bound) & (g > 0)) | ((s >= 1.0 - at_bound) & (g < 0))
    free = ~held
    n, dim = J.shape
    rr = float(r @ r)
    if not free.any():
        return 0.0
    delta, *_ = np.linalg.lstsq(J[:, free], -r, rcond=None)
    gain = float(np.sum((J[:, free] @ delta) ** 2))
    var = rr / max(n - dim, 1)
    if var <= 0.0:
        return 0.0 if gain <= 0.0 else float("inf")
    return gain / var
