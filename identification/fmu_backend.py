"""The FMU evaluation backend: candidates evaluated by a co-simulation FMU through fmpy.

Works for the beam FMUs of :mod:`fmu_build` and for third-party FMI 2.0
co-simulation FMUs, given the names of their parameters (one per unknown),
inputs (one per actuator, in order) and outputs (one per sensor, in order).

Protocol per candidate (zero-order hold, as :func:`ebb_model.simulate`):
``reset`` → ``setupExperiment`` → enter initialisation → set parameters →
exit initialisation → for every sample ``k``: set ``u_k``, get ``y_k``,
``doStep(dt)``.  The FMU is extracted and instantiated once per evaluator
object in a process (lazily, not pickled) and reused with ``reset()``; it is
freed when the evaluator is closed or collected.
"""
from __future__ import annotations

import shutil
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ebb_model import max_growth_factor
from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError, FmuError, ParameterError

from .native import ExperimentArrays
from .objectives import PENALTY, output_errors
from .parameters import ParameterSpace

__all__ = ["FmuEvaluator"]


class _Instance:
    """One extracted, instantiated FMU; frees itself (terminate, free, remove files)."""

    def __init__(self, path: str, instance_name: str):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        self.md = read_model_description(path)
        if self.md.coSimulation is None:
            raise FmuError(f"{path}: not a co-simulation FMU")
        self.dir = extract(path)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=instance_name)
        self.fmu.instantiate()
        self.fresh = True
        self._finalizer = weakref.finalize(self, _Instance._free, self.fmu, self.dir)

    @staticmethod
    def _free(fmu: Any, directory: str) -> None:
        try:
            fmu.terminate()
        except Exception:  # noqa: BLE001 - best effort at teardown
            pass
        try:
            fmu.freeInstance()
        except Exception:  # noqa: BLE001
            pass
        shutil.rmtree(directory, ignore_errors=True)

    def close(self) -> None:
        self._finalizer()


@dataclass(eq=False)
class FmuEvaluator:
    """Evaluate candidates through an FMU (picklable; the instance is created lazily per process)."""

    fmu_path: str
    config: BeamConfig
    space: ParameterSpace
    experiments: tuple[ExperimentArrays, ...]
    parameter_names: tuple[str, ...] | None = None
    input_names: tuple[str, ...] | None = None
    output_names: tuple[str, ...] | None = None
    per: str = "sensor"
    stabilising: bool = True
    _inst: _Instance | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if any(self.space.is_position(n) for n in self.space.names):
            raise ConfigError("--backend fmu: positions are fixed inside an FMU; identify them with the native "
                              "backend")
        self.parameter_names = tuple(self.parameter_names or self.space.names)
        self.input_names = tuple(self.input_names or self.config.input_names)
        self.output_names = tuple(self.output_names or self.config.output_names)
        if len(self.parameter_names) != self.space.dim:
            raise ConfigError(f"FMU parameter names: {len(self.parameter_names)} given, {self.space.dim} unknowns")
        if not Path(self.fmu_path).is_file():
            raise ConfigError(f"--fmu {self.fmu_path}: no such file")

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_inst"] = None
        return state

    @property
    def n_obj(self) -> int:
        """Number of objectives."""
        n = len(self.config.sensors) if self.per == "sensor" else len(self.experiments)
        return n + int(self.stabilising)

    def _instance(self) -> _Instance:
        if self._inst is None:
            inst = _Instance(self.fmu_path, "identification")
            missing = [n for n in (*self.parameter_names, *self.input_names, *self.output_names)
                       if n not in inst.vr]
            if missing:
                inst.close()
                raise FmuError(f"{self.fmu_path}: no variable(s) {', '.join(missing)}")
            self._inst = inst
        return self._inst

    def close(self) -> None:
        """Free the FMU instance of this process, if any."""
        if self._inst is not None:
            self._inst.close()
            self._inst = None

    def simulate(self, x: np.ndarray) -> tuple[list[np.ndarray], bool]:
        """Outputs per experiment for candidate ``x``; empty list when the FMU refuses the parameters."""
        inst = self._instance()
        fmu = inst.fmu
        vr_p = [inst.vr[n] for n in self.parameter_names]
        vr_u = [inst.vr[n] for n in self.input_names]
        vr_y = [inst.vr[n] for n in self.output_names]
        dt = self.config.time.dt
        outs = []
        for e in self.experiments:
            if not inst.fresh:
                fmu.reset()
            inst.fresh = False
            try:
                fmu.setupExperiment(startTime=0.0)
                fmu.enterInitializationMode()
                fmu.setReal(vr_p, [float(v) for v in x])
                fmu.exitInitializationMode()
            except Exception:  # noqa: BLE001 - fmpy raises on fmi2Error: parameters refused
                return [], False
            y = np.empty((e.inputs.shape[0], len(vr_y)))
            t = 0.0
            for k in range(e.inputs.shape[0]):
                fmu.setReal(vr_u, list(e.inputs[k]))
                y[k] = fmu.getReal(vr_y)
                fmu.doStep(currentCommunicationPoint=t, communicationStepSize=dt)
                t = (k + 1) * dt
            outs.append(y)
        return outs, True

    def objectives(self, x: np.ndarray) -> np.ndarray:
        """Objective vector of candidate ``x`` (same definitions and penalties as the native backend)."""
        cfg, params = self.space.apply(self.config, x)
        try:
            g = max_growth_factor(cfg, params) if self.stabilising else 0.0
        except ParameterError:
            return np.full(self.n_obj, 2 * PENALTY)  # as the native backend: never handed to the FMU
        n_err = self.n_obj - int(self.stabilising)
        sims, ok = self.simulate(x)
        if not ok:
            errs = np.full(n_err, PENALTY + 1.0)
        else:
            errs = output_errors(sims, [e.outputs for e in self.experiments], per=self.per)
            if not np.all(np.isfinite(errs)):
                errs = np.full(n_err, PENALTY + 1.0)
        return np.concatenate([errs, [g]]) if self.stabilising else errs

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        """Objectives of a population ``X`` (n, dim) → ``F`` (n, n_obj)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return np.array([self.objectives(x) for x in X])

    def __repr__(self) -> str:
        return f"FmuEvaluator({self.fmu_path!r}, unknowns={list(self.space.names)})"


