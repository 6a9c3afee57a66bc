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
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ebb_model import max_growth_factor
from ebb_model.acquisition.bandlimited import hold_hint
from ebb_model.space.adequacy import grid_line
from ebb_model.io.output import atomic_path
from ebb_model.config import BeamConfig
from ebb_model.threads import one_blas_thread
from ebb_model.errors import ClusterError, ConfigError, OutputError, StabilityError
from ebb_model.io.htmlio import PAGE, write_page
from ebb_model.io.jsonio import write_json
from ebb_model.io.output import check_new_output_dir, check_writable_dir, make_dir

from .data import Experiment, load_experiments
from .data_start import DataStart, data_start
from .start_modes import scale_moves_modes
from .export_targets import DEFAULT_TARGETS, check_targets
from .fisher import fisher_information, nominal_fisher
from .basins import better_of, noise_at, polish_basins
from .fit_hints import fit_hints
from .progress import Progress
from .numerics import grid_adequacy, refine_numerics
from .noise_model import NoiseModel, estimate_noise_model
from .modal_data import modal_data
from .prior import Prior, PriorCheck
from .report import html_sections
from .native import ExperimentArrays, NativeEvaluator
from .objectives import objective_names
from .optimise import CHECKPOINT, ParetoSet, check_settings, knee_index, optimise
from .parameters import ParameterSpace, parameter_space
from .problem import IdentificationProblem
from .resume import RunRecord
from .result import RESULT_FILE, IdentificationResult, PolishedPoint
from .runners import make_runner
from .noise import given_noise_std
from .config_file import load_identification_config
from .settings import identification_settings
from .uncertainty import uncertainty_model, write_uncertainty

__all__ = ["BACKENDS", "IdentificationResult", "PolishedPoint", "Progress", "identify",
           "load_identification_config", "read_data"]

BACKENDS = ("auto", "native", "fmu")
def read_data(config: BeamConfig, paths: Sequence[str | Path]) -> tuple[Experiment, ...]:
    """Load and check the experiments with the options of ``[identification.data]``."""
    if not paths:
        raise ConfigError("DATA: at least one data file is required")
    opts = dict(identification_settings(config).data)
    exps = load_experiments(list(paths), config, **opts)
    for e in exps:
        e.check_against(config)
    return exps


def _arrays(config: BeamConfig, exps: Sequence[Experiment]) -> tuple[ExperimentArrays, ...]:
    out = []
    for e in exps:
        idx = [e.output_names.index(s.name) for s in config.sensors]
        out.append(ExperimentArrays(e.name, np.asarray(e.inputs), np.asarray(e.outputs)[:, idx]))
    return tuple(out)


def _check_out_dir(out: Path, resume: bool) -> Path:
    """The result directory: new (absent or empty) for a run, an interrupted run's for ``resume``."""
    finished = (out / RESULT_FILE).exists()
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
             backend: str = "auto", workers: int = 1, dask: str | None = None, pop: int | None = None,
             generations: int | None = None, seed: int | None = None, resume: bool = False, force: bool = False,
             algorithm: str | None = None, per: str | None = None, stabilising: bool | None = None,
             noise_std: ArrayLike | None = None, progress: bool = True, export: bool = True,
             fmu: str | Path | None = None, fmu_parameters: Sequence[str] | None = None,
             fmu_inputs: Sequence[str] | None = None, fmu_outputs: Sequence[str] | None = None,
             polish: int = 1, polish_evaluations: int = 200, targets: Sequence[str] = DEFAULT_TARGETS,
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

    ``pop``, ``generations``, ``seed`` and ``algorithm`` default to 40, 30, 1 and ``"nsga2"`` — resuming, to the
    checkpoint's; ``resume`` refuses a checkpoint made with another config, other records or another value of an
    option given (:mod:`identification.resume`).

    ``polish = K`` refines the ``K`` Pareto points nearest the knee (knee
    first) with bounded least squares on the search backend and workers, at
    most ``polish_evaluations`` residual evaluations each (their Jacobians
    come on top and are counted).  The default, 1, polishes the knee: that
    is *the* identified model (:attr:`IdentificationResult.best`, ``identified``
    in ``pareto.json``); ``polish = 0`` reports the GA's knee, marked as not
    polished.  ``export`` writes every Pareto and polished point through the
    export ``targets`` (:data:`identification.export.TARGETS`) into
    ``out_dir/export``.  ``on_progress`` receives a
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
    # the GA's options: as given, else — resuming — the checkpoint's, else the defaults (identification.resume)
    stored = RunRecord.read(Path(out_dir)) if resume else None
    ga = RunRecord.options_for(stored, {"pop": pop, "generations": generations, "seed": seed,
                                        "algorithm": algorithm})
    pop, generations, seed, algorithm = ga["pop"], ga["generations"], ga["seed"], ga["algorithm"]
    _check_options(backend, pop, generations, algorithm, fmu, workers, dask, polish, polish_evaluations)
    if backend == "fmu" and cfg.time.input_hold == "bandlimited":
        raise ConfigError("`backend` fmu: an FMU takes the force sample by sample and cannot read the samples ahead "
                          "that [time] input = \"bandlimited\" needs; use the native backend (the FMU takes "
                          "\"cubic\")")
    per = per or ident.per or "sensor"
    if per not in ("sensor", "experiment"):
        raise ConfigError(f"`per`: unknown {per!r}; allowed: sensor, experiment")
    # the seed's stabilising objective (max growth factor of the θ-scheme) belongs to that scheme
    if stabilising is None:
        stabilising = cfg.time.scheme == "theta" if ident.stabilising is None else ident.stabilising
    noise_std = given_noise_std(cfg, noise_std)
    targets = check_targets(targets, cfg)
    out = _check_out_dir(Path(out_dir), resume)
    exps = read_data(cfg, data)
    hold_note = hold_hint(cfg, [e.inputs for e in exps])
    run_record = RunRecord.of(cfg, exps, ga)
    if stored is not None:
        stored.check(run_record, out)
    space: ParameterSpace = parameter_space(cfg)
    evaluator = NativeEvaluator(cfg, space, _arrays(cfg, exps), per=per, stabilising=bool(stabilising))
    fisher0 = nominal_fisher(evaluator, noise_std=noise_std)
    if fisher0.singular and not force:
        raise ConfigError(["identifiability: the Fisher information matrix is singular at the nominal point "
                           f"(rank {fisher0.rank} of {space.dim})", *fisher0.messages,
                           "remove or fix the unidentifiable unknowns, change sensors/inputs, or use `force`"])
    names = objective_names(cfg.output_names, [e.name for e in exps], per=per, stabilising=bool(stabilising))
    search_evaluator: Any = evaluator
    tmp_fmu_dir = None
    if backend == "fmu":
        search_evaluator, tmp_fmu_dir = _fmu_evaluator(evaluator, fmu, fmu_parameters, fmu_inputs, fmu_outputs)
    on_fmu = search_evaluator is not evaluator
    created = not out.exists()
    make_dir(out, exist_ok=True)
    try:
        write_json(out / "identifiability.json", fisher0.to_dict())
        if not resume:
            run_record.write(out)
        problem = IdentificationProblem(search_evaluator, names)

        def generation_done(gen: int, n_ev: int, X: np.ndarray, F: np.ndarray) -> None:
            if on_progress is not None:
                on_progress(Progress("generation", gen, n_ev, X, F, knee_index(F, names)))

        try:
            with make_runner(workers=workers, dask=dask) as runner:
                # what the records say first: the basin of the global answer (identification.data_start)
                start = data_start(evaluator, runner)
                pareto = optimise(problem, pop=pop, generations=generations, seed=seed, algorithm=algorithm,
                                  out_dir=out, resume=resume, runner=runner, progress=progress,
                                  callback=generation_done, initial=None if start is None else start.x[None, :])
                polish_noise = (NoiseModel.white(noise_std, len(exps)) if noise_std is not None
                                else noise_at(evaluator, better_of(evaluator, pareto.X[pareto.knee], start)))
                polished_raw = polish_basins(pareto, search_evaluator, runner, int(polish), int(polish_evaluations),
                                             on_progress, polish_noise, Prior.of(cfg, space.names), modal_data(cfg),
                                             start)
                if not on_fmu and polished_raw:
                    # the numerics the records ask for (identification.numerics); the hint is then theirs to give
                    evaluator, polished_raw, hold_note = refine_numerics(
                        evaluator, polished_raw, runner, int(polish_evaluations), polish_noise,
                        lambda c: NativeEvaluator(c, space, _arrays(c, exps), per=per, stabilising=bool(stabilising)))
                events = runner.events()
        finally:
            if on_fmu:
                search_evaluator.close()
            if tmp_fmu_dir is not None:
                import shutil

                shutil.rmtree(tmp_fmu_dir, ignore_errors=True)
        res = _result(evaluator, pareto, polished_raw, fisher0, noise_std is not None, out,
                      Path(config).stem if not isinstance(config, BeamConfig) else "beam", start)
        res = replace(res, events=events, hints=res.hints if hold_note is None else (hold_note, *res.hints))
        _write_uncertainty(res, evaluator)
        _write_results(res, evaluator)
        if export:
            from .export import export_points

            export_points(res, targets=targets)
    except KeyboardInterrupt:
        # resumable once a generation is checkpointed; before that, leave nothing behind
        if not (out / CHECKPOINT).exists():
            _remove_partial(out, created)
        raise
    except ClusterError as exc:
        # the cluster's scheduler gone mid-run: what it was computing is lost, the last generation's checkpoint is not
        if (out / CHECKPOINT).exists():
            raise ClusterError(f"{exc}; the checkpoint of the last finished generation is kept in {out}: continue "
                               "with `resume` on a running cluster (or on local workers)") from None
        _remove_partial(out, created)
        raise ClusterError(f"{exc}; nothing was kept") from None
    except OutputError as exc:
        # a full disk or a file system gone read-only mid-run: the atomic writes left no partial file
        if (out / RESULT_FILE).exists():
            # the run has finished and its results are written; what failed is the exports
            raise OutputError(f"{exc}; the results are written in {out} ({RESULT_FILE}): make room, then write "
                              "the exports with `export_points` on it", path=exc.path, errno=exc.errno) from None
        if (out / CHECKPOINT).exists():
            raise OutputError(f"{exc}; the checkpoint of the last finished generation is kept in {out}: make room, "
                              "then continue with `resume`", path=exc.path, errno=exc.errno) from None
        _remove_partial(out, created)
        raise OutputError(f"{exc}; nothing was kept", path=exc.path, errno=exc.errno) from None
    return res


def _write_uncertainty(res: IdentificationResult, evaluator: NativeEvaluator) -> None:
    """The identified model's uncertainty into ``out_dir/uncertainty`` (:mod:`identification.uncertainty`);
    nothing when it is unstable."""
    x = res.polished[0].x if res.polished else res.pareto.X[res.pareto.knee]
    assert res.noise is not None            # _result sets it; only a result read back has none
    try:
        model = uncertainty_model(evaluator, x, res.noise)
    except StabilityError:
        return
    write_uncertainty(model, evaluator, res.out_dir, f"{res.config_name}_identified")


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


def _check_options(backend: str, pop: int, generations: int, algorithm: str, fmu: str | Path | None, workers: int,
                   dask: str | None, polish: int, polish_evaluations: int) -> None:
    """Every option of :func:`identify` that needs no data, checked before anything is written.

    Raises
    ------
    ConfigError
        The first bad option, named.
    """
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


def _fmu_evaluator(native: NativeEvaluator, fmu: str | Path | None, parameters: Sequence[str] | None,
                   inputs: Sequence[str] | None, outputs: Sequence[str] | None) -> tuple[Any, str | None]:
    """The FMU backend's evaluator of ``native``'s problem: through ``fmu``, or an FMU built from the config into
    a temporary directory (returned too, for removal; ``None`` for a given FMU)."""
    from .fmu_backend import FmuEvaluator

    tmp_fmu_dir = None
    if fmu is None:
        import tempfile

        from fmu_build import build_fmu

        tmp_fmu_dir = tempfile.mkdtemp(prefix="ebb-fmu-")
        fmu = build_fmu(native.config, Path(tmp_fmu_dir) / "beam.fmu")
    return FmuEvaluator(str(fmu), native.config, native.space, native.experiments,
                        tuple(parameters) if parameters else None, tuple(inputs) if inputs else None,
                        tuple(outputs) if outputs else None, per=native.per,
                        stabilising=native.stabilising), tmp_fmu_dir


def _result(evaluator: NativeEvaluator, pareto: ParetoSet,
            polished_raw: list[tuple[int, np.ndarray, np.ndarray, int, Any]], fisher0: Any, noise_given: bool,
            out: Path, config_name: str, start: DataStart | None = None) -> IdentificationResult:
    """The run's result: the noise model of each experiment (the given white level, else estimated from the
    identified model's residual, :mod:`identification.noise_model`), and under it the Cramér–Rao std of every
    Pareto and polished point, their growth factor and stability (native model), the identified model's whitened
    fit residual and its numerical adequacy."""
    cfg, space, exps = evaluator.config, evaluator.space, evaluator.experiments
    best_x = polished_raw[0][1] if polished_raw else pareto.X[pareto.knee]
    best = evaluator.simulate(best_x)
    if noise_given or not best.stable:
        noise = NoiseModel.white(fisher0.noise_std, len(exps))
    else:
        noise = estimate_noise_model([e.inputs for e in exps], [e.outputs - y for e, y in zip(exps, best.outputs)],
                                     cfg.time.dt)
    props = [_point_properties(cfg, space, evaluator, x, noise) for x in pareto.X]
    polished = tuple(PolishedPoint(i, x, f, *_point_properties(cfg, space, evaluator, x, noise), n_ev, r.cost,
                                   r.success, r.message) for i, x, f, n_ev, r in polished_raw)
    advice, adequacy = grid_adequacy(evaluator, best_x, noise, best.stable)
    prior, modes = Prior.of(cfg, space.names), modal_data(cfg)
    grid = {**advice.to_dict(), "summary": grid_line(advice, adequacy)}
    priors: tuple[PriorCheck, ...] = ()
    if prior.count and best.stable:
        fi = fisher_information(evaluator, best_x, noise=noise)
        priors = tuple(prior.judge(best_x, prior.posterior_std(fi.matrix, fi.scales)))
    agreement = modes.agreement(*space.apply(cfg, best_x)) if modes is not None else None
    fit_gap = None
    hints: list[str] = []
    if best.stable:
        whitened = np.concatenate([noise.whiten(i, y - e.outputs) for i, (e, y) in enumerate(zip(exps, best.outputs))])
        fit_gap = dict(zip(cfg.output_names, map(float, np.mean(whitened ** 2, axis=0))))
        # a common scale of EI, ρA, c and N leaves the frequencies alone unless a declared mass, spring or fixed
        # axial force is there
        level_free = "EI" in space.names and "rhoA" in space.names and not scale_moves_modes(evaluator, best_x)
        hints += fit_hints(cfg.output_names, [e.outputs for e in exps], best.outputs, fit_gap, level_free, start)
    best_crb = polished[0].cramer_rao_std if polished else props[pareto.knee][0]
    return IdentificationResult(
        config=cfg, space=space, pareto=pareto, cramer_rao_std=np.array([p[0] for p in props]),
        growth_factors=np.array([p[1] for p in props]), stable=np.array([p[2] for p in props]), out_dir=out,
        config_name=config_name, polished=polished, adequacy=adequacy, fisher_nominal=fisher0, fit_gap_ratio=fit_gap,
        noise_model=tuple(noise.describe(cfg.output_names, [e.name for e in exps])), noise=noise, priors=priors,
        modal_agreement=agreement, data_start=None if start is None else start.to_dict(space.names),
        hints=tuple(hints), cramer_rao_note=_cramer_rao_note(evaluator, best_x, noise, best_crb), grid_advice=grid)


def _cramer_rao_note(evaluator: NativeEvaluator, x: np.ndarray, noise: NoiseModel, crb: np.ndarray) -> str | None:
    """Why the identified point's Cramér–Rao standard deviations cannot be computed (some are not finite);
    ``None`` when they can."""
    if np.all(np.isfinite(crb)):
        return None
    try:
        fi = fisher_information(evaluator, x, noise=noise)
    except StabilityError as exc:
        return f"not computable: {exc}"
    if fi.singular:
        return (f"not computable: the Fisher information is singular at the identified point (rank {fi.rank} of "
                f"{len(crb)}): " + "; ".join(fi.messages))
    return "not computable: the Fisher information could not be inverted at the identified point"


def _point_properties(cfg: BeamConfig, space: ParameterSpace, evaluator: NativeEvaluator, x: np.ndarray,
                      noise: NoiseModel) -> tuple[np.ndarray, float, bool]:
    """Cramér–Rao std (under the noise model), growth factor and stability of candidate ``x`` (native model)."""
    c, params = space.apply(cfg, x)
    g = float(max_growth_factor(c, params))
    stable = evaluator.simulate(x).stable
    try:
        crb = fisher_information(evaluator, x, noise=noise).cramer_rao_std
    except StabilityError:
        crb = np.full(space.dim, np.inf)
    return crb, g, stable


def _write_results(res: IdentificationResult, evaluator: NativeEvaluator) -> None:
    """``pareto.csv``, ``polished.csv`` (when polished), the plots, and last ``pareto.json`` (it marks the run as
    finished)."""
    doc = res.to_dict()
    points, polished, p = doc["points"], doc["polished"], res.pareto
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
    write_page(res.out_dir / PAGE, f"ebb identify: {res.config_name}", html_sections(res),
               subtitle="records: " + ", ".join(e.name for e in evaluator.experiments))
    write_json(res.out_dir / RESULT_FILE, doc)  # last: it marks the run as finished


def _write_csv(path: Path, header: list[str], rows: list[list[Any]]) -> None:
    with atomic_path(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
