"""Identifiability: the Fisher information matrix of the output-error problem.

For outputs ``y_s[k](θ)`` with independent Gaussian noise of variance
``σ_s²`` per sensor, the Fisher information of the scaled unknowns
``θ_j = p_j / s_j`` is

.. math::

    F = \\sum_{e, s, k} \\frac{1}{\\sigma_s^2}
        \\frac{\\partial y_{e,s}[k]}{\\partial \\theta}
        \\frac{\\partial y_{e,s}[k]}{\\partial \\theta}^T ,

with the sensitivities from central differences of the native model (relative
step :data:`REL_STEP`).  The scale ``s_j`` is ``|p_j|`` (relative sensitivities), or
the width of the bounds when the nominal value is zero.  The Cramér–Rao lower
bound of the standard deviation of ``p_j`` is ``s_j √((F⁻¹)_jj)``.

Following the seed (Talic et al.), the parameters are locally identifiable iff
``F`` is non-singular; a large condition number and eigenvectors of the
smallest eigenvalues name the parameter *combinations* the data cannot
resolve (e.g. ``EI`` and ``N`` moving together).

Noise variance
--------------
Given per sensor, or estimated from the data:
:func:`identification.noise.records_noise_std`, the Welch floor above the
band the inputs excite (the diagnosis' estimate too).  Noise-free records (a
model's own output) have no floor; then a tiny positive stand-in keeps the
matrix finite.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ebb_model.errors import DataError, StabilityError

from .native import NativeEvaluator
from .noise import records_noise_std
from .noise_model import NoiseModel

__all__ = ["REL_STEP", "FisherReport", "sensitivities", "fisher_information", "cramer_rao_std", "nominal_fisher"]

#: Relative step of the central differences.  A lightly damped record is nonlinear in EI on the scale of a
#: half-power bandwidth: on the broadband family's steel strip (one tip accelerometer, 3 s, 323 nodes) the
#: Cramér–Rao deviations with steps 1e-3, 1e-4, 1e-5 are, for EI, 0.45, 0.973 and 0.9997 of the one with 1e-6, for
#: c 0.68, 0.942 and 0.9994 — the step 1e-4 used before put them 3 and 6 % low.
REL_STEP = 1e-5
#: A buckled nominal point's axial load is relaxed towards zero by these factors, the first stable one taken.
RELAXED_LOAD = (0.5, 0.25, 0.0)


def _scales(evaluator: NativeEvaluator, x: np.ndarray) -> np.ndarray:
    width = evaluator.space.upper - evaluator.space.lower
    return np.where(np.abs(x) > 1e-12 * width, np.abs(x), width)


def sensitivities(evaluator: NativeEvaluator, x: np.ndarray, *, rel_step: float = REL_STEP) -> list[np.ndarray]:
    """``∂y/∂θ`` per experiment, each (n_samples, n_sensors, dim), by second-order differences.

    Central differences; within a step of a bound (e.g. ``c = 0`` at its lower bound, where ``c − h``
    is not a valid parameter) the one-sided three-point formula ``(∓3 y₀ ± 4 y₁ ∓ y₂)/(2h)`` into the box.

    Raises
    ------
    ebb_model.errors.StabilityError
        If the model is unstable at a point of the difference stencil.
    """
    x = np.asarray(x, dtype=float)
    s = _scales(evaluator, x)
    lo, hi = np.asarray(evaluator.space.lower, dtype=float), np.asarray(evaluator.space.upper, dtype=float)
    dim = x.size
    out = [np.empty(e.outputs.shape + (dim,)) for e in evaluator.experiments]
    y0: list[np.ndarray] | None = None

    def at(j: int, step: float) -> list[np.ndarray]:
        xs = x.copy()
        xs[j] += step
        sim = evaluator.simulate(xs)
        if not sim.stable:
            raise StabilityError(f"the model is unstable next to the point (parameter {evaluator.space.names[j]}); "
                                 "the Fisher information is not defined there")
        return list(sim.outputs)

    for j in range(dim):
        h = rel_step * s[j]
        if lo[j] <= x[j] - h and x[j] + h <= hi[j]:
            for e, (a, b) in enumerate(zip(at(j, h), at(j, -h))):
                out[e][:, :, j] = (a - b) / (2 * rel_step)
            continue
        if y0 is None:
            y0 = at(j, 0.0)
        sign = 1.0 if x[j] - h < lo[j] else -1.0   # into the box
        for e, (a0, a1, a2) in enumerate(zip(y0, at(j, sign * h), at(j, 2 * sign * h))):
            out[e][:, :, j] = sign * (-3 * a0 + 4 * a1 - a2) / (2 * rel_step)
    return out


@dataclass(frozen=True, eq=False)
class FisherReport:
    """Fisher information at a point and what it says about identifiability."""

    names: tuple[str, ...]
    point: np.ndarray
    scales: np.ndarray
    matrix: np.ndarray
    eigenvalues: np.ndarray
    eigenvectors: np.ndarray
    rank: int
    condition_number: float
    cramer_rao_std: np.ndarray
    noise_std: np.ndarray
    messages: tuple[str, ...]

    @property
    def singular(self) -> bool:
        """Whether the information matrix is numerically singular."""
        return self.rank < len(self.names)

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {
            "parameters": list(self.names),
            "point": dict(zip(self.names, map(float, self.point))),
            "rank": int(self.rank),
            "condition_number": float(self.condition_number),
            "eigenvalues": [float(v) for v in self.eigenvalues],
            "cramer_rao_std": dict(zip(self.names, map(float, self.cramer_rao_std))),
            "relative_cramer_rao_std": dict(zip(self.names, map(float, self.cramer_rao_std / self.scales))),
            "noise_std": [float(v) for v in self.noise_std],
            "messages": list(self.messages),
        }


def _combination(names: Sequence[str], v: np.ndarray) -> str:
    order = np.argsort(-np.abs(v))
    terms = [f"{v[i]:+.2f}·{names[i]}" for i in order if abs(v[i]) >= 0.1]
    return " ".join(terms)


def fisher_information(evaluator: NativeEvaluator, x: np.ndarray, *,
                       noise_std: ArrayLike | None = None, noise: NoiseModel | None = None,
                       rank_tol: float = 1e-9, ill_conditioned: float = 1e8) -> FisherReport:
    """Fisher information matrix of the scaled unknowns at ``x`` and its interpretation.

    Parameters
    ----------
    evaluator
        Native evaluator holding the config, unknowns and experiments.
    x
        The point (e.g. the nominal values, or a Pareto point).
    noise_std
        Noise standard deviation per sensor (white noise); estimated from the data if None.
    noise
        A noise model per experiment and sensor (:class:`~identification.noise_model.NoiseModel`): the
        sensitivities are whitened by it, ``F = Σ (A S/σ)ᵀ (A S/σ)`` — the information of coloured noise
        (then ``noise_std`` is ignored and the report's ``noise_std`` is its white-equivalent level).
    rank_tol
        Eigenvalues below ``rank_tol × λ_max`` count as zero.
    ill_conditioned
        Condition number above which weak directions are reported.

    Raises
    ------
    ebb_model.errors.StabilityError
        If the model is unstable at a point of the difference stencil around ``x``.
    """
    x = np.asarray(x, dtype=float)
    names = evaluator.space.names
    if noise is not None:
        sigma = np.median(noise.std, axis=0)
    elif noise_std is None:
        exps = evaluator.experiments
        meas = np.vstack([e.outputs for e in exps])
        try:
            sigma = records_noise_std([e.inputs for e in exps], [e.outputs for e in exps], evaluator.config.time.dt)
        except DataError:
            sigma = np.zeros(meas.shape[1])
        sigma = np.where(sigma > 0, sigma, 1e-12 * np.maximum(np.std(meas, axis=0), 1e-300))
    else:
        sigma = np.asarray(noise_std, dtype=float)
    S = sensitivities(evaluator, x)
    dim = x.size
    F = np.zeros((dim, dim))
    for e, Se in enumerate(S):
        if noise is None:
            W = Se / sigma[None, :, None]
        else:
            W = np.stack([np.column_stack([sp.whiten(Se[:, s, i]) for i in range(dim)])
                          for s, sp in enumerate(noise.spectra[e])], axis=1)
        F += np.einsum("ksi,ksj->ij", W, W)
    F = 0.5 * (F + F.T)
    lam, V = np.linalg.eigh(F)
    lam_max = float(lam[-1]) if lam.size else 0.0
    rank = int(np.sum(lam > rank_tol * lam_max)) if lam_max > 0 else 0
    cond = float(lam_max / lam[0]) if lam[0] > 0 else float("inf")
    scales = _scales(evaluator, x)
    msgs: list[str] = []
    if rank < dim:
        for i in range(dim - rank):
            msgs.append(f"not identifiable: the combination {_combination(names, V[:, i])} (relative changes) "
                        f"does not change the outputs of these sensors and inputs")
        crb = np.full(dim, np.inf)
    else:
        Finv = np.linalg.inv(F)
        crb = scales * np.sqrt(np.clip(np.diag(Finv), 0, None))
        if cond > ill_conditioned:
            msgs.append(f"ill-conditioned (condition number {cond:.3g}): weakest direction "
                        f"{_combination(names, V[:, 0])} (relative changes)")
    return FisherReport(tuple(names), x, scales, F, lam, V, rank, cond, crb, sigma, tuple(msgs))


def nominal_fisher(evaluator: NativeEvaluator, *, noise_std: ArrayLike | None = None) -> FisherReport:
    """The Fisher information at the nominal point — the identifiability check before a search.

    A newcomer's nominal values are guesses (30–60 % off), and a guess of a compressive load with a guess of EI
    can be a buckled beam (measured: a pinned–pinned beam under N −65 of EI 4.05, the config's guesses EI 1.73 and
    N −95.5; ``identify`` ended in a ``StabilityError`` before any search, the truth inside the bounds).  The
    identifiability check is then made at the nominal point with the axial load relaxed towards zero inside its
    bounds (:data:`RELAXED_LOAD`), the first stable one, and its messages say so; a nominal point that stays
    unstable raises as before.

    Raises
    ------
    ebb_model.errors.StabilityError
        If the model is unstable around the nominal point with every relaxed load.
    """
    space = evaluator.space
    x = np.asarray(space.nominal, dtype=float)
    try:
        return fisher_information(evaluator, x, noise_std=noise_std)
    except StabilityError as exc:
        if "N" not in space.names or x[space.names.index("N")] >= 0.0:
            raise
        first = exc
    j = space.names.index("N")
    for factor in RELAXED_LOAD:
        y = x.copy()
        y[j] = float(np.clip(factor * x[j], space.lower[j], space.upper[j]))
        try:
            report = fisher_information(evaluator, y, noise_std=noise_std)
        except StabilityError:
            continue
        note = (f"the nominal point is unstable (N {x[j]:.4g} buckles the nominal beam): identifiability checked "
                f"at N {y[j]:.4g} instead, the other unknowns nominal")
        return FisherReport(report.names, report.point, report.scales, report.matrix, report.eigenvalues,
                            report.eigenvectors, report.rank, report.condition_number, report.cramer_rao_std,
                            report.noise_std, (note, *report.messages))
    raise first


def cramer_rao_std(evaluator: NativeEvaluator, x: np.ndarray, noise_std: Sequence[float]) -> np.ndarray:
    """Cramér–Rao standard deviations of the unknowns at ``x`` (absolute units)."""
    return fisher_information(evaluator, x, noise_std=noise_std).cramer_rao_std
