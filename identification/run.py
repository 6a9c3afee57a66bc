"""The identification workflow as one API call (what ``ebb identify`` runs).

config + data files → experiments → unknowns → Fisher information at the
nominal point (stop when singular unless ``force``) → pymoo GA with a
checkpoint per generation → optional local polish (``polish = K``: the ``K``
Pareto points nearest the knee, knee first, refined by bounded
``scipy.optimize.least_squares`` on the same backend and workers, see
:mod:`identification.polish`) → Pareto set and polished points with
Cramér–Rao standard deviations, growth factor and stability per point, knee
marked → ``pareto.json``, ``pareto.csv``, ``polished.csv`` (when polished),
``identifiability.json``, plots, and exports of every Pareto and polished
point (see :mod:`identification.export`).

Evaluation counts: ``n_evaluations`` in ``pareto.json`` is the total number
of model evaluations of the search, GA plus polish (residuals, Jacobian
columns and the final objective evaluation of each polished point); the
simulations of the Fisher analysis (``2 × unknowns`` per point) are not
included.

Bad input is detected before the output directory is created, so a failed
run leaves nothing behind.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from ebb_model import max_growth_factor
from ebb_model.adequacy import NumericalAdequacy, numerical_adequacy
from ebb_model.output import atomic_path
from ebb_model.config import BeamConfig
from ebb_model.threads import one_blas_thread
from ebb_model.errors import ConfigError, OutputError, StabilityError
from ebb_model.jsonio import write_json
from ebb_model.output import check_new_output_dir, check_writable_dir, make_dir

from .data import Experiment, load_experiments
from .fisher import FisherReport, fisher_information
from .native import ExperimentArrays, NativeEvaluator
from .objectives import objective_names
from .optimise import CHECKPOINT, ParetoSet, check_settings, knee_index, knee_order, optimise
from .parameters import ParameterSpace, parameter_space
from .polish import polish as polish_point
from .problem import IdentificationProblem
from .runners import Runner, make_runner
from .noise import given_noise_std
from .settings import identification_settings, load_identification_config

__all__ = ["BACKENDS", "IdentificationResult", "PolishedPoint", "Progress", "identify",
           "load_identification_config", "read_data"]

BACKENDS = ("auto", "native", "fmu")
#: Largest fit residual (in noise variances, per sensor) at which the Cramér–Rao bound is reported as valid: the
#: bound assumes the model explains the data up to the noise.
CRB_GAP_LIMIT = 2.0
def read_data(config: BeamConfig, paths: Sequence[str | Path]) -> tuple[Experiment, ...]:
    """Load and check the experiments with the options of ``[identification.data]``."""
    if not paths:
        raise ConfigError("DATA: at least one data file is required")
    opts = dict(identification_settings(config).data)
    exps = load_experiments(list(paths), config, **opts)
    for e in exps:
        e.check_against(config)
    return exps


@dataclass(frozen=True, eq=False)
class PolishedPoint:
    """A Pareto point after the local polish.

    Attributes
    ----------
    from_index
        Index of the Pareto point it started from (into ``pareto.X``).
    x, objectives
        Polished parameters and their objective values.
    cramer_rao_std
        Cramér–Rao standard deviations at ``x``.
    growth_factor, stable
        Stabilising objective and stability of the discrete beam at ``x``.
    n_evaluations
        Model evaluations of this polish (including its Jacobians and the
        final objective evaluation).
    cost, success, message
        Final sum of squared normalised residuals and ``least_squares``'s verdict.
    """

    from_index: int
    x: np.ndarray
    objectives: np.ndarray
    cramer_rao_std: np.ndarray
    growth_factor: float
    stable: bool
    n_evaluations: int
    cost: float
    success: bool
    message: str


@dataclass(frozen=True)
class Progress:
    """What :func:`identify` reports to ``on_progress`` during the search.

    ``stage`` is ``"generation"`` (after every GA generation: ``X``, ``F`` the
    current non-dominated set, ``knee`` its knee) or ``"polish"`` (after every
    polished point: ``X``, ``F`` of that one point, ``knee = 0``).
    ``n_evaluations`` counts the search's model evaluations so far (GA plus
    polish).
    """

    stage: str
    step: int
    n_evaluations: int
    X: np.ndarray
    F: np.ndarray
    knee: int


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """Outcome of :func:`identify`."""

    pareto: ParetoSet
    fisher_nominal: FisherReport
    cramer_rao_std: np.ndarray
    growth_factors: np.ndarray
    stable: np.ndarray
    out_dir: Path
    polished: tuple[PolishedPoint, ...] = ()
    adequacy: NumericalAdequacy | None = None   # numerical share of the gap at :attr:`best`

    @property
    def knee(self) -> dict[str, float]:
        """Parameters of the knee point of the GA's front."""
        p = self.pareto
        return dict(zip(p.parameter_names, map(float, p.X[p.knee])))

    @property
    def best(self) -> dict[str, float]:
        """Parameters of the polished knee when polished, otherwise of the knee."""
        if not self.polished:
            return self.knee
        return dict(zip(self.pareto.parameter_names, map(float, self.polished[0].x)))

    @property
    def identified(self) -> dict[str, Any]:
        """*The* identified model: the polished knee (else the GA's knee, marked as not polished), its
        Cramér–Rao standard deviations and the fit quality they assume (``cramer_rao_valid``: the fit's residual
        is within :data:`CRB_GAP_LIMIT` noise variances of every sensor)."""
        names = self.pareto.parameter_names
        if self.polished:
            q = self.polished[0]
            source, x, crb = f"polished knee, from Pareto point {q.from_index}", q.x, q.cramer_rao_std
        else:
            i = self.pareto.knee
            source, x, crb = f"knee of the GA front, Pareto point {i}, NOT polished", self.pareto.X[i], \
                self.cramer_rao_std[i]
        doc: dict[str, Any] = {"from": source, "polished": bool(self.polished),
                               "parameters": dict(zip(names, map(float, x))),
                               "cramer_rao_std": dict(zip(names, map(float, crb)))}
        if self.adequacy is not None:
            gap = dict(zip(self.adequacy.sensors, map(float, self.adequacy.gap)))
            doc["fit_gap_ratio"] = gap
            doc["cramer_rao_valid"] = bool(max(gap.values(), default=0.0) <= CRB_GAP_LIMIT)
        return doc

    @property
    def n_evaluations(self) -> int:
        """Model evaluations of the search: GA plus polish."""
        return int(self.pareto.n_evaluations + sum(q.n_evaluations for q in self.polished))


def _arrays(config: BeamConfig, exps: Sequence[Experiment]) -> tuple[ExperimentArrays, ...]:
    out = []
    for e in exps:
        idx = [e.output_names.index(s.name) for s in config.sensors]
        out.append(ExperimentArrays(e.name, np.asarray(e.inputs), np.asarray(e.outputs)[:, idx]))
    return tuple(out)


def _check_out_dir(out: Path, resume: bool) -> Path:
    """The result directory: new (absent or empty) for a run, an interrupted run's for ``resume``."""
    finished = (out / "pareto.json").exists()
    if resume:
        if (out / CHECKPOINT).exists() and not finished:
            return check_writable_dir(out, name="out_dir")
        if finished:
            raise ConfigError(f"`resume`: the run in {out} has finished (pareto.json); nothing to resume")
        raise ConfigError(f"`resume`: {out} holds no interrupted `identify` run (no {CHECKPOINT})")
    if (out / CHECKPOINT).exists() and not finished:
        raise ConfigError(f"`out_dir` {out}: holds an interrupted run; continue it with `resume`, or choose a new "
                          "directory")
    if finished:
        raise ConfigError(f"`out_dir` {out}: holds a finished run; choose a new directory (export its points with "
                          "`export_points`)")
    return check_new_output_dir(out, name="out_dir")


@one_blas_thread
def identify(config: BeamConfig | str | Path, data: Sequence[str | Path], out_dir: str | Path, *,
             backend: str = "auto", workers: int = 1, dask: str | None = None, pop: int = 40,
             generations: int = 30, seed: int = 1, resume: bool = False, force: bool = False,
             algorithm: str = "nsga2", per: str | None = None, stabilising: bool | None = None,
             noise_std: Sequence[float] | None = None, progress: bool = True, export: bool = True,
             fmu: str | Path | None = None, fmu_parameters: Sequence[str] | None = None,
             fmu_inputs: Sequence[str] | None = None, fmu_outputs: Sequence[str] | None = None,
             polish: int = 1, polish_evaluations: int = 200,
             on_progress: Callable[[Progress], None] | None = None) -> IdentificationResult:
    """Identify the unknowns of ``config`` from ``data``; write results into ``out_dir``.

    ``backend="auto"`` and ``"native"`` use the ``ebb_model`` fast path;
    ``"fmu"`` evaluates through an FMU with fmpy: the given ``fmu`` (a
    third-party FMU needs ``fmu_parameters``/``fmu_inputs``/``fmu_outputs``,
    the names of its variables in the order of the unknowns, actuators and
    sensors) or one built from the config.  The Fisher information always
    uses the native model.

    ``workers = K`` evaluates on ``K`` local processes; ``dask`` on a Dask
    cluster: a scheduler address, or ``"local:K"`` for a local cluster
    started (and closed) for this run (:mod:`identification.cluster`).

    ``polish = K`` refines the ``K`` Pareto points nearest the knee (knee
    first) with bounded least squares on the search backend and workers, at
    most ``polish_evaluations`` residual evaluations each (their Jacobians
    come on top and are counted).  The default, 1, polishes the knee: that
    is *the* identified model (:attr:`IdentificationResult.best`, ``identified``
    in ``pareto.json``); ``polish = 0`` reports the GA's knee, marked as not
    polished.  ``on_progress`` receives a
    :class:`Progress` after every generation and every polished point.

    Raises
    ------
    ConfigError, DataError, FmuError
        Bad config, data, settings or FMU — before anything is written.
    OutputError
        ``out_dir`` cannot be written (before anything is computed), or writing failed during the run (a full
        disk): nothing is kept, or — after the first generation — the checkpoint, to continue with ``resume``.
    """
    cfg = load_identification_config(config) if not isinstance(config, BeamConfig) else config
    ident = identification_settings(cfg)
    if backend not in BACKENDS:
        raise ConfigError(f"`backend`: unknown {backend!r}; allowed: {', '.join(BACKENDS)}")
    check_settings(pop, generations, algorithm)
    if fmu is not None:
        if backend != "fmu":
            raise ConfigError(f"`fmu` {fmu}: evaluated only with `backend` fmu (got `backend` {backend})")
        from .fmu_backend import check_fmu_file

        if not Path(fmu).is_file():
            raise ConfigError(f"`fmu_path` {fmu}: no such file")
        check_fmu_file(fmu)   # an FMU at all (its variables: when the evaluator is made, also before writing)
    if workers < 1:
        raise ConfigError(f"`workers` must be >= 1, got {workers}")
    if dask is not None:
        from .cluster import parse_local_address

        parse_local_address(dask)  # a malformed local:K fails here, before anything is written
    if isinstance(polish, bool) or not isinstance(polish, (int, np.integer)) or polish < 0:
        raise ConfigError(f"`polish` must be an integer >= 0, got {polish!r}")
    if isinstance(polish_evaluations, bool) or not isinstance(polish_evaluations, (int, np.integer)) \
            or polish_evaluations < 1:
        raise ConfigError(f"polish_evaluations must be an integer >= 1, got {polish_evaluations!r}")
    per = per or ident.per or "sensor"
    if per not in ("sensor", "experiment"):
        raise ConfigError(f"`per`: unknown {per!r}; allowed: sensor, experiment")
    # the seed's stabilising objective (max growth factor of the θ-scheme) belongs to that scheme
    if stabilising is None:
        stabilising = cfg.time.scheme == "theta" if ident.stabilising is None else ident.stabilising
    noise_std = given_noise_std(cfg, noise_std)
    out = _check_out_dir(Path(out_dir), resume)
    exps = read_data(cfg, data)
    space: ParameterSpace = parameter_space(cfg)
    evaluator = NativeEvaluator(cfg, space, _arrays(cfg, exps), per=per, stabilising=bool(stabilising))
    fisher0 = fisher_information(evaluator, space.nominal, noise_std=noise_std)
    if fisher0.singular and not force:
        raise ConfigError(["identifiability: the Fisher information matrix is singular at the nominal point "
                           f"(rank {fisher0.rank} of {space.dim})", *fisher0.messages,
                           "remove or fix the unidentifiable unknowns, change sensors/inputs, or use `force`"])
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
    created = not out.exists()
    make_dir(out, exist_ok=True)
    try:
        write_json(out / "identifiability.json", fisher0.to_dict())
        problem = IdentificationProblem(search_evaluator, names)

        def generation_done(gen: int, n_ev: int, X: np.ndarray, F: np.ndarray) -> None:
            if on_progress is not None:
                on_progress(Progress("generation", gen, n_ev, X, F, knee_index(F, names)))

        try:
            with make_runner(workers=workers, dask=dask) as runner:
                pareto = optimise(problem, pop=pop, generations=generations, seed=seed, algorithm=algorithm,
                                  out_dir=out, resume=resume, runner=runner, progress=progress,
                                  callback=generation_done)
                polished_raw = _polish_front(pareto, search_evaluator, runner, int(polish), int(polish_evaluations),
                                             on_progress)
        finally:
            if search_evaluator is not evaluator:
                search_evaluator.close()
            if tmp_fmu_dir is not None:
                import shutil

                shutil.rmtree(tmp_fmu_dir, ignore_errors=True)
        crb, g, st = [], [], []
        for x in pareto.X:
            c_, g_, s_ = _point_properties(cfg, space, evaluator, x, fisher0.noise_std)
            crb.append(c_)
            g.append(g_)
            st.append(s_)
        polished = []
        for i, x, f, n_ev, r in polished_raw:
            c_, g_, s_ = _point_properties(cfg, space, evaluator, x, fisher0.noise_std)
            polished.append(PolishedPoint(i, x, f, c_, g_, s_, n_ev, r.cost, r.success, r.message))
        best_x = polished_raw[0][1] if polished_raw else pareto.X[pareto.knee]
        adequacy = numerical_adequacy(*space.apply(cfg, best_x),
                                      [(e.inputs, e.outputs) for e in evaluator.experiments], fisher0.noise_std)
        res = IdentificationResult(pareto, fisher0, np.array(crb), np.array(g), np.array(st), out, tuple(polished),
                                   adequacy)
        _write_results(res, cfg, evaluator,
                       Path(config).stem if not isinstance(config, BeamConfig) else "beam")
        if export:
            from .export import export_points

            export_points(out)
    except KeyboardInterrupt:
        # resumable once a generation is checkpointed; before that, leave nothing behind
        if not (out / CHECKPOINT).exists():
            _remove_partial(out, created)
        raise
    except OutputError as exc:
        # a full disk or a file system gone read-only mid-run: the atomic writes left no partial file
        if (out / CHECKPOINT).exists():
            raise OutputError(f"{exc}; the checkpoint of the last finished generation is kept in {out}: make room, "
                              "then continue with `resume`", path=exc.path, errno=exc.errno) from None
        _remove_partial(out, created)
        raise OutputError(f"{exc}; nothing was kept", path=exc.path, errno=exc.errno) from None
    return res


def _remove_partial(out: Path, created: bool) -> None:
    """Remove what a run wrote into ``out`` before its first checkpoint (``out`` was absent or empty:
    :func:`_check_out_dir`)."""
    import shutil

    if created:
        shutil.rmtree(out, ignore_errors=True)
        return
    for item in out.iterdir():
        if item.is_dir():
            shutil.rmtree(item, ignore_errors=True)
        else:
            item.unlink(missing_ok=True)


def _polish_front(pareto: ParetoSet, evaluator: Any, runner: Runner, k: int, budget: int,
                  on_progress: Callable[[Progress], None] | None) -> list[tuple[int, np.ndarray, np.ndarray, int, Any]]:
    """Polish the ``k`` points nearest the knee (knee first): ``(from_index, x, F, evaluations, result)``."""
    out: list[tuple[int, np.ndarray, np.ndarray, int, Any]] = []
    n_done = pareto.n_evaluations
    for step, i in enumerate(knee_order(pareto.F, pareto.objective_names)[:k]):
        r = polish_point(evaluator, pareto.X[i], runner=runner, max_evaluations=budget)
        f = np.asarray(runner(evaluator, r.x[None, :]))[0]
        n_ev = r.n_evaluations + 1
        n_done += n_ev
        out.append((int(i), r.x, f, n_ev, r))
        if on_progress is not None:
            on_progress(Progress("polish", step, n_done, r.x[None, :], f[None, :], 0))
    return out


def _point_properties(cfg: BeamConfig, space: ParameterSpace, evaluator: NativeEvaluator, x: np.ndarray,
                      noise_std: np.ndarray) -> tuple[np.ndarray, float, bool]:
    """Cramér–Rao std, growth factor and stability of candidate ``x`` (native model)."""
    c, params = space.apply(cfg, x)
    g = float(max_growth_factor(c, params))
    stable = evaluator.simulate(x).stable
    try:
        crb = fisher_information(evaluator, x, noise_std=noise_std).cramer_rao_std
    except StabilityError:
        crb = np.full(space.dim, np.inf)
    return crb, g, stable


def _write_results(res: IdentificationResult, cfg: BeamConfig, evaluator: NativeEvaluator,
                   config_name: str) -> None:
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
    polished = []
    for j, q in enumerate(res.polished):
        polished.append({
            "index": j,
            "from_index": int(q.from_index),
            "parameters": dict(zip(p.parameter_names, map(float, q.x))),
            "objectives": dict(zip(p.objective_names, map(float, q.objectives))),
            "cramer_rao_std": {k: float(v) for k, v in zip(p.parameter_names, q.cramer_rao_std)},
            "growth_factor": float(q.growth_factor),
            "stable": bool(q.stable),
            "n_evaluations": int(q.n_evaluations),
            "cost": float(q.cost),
            "success": bool(q.success),
            "message": q.message,
        })
    n_polish = sum(q["n_evaluations"] for q in polished)
    doc = {
        "config": cfg.to_dict(),
        "config_name": config_name,
        "identified": res.identified,
        "parameter_names": list(p.parameter_names),
        "objective_names": list(p.objective_names),
        "knee": int(p.knee),
        "n_evaluations": int(p.n_evaluations + n_polish),
        "n_evaluations_ga": int(p.n_evaluations),
        "n_evaluations_polish": int(n_polish),
        "generations": int(p.generations),
        "points": points,
        "polished": polished,
        # at the reported point (the polished knee, else the knee): how much of its gap is the grid's
        "numerical_adequacy": res.adequacy.to_dict() if res.adequacy is not None else None,
    }
    # the growth factor is a column once: as an objective when the stabilising objective is on, else on its own
    extra = [] if "growth_factor" in p.objective_names else ["growth_factor"]
    head = [*p.parameter_names, *p.objective_names, *[f"crb_{n}" for n in p.parameter_names], *extra, "stable"]

    def row(q: dict[str, Any]) -> list[Any]:
        return [*q["parameters"].values(), *q["objectives"].values(), *q["cramer_rao_std"].values(),
                *([q["growth_factor"]] if extra else []), int(q["stable"])]

    _write_csv(res.out_dir / "pareto.csv", ["index", "knee", *head],
               [[pt["index"], int(pt["knee"]), *row(pt)] for pt in points])
    stale = res.out_dir / "polished.csv"
    if polished:
        _write_csv(stale, ["index", "from_index", *head, "n_evaluations", "success"],
                   [[q["index"], q["from_index"], *row(q), q["n_evaluations"], int(q["success"])] for q in polished])
    elif stale.exists():      # a resumed run without polish: no header-only file
        stale.unlink()
    from .plots import plot_results

    plot_results(res, evaluator)
    write_json(res.out_dir / "pareto.json", doc)  # last: it marks the run as finished


def _write_csv(path: Path, header: list[str], rows: list[list[Any]]) -> None:
    with atomic_path(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
