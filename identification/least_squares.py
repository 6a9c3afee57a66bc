"""The fitting engine shared by the identification and the gap diagnosis.

Both fit stacked residual vectors of a model to records — the identification's
polish (residuals normalised by each sensor's spread, :mod:`identification.polish`)
and the diagnosis' baseline and effect refits (residuals normalised by the noise,
:mod:`diagnosis.problem.fitting`) — and both search globally before they fit locally.
This module is the one place where that is done:

* **Scaling.**  Unknowns are mapped to the unit cube by their bounds
  (:class:`Box`); bounds are respected.
* **Refused candidates.**  A candidate the model refuses (unstable, invalid
  parameters, an FMU refusing them, non-finite outputs) gets the residual
  :data:`~identification.objectives.PENALTY` on every sample (:func:`penalised`):
  finite, so the trust region shrinks away from it, never NaN.
* **Local least squares** (:func:`fit_least_squares`): bounded trust-region
  reflective ``scipy.optimize.least_squares`` with a forward-difference
  Jacobian in the scaled unknowns whose columns are evaluated as one batch
  (through the identification's runner: worker processes or Dask).  The step,
  :data:`DIFF_STEP` = 1e-5 of each range, balances the model's round-off against
  truncation: the beam's outputs carry about 1e-8 relative noise from its
  eigen-decomposition (cond K ≈ 4e7 at 199 nodes), which makes columns of a
  1e-6 step 0.2–0.9 % wrong in EI, ρA and N; at 1e-5 every column is within
  7e-4 of a central-difference reference (``tests/test_recovery.py``).
  The fit stops as soon as the Gauss–Newton step from the current point would
  lower χ² by less than :data:`CHI2_RESOLUTION` residual variances
  (:func:`predicted_chi2_decrease`): the unknowns are then within a few
  hundredths of their standard deviation of the local optimum, below anything
  the data can tell apart.  ``least_squares``' own ``xtol``/``ftol`` tests still
  apply (noise-free data, where the residual variance vanishes with the fit).
* **Global search** (:func:`evolve`): differential evolution over the unit cube,
  seeded with the start, and :func:`distinct_members` — the best members of its
  final population that lie apart, as starts of local fits in other basins.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
from scipy.optimize import differential_evolution, least_squares

from .objectives import PENALTY

__all__ = ["Box", "CHI2_RESOLUTION", "DIFF_STEP", "Evolution", "LocalFit", "distinct_members", "evolve",
           "fit_least_squares", "penalised", "predicted_chi2_decrease"]

#: Predicted decrease of χ² (in units of the residual variance) below which a local fit has converged.
CHI2_RESOLUTION = 1.0e-3
#: Forward-difference step of the Jacobian, in unknowns scaled to [0, 1] (see the module docstring).
DIFF_STEP = 1.0e-5


#: Residuals beyond this are a diverging simulation, not a fit: penalised like a refused candidate (their
#: squares would overflow the sum of squares).
DIVERGED = 1e100


def penalised(r: np.ndarray | None, n: int) -> np.ndarray:
    """``r`` when it is a finite residual vector (every entry below :data:`DIVERGED`), else :data:`PENALTY` on
    all ``n`` samples."""
    if r is None or r.size != n or not np.all(np.abs(r) < DIVERGED):
        return np.full(n, PENALTY)
    return r


@dataclass(frozen=True)
class Box:
    """Bounds of the unknowns and the map to the unit cube.

    Parameters
    ----------
    lower, upper
        Bounds (physical units), ``lower < upper``.
    """

    lower: np.ndarray
    upper: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "lower", np.asarray(self.lower, dtype=float))
        object.__setattr__(self, "upper", np.asarray(self.upper, dtype=float))

    @property
    def span(self) -> np.ndarray:
        """``upper − lower``."""
        return self.upper - self.lower

    def to_unit(self, x: np.ndarray) -> np.ndarray:
        """Physical → scaled (clipped into [0, 1])."""
        return np.clip((np.asarray(x, dtype=float) - self.lower) / self.span, 0.0, 1.0)

    def from_unit(self, s: np.ndarray) -> np.ndarray:
        """Scaled → physical (rows of a batch alike)."""
        return self.lower + np.asarray(s, dtype=float) * self.span


@dataclass(frozen=True)
class LocalFit:
    """Outcome of :func:`fit_least_squares`.

    Attributes
    ----------
    x
        The fitted unknowns (physical units).
    residuals
        Residual vector at ``x``.
    jac
        Jacobian of the residuals w.r.t. the scaled unknowns at ``x``.
    n_evaluations
        Residual evaluations used (Jacobian columns included).
    success, message
        Convergence (the χ² resolution test or ``least_squares``' own).
    """

    x: np.ndarray
    residuals: np.ndarray
    jac: np.ndarray
    n_evaluations: int
    success: bool
    message: str

    @property
    def rss(self) -> float:
        """Sum of squared residuals."""
        return float(self.residuals @ self.residuals)


def fit_least_squares(batch: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, box: Box, *,
                      max_evaluations: int = 400, xtol: float = 1e-10, ftol: float = 1e-12,
                      diff_step: float = DIFF_STEP, chi2_resolution: float = CHI2_RESOLUTION) -> LocalFit:
    """Bounded least-squares fit from ``x0`` (see the module docstring).

    Parameters
    ----------
    batch
        Residual vectors of a batch of candidates: ``(k, dim)`` physical → ``(k, n)``; refused
        candidates must come back penalised (:func:`penalised`), never raise.
    x0
        Start (physical units), clipped into the box.
    box
        Bounds of the unknowns.
    max_evaluations
        ``least_squares``' ``max_nfev`` (the Jacobian's evaluations come on top and are counted).
    xtol, ftol
        ``least_squares`` tolerances (``xtol`` relative to the scaled unknowns).
    diff_step
        Forward-difference step in the scaled unknowns, taken inwards at a bound.
    chi2_resolution
        Stop once a Gauss–Newton step would lower χ² by less than this many residual variances; 0
        disables the test.
    """
    count = [0]
    last: dict[bytes, np.ndarray] = {}
    jacobian: dict[bytes, np.ndarray] = {}

    def run(S: np.ndarray) -> np.ndarray:
        count[0] += len(S)
        return np.asarray(batch(box.from_unit(S)), dtype=float)

    def fun(s: np.ndarray) -> np.ndarray:
        key = s.tobytes()
        if key not in last:
            last.clear()
            last[key] = run(s[None, :])[0]
        return last[key]

    def jac(s: np.ndarray) -> np.ndarray:
        steps = np.where(s + diff_step <= 1.0, diff_step, -diff_step)
        S = s[None, :] + np.diag(steps)
        key = s.tobytes()
        if key in last:
            r0, R = last[key], run(S)
        else:
            both = run(np.vstack([s[None, :], S]))
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

    res = least_squares(fun, box.to_unit(x0), jac=jac, bounds=(0.0, 1.0), x_scale="jac", xtol=xtol,
                        ftol=ftol, gtol=1e-12, max_nfev=max_evaluations, callback=stop_when_resolved)
    if converged:
        success, message = True, (f"converged: a Gauss-Newton step would lower chi2 by {converged[0]:.1e} "
                                  f"(< {chi2_resolution:g} residual variances)")
    else:
        success, message = bool(res.success), str(res.message)
    return LocalFit(box.from_unit(res.x), np.asarray(res.fun, dtype=float), np.asarray(res.jac, dtype=float),
                    count[0], success, message)


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


@dataclass(frozen=True)
class Evolution:
    """Outcome of :func:`evolve`: the best candidate and the final population (physical units)."""

    x: np.ndarray
    cost: float
    population: np.ndarray
    energies: np.ndarray
    n_evaluations: int


def evolve(cost: Callable[[np.ndarray], float], x0: np.ndarray, box: Box, *, seed: int = 0, maxiter: int = 20,
           popsize: int = 8) -> Evolution:
    """Differential evolution of ``cost`` (physical unknowns → float) over the box, seeded with ``x0``.

    Lightly damped records have many local minima (resonances misaligned by one mode, a parameter
    compensating an unmodelled effect at its bound): a short evolution finds the basin a local fit then
    polishes.  Sobol initialisation, no polish of its own.
    """
    res = differential_evolution(lambda s: cost(box.from_unit(s)), [(0.0, 1.0)] * len(box.lower),
                                 x0=box.to_unit(x0), popsize=popsize, maxiter=maxiter, tol=1e-8, seed=seed,
                                 polish=False, init="sobol")
    return Evolution(box.from_unit(res.x), float(res.fun), box.from_unit(res.population),
                     np.asarray(res.population_energies, dtype=float), int(res.nfev))


def distinct_members(evolution: Evolution, box: Box, first: np.ndarray, n: int, *, separation: float = 0.15
                     ) -> list[np.ndarray]:
    """``first`` and the best members of the final population that lie apart from each other.

    Members are kept when they differ from every kept one by more than ``separation`` of the bounds in
    some unknown; at most ``n`` in all, ``first`` first.
    """
    picks = [box.to_unit(first)]
    for i in np.argsort(evolution.energies):
        if len(picks) >= n:
            break
        cand = box.to_unit(evolution.population[i])
        if all(np.max(np.abs(cand - q)) > separation for q in picks):
            picks.append(cand)
    return [box.from_unit(q) for q in picks]
