"""The FMU evaluation backend: candidates evaluated by a co-simulation FMU through fmpy.

Works for the beam FMUs of :mod:`fmu_build` and for third-party FMI 2.0
co-simulation FMUs, given the names of their parameters (one per unknown),
inputs (one per actuator, in order) and outputs (one per sensor, in order).

Protocol per candidate (zero-order hold, as :func:`ebb_model.simulate`):
``reset`` → ``setupExperiment`` → enter initialisation → set parameters →
exit initialisation → for every sample ``k``: set ``u_k``, get ``y_k``,
``doStep(dt)``.

Instances
---------
An evaluator carries a run token (created with it, kept when pickled).  Each
process keeps at most one extracted, instantiated FMU per token and thread in
a registry that is created lazily on first use (nothing exists at import):
process-pool workers and Dask workers instantiate the FMU once, at their first
candidate, and reuse it with ``reset()`` for every later candidate of the run,
however often the evaluator is pickled to them.  :meth:`FmuEvaluator.close`
frees the calling process's instances of the token; whatever is left is freed
when the process exits (a ``multiprocessing`` finaliser, which also runs in
pool workers at pool shutdown).
"""
from __future__ import annotations

import functools
import multiprocessing.util
import shutil
import threading
import uuid
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, cast

import numpy as np

from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError, FmuError

from .native import ExperimentArrays
from .objectives import ObjectiveFunction, SimulationOutcome
from .parameters import ParameterSpace

__all__ = ["FmuEvaluator", "check_fmu_file"]


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


class _InstanceRegistry:
    """The FMU instances of one process: one per (run token, thread), counted, freed on release or exit."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._instances: dict[tuple[str, int], _Instance] = {}
        self._created: dict[str, int] = {}
        # runs at normal interpreter exit and at the exit of multiprocessing workers (which skip atexit)
        multiprocessing.util.Finalize(self, self.release_all, exitpriority=100)

    def get(self, token: str, create: Callable[[], _Instance]) -> _Instance:
        """This thread's instance for ``token``, created on first use."""
        key = (token, threading.get_ident())
        with self._lock:
            inst = self._instances.get(key)
        if inst is None:
            inst = create()
            with self._lock:
                self._instances[key] = inst
                self._created[token] = self._created.get(token, 0) + 1
        return inst

    def created(self, token: str) -> int:
        """Number of instances created for ``token`` in this process so far."""
        with self._lock:
            return self._created.get(token, 0)

    def release(self, token: str) -> None:
        """Free this process's instances of ``token``."""
        with self._lock:
            keys = [k for k in self._instances if k[0] == token]
            insts = [self._instances.pop(k) for k in keys]
        for inst in insts:
            inst.close()

    def release_all(self) -> None:
        """Free every instance of this process."""
        with self._lock:
            insts = list(self._instances.values())
            self._instances.clear()
        for inst in insts:
            inst.close()


@functools.lru_cache(maxsize=1)
def _registry() -> _InstanceRegistry:
    """This process's instance registry, created on first use."""
    return _InstanceRegistry()


def check_fmu_file(path: str | Path, names: tuple[str, ...] = ()) -> None:
    """Check, before any work, that ``path`` is an FMI co-simulation FMU with the variables ``names``.

    Raises
    ------
    FmuError
        Not a zip archive, no ``modelDescription.xml`` in it, an unreadable model description, no co-simulation
        interface, or variables missing — naming the file.
    """
    import zipfile

    from fmpy import read_model_description

    if not zipfile.is_zipfile(path):
        raise FmuError(f"`fmu_path` {path}: not an FMU (not a zip archive)")
    with zipfile.ZipFile(path) as zf:
        if "modelDescription.xml" not in zf.namelist():
            raise FmuError(f"`fmu_path` {path}: not an FMU (no modelDescription.xml in the archive)")
    try:
        md = read_model_description(path)
    except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions (XML, schema, version) here
        raise FmuError(f"`fmu_path` {path}: unreadable modelDescription.xml ({type(exc).__name__}: "
                       f"{str(exc).splitlines()[0] if str(exc) else ''})") from None
    if md.coSimulation is None:
        raise FmuError(f"`fmu_path` {path}: not a co-simulation FMU")
    have = {v.name for v in md.modelVariables}
    missing = [n for n in names if n not in have]
    if missing:
        raise FmuError(f"`fmu_path` {path}: no variable(s) {', '.join(missing)}")


def _new_token() -> str:
    return uuid.uuid4().hex


@dataclass(eq=False)
class FmuEvaluator(ObjectiveFunction):
    """Evaluate candidates through an FMU (picklable; the instance is created lazily per process; objectives:
    :class:`ObjectiveFunction`, as the native backend's)."""

    fmu_path: str
    config: BeamConfig
    space: ParameterSpace
    experiments: tuple[ExperimentArrays, ...]
    parameter_names: tuple[str, ...] | None = None
    input_names: tuple[str, ...] | None = None
    output_names: tuple[str, ...] | None = None
    per: str = "sensor"
    stabilising: bool = True
    token: str = field(default_factory=_new_token, repr=False)

    def __post_init__(self) -> None:
        if any(self.space.moves_points(n) for n in self.space.names):
            raise ConfigError("`backend` fmu: positions and point sizes are fixed inside an FMU; identify them "
                              "with the native backend")
        self.parameter_names = tuple(self.parameter_names or self.space.names)
        self.input_names = tuple(self.input_names or self.config.input_names)
        self.output_names = tuple(self.output_names or self.config.output_names)
        if len(self.parameter_names) != self.space.dim:
            raise ConfigError(f"FMU parameter names: {len(self.parameter_names)} given, {self.space.dim} unknowns")
        if not Path(self.fmu_path).is_file():
            raise ConfigError(f"`fmu_path` {self.fmu_path}: no such file")
        check_fmu_file(self.fmu_path, (*self.parameter_names, *self.input_names, *self.output_names))

    def _names(self) -> tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]:
        """The parameters', inputs' and outputs' names (tuples since ``__post_init__``)."""
        return cast("tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]",
                    (self.parameter_names, self.input_names, self.output_names))

    def _create(self) -> _Instance:
        inst = _Instance(self.fmu_path, "identification")
        parameter_names, input_names, output_names = self._names()
        missing = [n for n in (*parameter_names, *input_names, *output_names) if n not in inst.vr]
        if missing:
            inst.close()
            raise FmuError(f"{self.fmu_path}: no variable(s) {', '.join(missing)}")
        return inst

    def _instance(self) -> _Instance:
        return _registry().get(self.token, self._create)

    def instantiations(self) -> int:
        """FMU instances created for this evaluator's run in the calling process so far."""
        return _registry().created(self.token)

    def close(self) -> None:
        """Free this process's FMU instances of this run, if any (a later evaluation creates a new one)."""
        _registry().release(self.token)

    def simulate(self, x: np.ndarray) -> SimulationOutcome:
        """Outputs per experiment for candidate ``x``; not simulated when the FMU refuses the parameters (the
        spectral radius is not known here)."""
        inst = self._instance()
        fmu = inst.fmu
        parameter_names, input_names, output_names = self._names()
        vr_p = [inst.vr[n] for n in parameter_names]
        vr_u = [inst.vr[n] for n in input_names]
        vr_y = [inst.vr[n] for n in output_names]
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
                return SimulationOutcome((), False)
            y = np.empty((e.inputs.shape[0], len(vr_y)))
            t = 0.0
            for k in range(e.inputs.shape[0]):
                fmu.setReal(vr_u, list(e.inputs[k]))
                y[k] = fmu.getReal(vr_y)
                fmu.doStep(currentCommunicationPoint=t, communicationStepSize=dt)
                t = (k + 1) * dt
            outs.append(y)
        return SimulationOutcome(tuple(outs), True)

    def outcome(self, x: np.ndarray, config: BeamConfig, params: Mapping[str, float]) -> SimulationOutcome:
        """The FMU's simulation of candidate ``x`` (:meth:`ObjectiveFunction.outcome`; parameters the FMU refuses:
        not simulated)."""
        return self.simulate(x)

    def __repr__(self) -> str:
        return f"FmuEvaluator({self.fmu_path!r}, unknowns={list(self.space.names)})"


