"""The native evaluation backend: the ``ebb_model`` fast path (modal form + compiled recursion).

An evaluator maps a candidate parameter vector to the simulated outputs of
every experiment and to the objective vector.  It is a plain picklable value
(config, unknowns, experiments), so process pools and Dask workers can run it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ebb_model import fast_model, max_growth_factor, simulate
from ebb_model.arrays import as_matrix
from ebb_model.config import BeamConfig
from ebb_model.errors import ParameterError

from .objectives import PENALTY, SimulationOutcome, output_errors
from .parameters import ParameterSpace

__all__ = ["ExperimentArrays", "NativeEvaluator", "experiments_from_arrays"]


@dataclass(frozen=True, eq=False)
class ExperimentArrays:
    """The arrays of one experiment needed for evaluation (inputs and measured outputs)."""

    name: str
    inputs: np.ndarray
    outputs: np.ndarray


def experiments_from_arrays(items: Sequence[tuple[str, np.ndarray, np.ndarray]]) -> tuple[ExperimentArrays, ...]:
    """``(name, inputs, outputs)`` triples to :class:`ExperimentArrays` (1-D signals become columns)."""
    return tuple(ExperimentArrays(n, as_matrix(u, f"{n}: inputs", finite=False),
                                  as_matrix(y, f"{n}: outputs", finite=False)) for n, u, y in items)


@dataclass(frozen=True, eq=False)
class NativeEvaluator:
    """Evaluate candidates with the native fast path.

    Parameters
    ----------
    config
        Set-up; nominal values fill parameters that are not unknowns.
    space
        The unknowns.
    experiments
        Inputs (n, n_actuators) and measured outputs (n, n_sensors) per experiment.
    per
        Output errors per ``"sensor"`` or per ``"experiment"``.
    stabilising
        Append the stabilising objective (maximum growth factor).
    """

    config: BeamConfig
    space: ParameterSpace
    experiments: tuple[ExperimentArrays, ...]
    per: str = "sensor"
    stabilising: bool = True

    @property
    def n_obj(self) -> int:
        """Number of objectives."""
        n = len(self.config.sensors) if self.per == "sensor" else len(self.experiments)
        return n + int(self.stabilising)

    def simulate(self, x: np.ndarray) -> SimulationOutcome:
        """Simulated outputs per experiment and the spectral radius of Φ for candidate ``x`` (not simulated
        when it exceeds one)."""
        return self._simulate(*self.space.apply(self.config, x))

    def _simulate(self, cfg: BeamConfig, params: Mapping[str, float]) -> SimulationOutcome:
        model = fast_model(cfg, params)
        rho = model.spectral_radius()
        if rho > 1.0 + 1e-9:
            return SimulationOutcome((), False, rho)
        return SimulationOutcome(tuple(simulate(model, e.inputs).outputs for e in self.experiments), True, rho)

    def objectives(self, x: np.ndarray) -> np.ndarray:
        """Objective vector of candidate ``x`` (finite, penalised when unstable)."""
        try:
            cfg, params = self.space.apply(self.config, x)
            g = max_growth_factor(cfg, params) if self.stabilising else 0.0
            sim = self._simulate(cfg, params)
        except ParameterError:
            return np.full(self.n_obj, 2 * PENALTY)
        n_err = self.n_obj - int(self.stabilising)
        if not sim.stable:
            errs = np.full(n_err, sim.penalty)
        else:
            errs = output_errors(sim.outputs, [e.outputs for e in self.experiments], per=self.per)
            if not np.all(np.isfinite(errs)):
                errs = np.full(n_err, sim.penalty)
        return np.concatenate([errs, [g]]) if self.stabilising else errs

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        """Objectives of a population ``X`` (n, dim) → ``F`` (n, n_obj)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return np.array([self.objectives(x) for x in X])

