"""Objectives of the identification: output errors and the stabilising objective.

Output error
------------
The normalised RMS error of sensor ``s`` over the samples of all experiments

.. math::

    e_s = \\frac{\\lVert y_s^{sim} - y_s^{meas} \\rVert_2}{\\lVert y_s^{meas} - \\bar y_s^{meas} \\rVert_2},

0 for a perfect fit, 1 for a model no better than the measurement's mean
(``1 - e_s`` is the "fit" of MATLAB's ``compare`` as a fraction).  With
``per = "experiment"`` the errors of all sensors of one experiment are pooled
(squared errors summed, each sensor normalised by its own spread) instead.

Stabilising objective
---------------------
The maximum growth factor of the θ-scheme's dispersion relation over the
grid's wavenumbers (:func:`ebb_model.max_growth_factor`), after Talic et al.:
it is ≤ 1 for a stable scheme; minimising it steers the front away from
unstable and marginal (undamped) parameter sets.

Stability constraint and penalty
--------------------------------
Candidates whose finite beam is unstable (spectral radius of Φ above one) are
never simulated.  The optimiser sees them as *infeasible*: the constraint
``g = ρ(Φ) − 1 <= 0`` (:func:`stability_margin`; pymoo's ``out["G"]``) decides
feasibility before any objective does.  Their objectives stay finite —
:data:`PENALTY` plus their spectral radius on every output-error objective —
so every value is ordered (never NaN) for the polish and the reports.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np

from ebb_model import max_growth_factor
from ebb_model.arrays import as_matrix
from ebb_model.errors import ParameterError

if TYPE_CHECKING:
    from ebb_model.config import BeamConfig

    from .parameters import ParameterSpace

__all__ = ["PENALTY", "STABILITY_TOLERANCE", "ObjectiveFunction", "SimulationOutcome", "nrmse", "objective_names",
           "measured_spread", "output_errors", "stability_margin"]

#: Objective value given to unstable candidates (plus their spectral radius).
PENALTY = 1.0e3
#: Largest spectral radius of Φ above one that still counts as stable (round-off of an undamped beam's unit
#: circle).
STABILITY_TOLERANCE = 1e-9


@dataclass(frozen=True, eq=False)
class SimulationOutcome:
    """What an evaluator's simulation of one candidate gave, whatever the backend.

    Attributes
    ----------
    outputs
        Simulated outputs per experiment, shape (n, n_sensors) each; empty when the candidate was not
        simulated (unstable, or parameters refused by the FMU).
    stable
        Whether the candidate was simulated.
    spectral_radius
        Spectral radius of Φ when the backend knows it (native), NaN otherwise (FMU).
    """

    outputs: tuple[np.ndarray, ...]
    stable: bool
    spectral_radius: float = math.nan

    @property
    def penalty(self) -> float:
        """Output-error objective of a candidate that was not simulated: :data:`PENALTY` plus its spectral
        radius (1 when unknown)."""
        return PENALTY + (self.spectral_radius if math.isfinite(self.spectral_radius) else 1.0)


def nrmse(y_sim: np.ndarray, y_meas: np.ndarray) -> np.ndarray:
    """Normalised RMS error per column (see the module docstring)."""
    y_sim = as_matrix(y_sim, "y_sim", finite=False)
    y_meas = as_matrix(y_meas, "y_meas", finite=False)
    num = np.linalg.norm(y_sim - y_meas, axis=0)
    den = np.linalg.norm(y_meas - y_meas.mean(axis=0), axis=0)
    return num / np.where(den > 0, den, 1.0)


def objective_names(sensor_names: Sequence[str], experiment_names: Sequence[str], *, per: str = "sensor",
                    stabilising: bool = True) -> tuple[str, ...]:
    """Names of the objectives, in the order of :func:`output_errors` (+ ``growth_factor``)."""
    if per not in ("sensor", "experiment"):
        raise ValueError(f"per must be 'sensor' or 'experiment', got {per!r}")
    base = tuple(f"nrmse_{s}" for s in sensor_names) if per == "sensor" \
        else tuple(f"nrmse_{e}" for e in experiment_names)
    return base + (("growth_factor",) if stabilising else ())


def output_errors(sims: Sequence[np.ndarray], meas: Sequence[np.ndarray], *, per: str = "sensor",
                  spread: Sequence[np.ndarray] | None = None) -> np.ndarray:
    """Output-error objectives of one candidate.

    Parameters
    ----------
    sims, meas
        Simulated and measured outputs per experiment, each (n_samples_e, n_sensors).
    per
        ``"sensor"``: one objective per sensor, pooled over experiments;
        ``"experiment"``: one per experiment, pooled over sensors.
    spread
        :func:`measured_spread` of ``meas`` when the caller keeps it (it is the same for every candidate);
        computed here otherwise.
    """
    den_e = measured_spread(meas) if spread is None else spread
    rss = [_column_squares(s - m) for s, m in zip(sims, meas)]
    if per == "sensor":
        num = sum(rss)
        den = sum(den_e)
        return np.sqrt(num / np.where(den > 0, den, 1.0))
    return np.array([np.sqrt(np.mean(r / np.where(den > 0, den, 1.0))) for r, den in zip(rss, den_e)])


def _column_squares(d: np.ndarray) -> np.ndarray:
    """Sum of squares of each column (one pass, no squared copy: 2.5x ``np.sum(d ** 2, axis=0)`` on a 60 s
    record)."""
    return np.einsum("ij,ij->j", d, d)


def measured_spread(meas: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Each experiment's sum of squared deviations from the mean per sensor: the output errors' denominators."""
    return [np.sum((m - m.mean(axis=0)) ** 2, axis=0) for m in meas]


class ObjectiveFunction:
    """The objective vector of a candidate, written once for every evaluation backend.

    A backend (:class:`~identification.native.NativeEvaluator`, :class:`~identification.fmu_backend.FmuEvaluator`)
    has the attributes below and says only how it simulates a candidate (:meth:`outcome`); the output errors,
    the stabilising objective and the penalties are this class's.

    Attributes
    ----------
    config, space, experiments
        Set-up, unknowns, and the experiments' inputs and measured outputs.
    per
        Output errors per ``"sensor"`` or per ``"experiment"`` (:func:`output_errors`).
    stabilising
        Append the stabilising objective (maximum growth factor).
    """

    config: BeamConfig
    space: ParameterSpace
    experiments: tuple[Any, ...]
    per: str
    stabilising: bool

    @property
    def n_obj(self) -> int:
        """Number of objectives."""
        n = len(self.config.sensors) if self.per == "sensor" else len(self.experiments)
        return n + int(self.stabilising)

    def outcome(self, x: np.ndarray, config: BeamConfig, params: Mapping[str, float]) -> SimulationOutcome:
        """The backend's simulation of candidate ``x`` (whose config and parameter values are given)."""
        raise NotImplementedError

    def objectives(self, x: np.ndarray) -> np.ndarray:
        """Objective vector of candidate ``x`` (:meth:`assess`)."""
        return self.assess(x)[0]

    def assess(self, x: np.ndarray) -> tuple[np.ndarray, float]:
        """Objective vector of candidate ``x`` and its stability constraint ``g <= 0``.

        The objectives are finite always — :data:`PENALTY` terms for a candidate that was not simulated
        (unstable, refused) and twice :data:`PENALTY` for non-physical parameter values (never simulated by
        any backend) —, so a population stays ordered.  The constraint (:func:`stability_margin`) is what the
        optimiser decides feasibility by: an unstable candidate is infeasible, not merely a poor fit.
        """
        try:
            cfg, params = self.space.apply(self.config, x)
            g = max_growth_factor(cfg, params) if self.stabilising else 0.0
            sim = self.outcome(np.asarray(x, dtype=float), cfg, params)
        except ParameterError:
            return np.full(self.n_obj, 2 * PENALTY), 1.0
        n_err = self.n_obj - int(self.stabilising)
        if not sim.stable:
            errs = np.full(n_err, sim.penalty)
        else:
            errs = output_errors(sim.outputs, [e.outputs for e in self.experiments], per=self.per,
                                 spread=self._spread)
            if not np.all(np.isfinite(errs)):
                errs = np.full(n_err, sim.penalty)
        return (np.concatenate([errs, [g]]) if self.stabilising else errs), stability_margin(sim)

    @cached_property
    def _spread(self) -> list[np.ndarray]:
        """The output errors' denominators (:func:`measured_spread`), computed once: every candidate shares them."""
        return measured_spread([e.outputs for e in self.experiments])

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        """Objectives of a population ``X`` (n, dim) → ``F`` (n, n_obj)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return np.array([self.objectives(x) for x in X])

    def evaluate_constrained(self, X: np.ndarray) -> np.ndarray:
        """Objectives and stability constraint of a population ``X`` (n, dim) → ``[F | G]`` (n, n_obj + 1)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return np.array([np.append(*self.assess(x)) for x in X])


def stability_margin(sim: SimulationOutcome) -> float:
    """The stability constraint of a simulated candidate, ``g <= 0`` when feasible: ``ρ(Φ) − (1 + 1e-9)`` when
    the backend knows the spectral radius (the native model's stability test), else ``−1`` for a simulated
    candidate and ``+1`` for one the backend refused."""
    if math.isfinite(sim.spectral_radius):
        return float(sim.spectral_radius - (1.0 + STABILITY_TOLERANCE))
    return -1.0 if sim.stable else 1.0
