"""The native evaluation backend: the ``ebb_model`` fast path (modal form + compiled recursion).

An evaluator maps a candidate parameter vector to the simulated outputs of
every experiment and to the objective vector.  It is a plain picklable value
(config, unknowns, experiments), so process pools and Dask workers can run it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ebb_model import fast_model, simulate
from ebb_model.arrays import as_matrix
from ebb_model.config import BeamConfig

from .objectives import STABILITY_TOLERANCE, ObjectiveFunction, SimulationOutcome
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
class NativeEvaluator(ObjectiveFunction):
    """Evaluate candidates with the native fast path (objectives: :class:`ObjectiveFunction`).

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

    def simulate(self, x: np.ndarray) -> SimulationOutcome:
        """Simulated outputs per experiment and the spectral radius of Φ for candidate ``x`` (not simulated
        when it exceeds one)."""
        return self._simulate(*self.space.apply(self.config, x))

    def _simulate(self, cfg: BeamConfig, params: Mapping[str, float]) -> SimulationOutcome:
        model = fast_model(cfg, params)
        rho = model.spectral_radius()
        if rho > 1.0 + STABILITY_TOLERANCE:
            return SimulationOutcome((), False, rho)
        return SimulationOutcome(tuple(simulate(model, e.inputs).outputs for e in self.experiments), True, rho)

    def outcome(self, x: np.ndarray, config: BeamConfig, params: Mapping[str, float]) -> SimulationOutcome:
        """The fast path's simulation of candidate ``x`` (:meth:`ObjectiveFunction.outcome`)."""
        return self._simulate(config, params)

