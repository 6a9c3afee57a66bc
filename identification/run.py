"""The identification workflow as one API call (what ``ebb identify`` runs).

config + data files → experiments → unknowns → Fisher information at the
nominal point (stop when singular unless ``force``) → pymoo GA with a
checkpoint per generation → Pareto set with Cramér–Rao standard deviations,
growth factor and stability per point, knee marked → ``pareto.json``,
``pareto.csv``, ``identifiability.json``, plots, and exports of every Pareto
point (see :mod:`identification.export`).

Bad input is detected before the output directory is created, so a failed
run leaves nothing behind.
"""
from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ebb_model import load_config, max_growth_factor
from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError
from ebb_model.jsonio import write_json

from .data import Experiment, load_experiments
from .fisher import FisherReport, fisher_information
from .native import ExperimentArrays, NativeEvaluator
from .objectives import objective_names
from .optimise import ALGORITHMS, CHECKPOINT, ParetoSet, optimise
from .parameters import ParameterSpace, parameter_space
from .problem import IdentificationProblem
from .runners import make_runner

__all__ = ["BACKENDS", "IdentificationResult", "identify", "load_identification_config", "read_data"]

BACKENDS = ("auto", "native", "fmu")
_DATA_KEYS = ("mapping", "units", "remove_offset", "pre_trigger", "resample", "format")


def load_identification_config(path: str | Path) -> BeamConfig:
    """Load a config whose ``[identification]`` table is kept for this layer."""
    cfg = load_config(path, extra_sections=("identification",))
    ident = cfg.extra.get("identification", {})
    if not isinstance(ident, Mapping):
        raise ConfigError("identification: must be a table")
    allowed = ("positions", "data", "noise_std", "per", "stabilising")
    bad = [f"identification.{k}: unknown key; allowed: {', '.join(allowed)}" for k in ident if k not in allowed]
    data = ident.get("data", {})
    if not isinstance(data, Mapping):
        bad.append("identification.data: must be a table")
    else:
        bad += [f"identification.data.{k}: unknown key; allowed: {', '.join(_DATA_KEYS)}"
                for k in data if k not in _DATA_KEYS]
    if bad:
        raise ConfigError(bad)
    return cfg


def read_data(config: BeamConfig, paths: Sequence[str | Path]) -> tuple[Experiment, ...]:
    """Load and check the experiments with the options of ``[identification.data]``."""
    if not paths:
        raise ConfigError("DATA: at least one data file is required")
    opts = dict(config.extra.get("identification", {}).get("data", {}))
    exps = load_experiments(list(paths), config, **opts)
    for e in exps:
        e.check_against(config)
    return exps


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """Outcome of :func:`identify`."""

    pareto: ParetoSet
    fisher_nominal: FisherReport
    cramer_rao_std: np.ndarray
    growth_factors: np.ndarray
    stable: np.ndarray
    out_dir: Path

    @property
    def knee(self) -> dict[str, float]:
        """Parameters of the knee point."""
        p = self.pareto
        return dict(zip(p.parameter_names, map(float, p.X[p.knee])))


def _arrays(config: BeamConfig, exps: Sequence[Experiment]) -> tuple[ExperimentArrays, ...]:
    out = []
    for e in exps:
        idx = [e.output_names.index(s.name) for s in config.sensors]
        out.append(ExperimentArrays(e.name, np.asarray(e.inputs), np.asarray(e.outputs)[:, idx]))
    return tuple(out)


def identify(config: BeamConfig | str | Path, data: Sequence[str | Path], out_dir: str | Path, *,
             backend: str = "auto", workers: int = 1, dask: str | None = None, pop: int = 40,
             generations: int = 30, seed: int = 1, resume: bool = False, force: bool = False,
             algorithm: str = "nsga2", per: str | None = None, stabilising: bool | None = None,
             noise_std: Sequence[float] | None = None, progress: bool = True, export: bool = True,
             fmu: str | Path | None = None, fmu_parameters: Sequence[str] | None = None,
             fmu_inputs: Sequence[str] | None = None, fmu_outputs: Sequence[str] | None = None
             ) -> IdentificationResult:
    """Identify the unknowns of ``config`` from ``data``; write results into ``out_dir``.

    ``backend="auto"`` and ``"native"`` use the ``ebb_model`` fast path;
    ``"fmu"`` evaluates through an FMU with fmpy: the given ``fmu`` (a
    third-party FMU needs ``fmu_parameters``/``fmu_inputs``/``fmu_outputs``,
    the names of its variables in the order of the unknowns, actuators and
    sensors) or one built from the config.  The Fisher information always
    uses the native model.

    Raises
    ------
    ConfigError, DataError
        Bad config, data or settings — before anything is written.
    """
    cfg = load_identification_config(config) if not isinstance(config, BeamConfig) else config
    ident = dict(cfg.extra.get("identification", {}))
    if backend not in BACKENDS:
        raise ConfigError(f"--backend: unknown {backend!r}; allowed: {', '.join(BACKENDS)}")
    if algorithm not in ALGORITHMS:
        raise ConfigError(f"--algorithm: unknown {algorithm!r}; allowed: {', '.join(ALGORITHMS)}")
    if workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {workers}")
    per = per or ident.get("per", "sensor")
    if per not in ("sensor", "experiment"):
        raise ConfigError(f"--per: unknown {per!r}; allowed: sensor, experiment")
    stabilising = ident.get("stabilising", True) if stabilising is None else stabilising
    noise_std = noise_std if noise_std is not None else ident.get("noise_std")
    if noise_std is not None:
        noise_std = [float(v) for v in np.atleast_1d(noise_std)]
        if len(noise_std) != len(cfg.sensors) or not all(v > 0 and math.isfinite(v) for v in noise_std):
            raise ConfigError(f"noise_std: need one positive number per sensor ({len(cfg.sensors)})")
    out = Path(out_dir)
    if resume and not (out / CHECKPOINT).exists():
        raise ConfigError(f"--resume: no checkpoint in {out}")
    if not resume and out.exists() and any(out.iterdir()):
        raise ConfigError(f"--out {out}: exists and is not empty (use --resume to continue a run)")
    if not out.parent.is_dir():
        raise ConfigError(f"--out {out}: parent directory does not exist")
    exps = read_data(cfg, data)
    space: ParameterSpace = parameter_space(cfg)
    evaluator = NativeEvaluator(cfg, space, _arrays(cfg, exps), per=per, stabilising=bool(stabilising))
    fisher0 = fisher_information(evaluator, space.nominal, noise_std=noise_std)
    if fisher0.singular and not force:
        raise ConfigError(["identifiability: the Fisher information matrix is singular at the nominal point "
                           f"(rank {fisher0.rank} of {space.dim})", *fisher0.messages,
                           "remove or fix the unidentifiable unknowns, change sensors/inputs, or use --force"])
    names = objective_names(cfg.output_names, [e.name for e in exps], per=per, stabilising=bool(stabilising))
    search_evaluator: Any = evaluator
    tmp_fmu_dir = None
    if backend == "fmu":
        from .fmu_backend import FmuEvaluator

        if fmu is None:
            import tempfile

            from fmu_build import build_fmu

            tmp_fmu_dir = tempfile.mkdtemp(prefix="ebb-fmu-")
            fmu = build_fmu(cfg, Path(tmp_fmu_dir) / "beam.fmu")
        search_evaluator = FmuEvaluator(str(fmu), cfg, space, evaluator.experiments,
                                        tuple(fmu_parameters) if fmu_parameters else None,
                                        tuple(fmu_inputs) if fmu_inputs else None,
                                        tuple(fmu_outputs) if fmu_outputs else None, per=per,
                                        stabilising=bool(stabilising))
    out.mkdir(exist_ok=True)
    write_json(out / "identifiability.json", fisher0.to_dict())
    problem = IdentificationProblem(search_evaluator, names)
    try:
        with make_runner(workers=workers, dask=dask) as runner:
            pareto = optimise(problem, pop=pop, generations=generations, seed=seed, algorithm=algorithm,
                              out_dir=out, resume=resume, runner=runner, progress=progress)
    finally:
        if search_evaluator is not evaluator:
            search_evaluator.close()
        if tmp_fmu_dir is not None:
            import shutil

            shutil.rmtree(tmp_fmu_dir, ignore_errors=True)
    crb, g, st = [], [], []
    for x in pareto.X:
        c, params = space.apply(cfg, x)
        g.append(max_growth_factor(c, params))
        _, rho = evaluator.simulate(x)
        st.append(rho <= 1 + 1e-9)
        try:
            crb.append(fisher_information(evaluator, x, noise_std=fisher0.noise_std).cramer_rao_std)
        except ValueError:
            crb.append(np.full(space.dim, np.inf))
    res = IdentificationResult(pareto, fisher0, np.array(crb), np.array(g), np.array(st), out)
    _write_results(res, cfg, evaluator)
    if export:
        from .export import export_points

        export_points(out)
    return res


def _write_results(res: IdentificationResult, cfg: BeamConfig, evaluator: NativeEvaluator) -> None:
    p = res.pareto
    points = []
    for i, (x, f) in enumerate(zip(p.X, p.F)):
        points.append({
            "index": i,
            "knee": i == p.knee,
            "parameters": dict(zip(p.parameter_names, map(float, x))),
            "objectives": dict(zip(p.objective_names, map(float, f))),
            "cramer_rao_std": {k: float(v) for k, v in zip(p.parameter_names, res.cramer_rao_std[i])},
            "growth_factor": float(res.growth_factors[i]),
            "stable": bool(res.stable[i]),
        })
    doc = {
        "config": cfg.to_dict(),
        "parameter_names": list(p.parameter_names),
        "objective_names": list(p.objective_names),
        "knee": int(p.knee),
        "n_evaluations": int(p.n_evaluations),
        "generations": int(p.generations),
        "points": points,
    }
    write_json(res.out_dir / "pareto.json", doc)
    tmp = res.out_dir / "pareto.csv.part"
    with tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["index", "knee", *p.parameter_names, *p.objective_names,
                    *[f"crb_{n}" for n in p.parameter_names], "growth_factor", "stable"])
        for pt, crb in zip(points, res.cramer_rao_std):
            w.writerow([pt["index"], int(pt["knee"]), *pt["parameters"].values(), *pt["objectives"].values(),
                        *map(float, crb), pt["growth_factor"], int(pt["stable"])])
    os.replace(tmp, res.out_dir / "pareto.csv")
    from .plots import plot_results

    plot_results(res, evaluator)
