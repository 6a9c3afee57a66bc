"""The gap diagnosis as one API call (what ``ebb diagnose`` runs): a thin orchestrator of the stages.

config + data (+ held-out records or a held-out tail of each record) → **baseline** (:mod:`diagnosis.baseline`:
fitted on the fit windows from an identification result or the nominal values, the force's sign weighed, the
noise model) → **candidates** (:mod:`diagnosis.candidates`) → **search** (:mod:`diagnosis.search`: score tests,
refits, ranking) → numerical adequacy of the grid → **localisation** of the residual (:mod:`diagnosis.localise`:
where) → **judgement** (:mod:`diagnosis.judgement`: the verdict through its ordered rules) → the **next
experiment** when candidates remain tied (:mod:`diagnosis.design`) → **report** (:mod:`diagnosis.report`: held-out
gap before/after per sensor and band, ``gap.json``, figures, the page) and the **corrected model**
(:mod:`diagnosis.corrected`).

Bad input is detected before anything is written; the output directory appears only when complete.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence, cast

import numpy as np

from ebb_model.space.adequacy import adequacy_grid, excited_band, grid_line, modes_top, numerical_adequacy
from ebb_model.config import BeamConfig
from ebb_model.errors import ClusterError, ConfigError
from ebb_model.space.grid_advice import grid_advice
from ebb_model.io.htmlio import PAGE, write_page
from ebb_model.io.jsonio import write_json
from ebb_model.modal.modal import discrete_frequencies
from ebb_model.io.output import check_new_output_dir, staged_dir
from ebb_model.threads import one_blas_thread

from identification.cluster import parse_local_address
from identification.export_targets import DEFAULT_TARGETS, check_targets
from identification.grid_shift import on_the_grid_of, shift_between
from identification.modal_data import modal_data
from identification.noise import given_noise_std, records_noise_std
from identification.parameters import parameter_space
from identification.prior import Prior
from identification.result import IdentificationResult
from identification.run import load_identification_config, read_data

from .baseline.fit import baseline_fit, floor_from_the_records, start_from_result
from .baseline.noise import noise_of, under_the_noise
from .baseline.polarity import PolarityCheck, check_polarity
from .candidates.catalogue import catalogue_of
from .effects import Catalogue, Effect
from .design import next_experiment
from .judgement.rules import Case, Judgement, judge
from .judgement.verdict import Kind, settled
from .judgement.weigh import Weighed, weigh
from .localise import Localisation, localise
from .problem.evidence import earlier_evidence
from .problem.fitting import Fit, GapProblem
from .problem.records import ordered_record, split_records
from .report.assemble import effect_rows, gap_report
from .report.html import html_sections
from .report.result import DiagnosisSettings, GapReport
from .judgement.apart import SetupsApart, apart_parts, disagreement
from .search.lead import LeadNumerics, lead
from .search.reuse import RefitMemo
from .search.plausible import plausible_readings
from .search.modal_pattern import PatternFit, carried
from .search.modal_source import modal_source
from .search.rank import Ranking, rank_effects
from .search.rebase import against_the_best_baseline
from .search.sign import sign_with_refits
from .search.workers import DaskExecutor, close_refit_pool, refit_pool
from .settings import thresholds_from_config
from .setups import RIG_PARTS, Setups, setups_from_config
from .stages import StageClock

__all__ = ["Diagnosis", "diagnose", "GAP_FILE"]

GAP_FILE = "gap.json"


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """Outcome of :func:`diagnose`: the problem solved (records, unknowns, noise — the force's sign as taken), the
    search's ranking, what was found (:class:`~diagnosis.report.result.GapReport`) and where it was written."""

    problem: GapProblem
    ranking: Ranking
    report: GapReport
    out_dir: Path | None

    @property
    def verdict(self) -> str:
        """Label of the effect that explains the gap, ``"none"``, ``"unexplained"`` (a gap no effect of the
        catalogue explains), ``"indistinguishable"`` or ``"grid"`` (the model's own discretisation error)."""
        return self.report.verdict

    @property
    def document(self) -> dict[str, Any]:
        """The ``gap.json`` document (:meth:`GapReport.to_dict`)."""
        return self.report.to_dict()


@one_blas_thread
def diagnose(config: BeamConfig | str | Path, data: Sequence[str | Path], out_dir: str | Path | None, *,
             holdout: Sequence[str | Path] = (), result: IdentificationResult | str | Path | None = None,
             holdout_fraction: float = 0.3, shortlist: int | None = None, noise_std: Sequence[float] | None = None,
             plots: bool = True, export: bool = True, targets: Sequence[str] = DEFAULT_TARGETS, workers: int = 2,
             dask: Any = None, earlier: str | Path | None = None,
             progress: Callable[[str], None] | None = None) -> Diagnosis:
    """Locate the sim-to-real gap, name the effect that explains it, and measure how far it closes.

    Parameters
    ----------
    config
        Identification config (path or value): geometry, sensors, the baseline
        unknowns (``identify = true``) with bounds.
    data
        Measured records to fit (any format of :mod:`identification.data`).
    out_dir
        Directory for ``gap.json`` and plots; must not exist or be empty.
        ``None`` writes nothing (API use).
    holdout
        Records held out entirely; without them the last ``holdout_fraction``
        of every record is held out.
    result
        An identification result, or an ``ebb identify`` output directory: the baseline fit starts from its
        identified model (the polished knee) instead of the nominal values.
    shortlist
        Number of best-scoring effects that are refitted.
    noise_std
        Measurement-noise standard deviation per sensor; default the
        config's ``[identification] noise_std``, else estimated from the data
        (noise floor above the excited band).
    export
        When the verdict names an effect, write the corrected model (baseline
        plus that effect, refitted) to ``out_dir/corrected/``: config,
        python-control StateSpace and FMU (:mod:`diagnosis.corrected.export`).
    targets
        With ``export``, the export targets of the corrected model
        (:data:`identification.export_targets.TARGETS`; ``standalone`` adds
        ``corrected_standalone.fmu``, the standalone C FMU).
    workers
        Processes refitting the shortlisted effects side by side (default 2;
        1: all in this process).  The result does not depend on it.
    dask
        Refit on a Dask cluster instead: a scheduler address, ``"local:K"``
        (a local cluster of K workers, started and closed here) or a connected
        ``distributed.Client``.  The result does not depend on it either.
    earlier
        The ``gap.json`` (or its directory) of an earlier diagnosis of the same bench on other records — the
        record a next experiment (:mod:`diagnosis.design`) asked for is weighed with the records that asked for
        it: the posterior odds between the models start from the earlier ones
        (:func:`~diagnosis.problem.evidence.log_posteriors`).

    Returns
    -------
    Diagnosis

    Raises
    ------
    ConfigError, DataError
        Bad config, data or settings — before anything is written.
    """
    say = progress or (lambda _m: None)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers: must be a whole number >= 1, got {workers!r}")
    if isinstance(dask, str):
        parse_local_address(dask)     # a malformed local:K stops the run before anything is written
    cfg = load_identification_config(config) if not isinstance(config, BeamConfig) else config
    settings = thresholds_from_config(cfg, shortlist=shortlist)
    setups = setups_from_config(cfg)
    targets = check_targets(targets, cfg)
    prior_odds = earlier_evidence(earlier, GAP_FILE) if earlier is not None else None
    out = Path(out_dir) if out_dir is not None else None
    if out is not None:
        check_new_output_dir(out)
    exps = read_data(cfg, data)
    held = read_data(cfg, holdout) if holdout else ()
    records = split_records([ordered_record(cfg, e) for e in exps], [ordered_record(cfg, e) for e in held],
                            holdout_fraction=holdout_fraction)
    space = parameter_space(cfg)
    beta0 = start_from_result(result, space.names) if result is not None else np.asarray(space.nominal)
    dt = cfg.time.dt
    given = given_noise_std(cfg, noise_std)
    sigma = given if given is not None else records_noise_std([r.inputs for r in records],
                                                              [r.outputs for r in records], dt)
    modes = modal_data(cfg)
    if setups is not None and modes is not None and "modes" not in setups.names:
        raise ConfigError("setups: the config gives measured modes but no set-up holds them (evidence = [\"modes\"])")
    problem = GapProblem(cfg, space, records, sigma, prior=Prior.of(cfg, space.names), modes=modes,
                         settings=settings, modes_lack=frozenset() if setups is None else setups.modes_lack())
    clock = StageClock()
    executor = refit_pool(workers, dask)
    try:
        memo = RefitMemo()      # the local refits, for the rankings that would repeat them
        search = partial(_search, beta0=beta0, fit_noise=given is None, setups=setups, executor=executor,
                         parallel=executor.workers if isinstance(executor, DaskExecutor) else workers, clock=clock,
                         say=say, memo=memo)
        found = _signed(problem, search, executor, clock, say)
        case = _case(found, clock, say, prior_odds)
        judgement = judge(case)
        say(f"verdict: {judgement.verdict.name}")
        case, setups, tried = _apart(case, judgement, found, setups, executor, clock, say, memo, prior_odds)
        case = _readings(case, tried, found, executor, clock, say)
        judgement = judge(case)                 # every change of the verdict goes through the rules
        problem, ranking = case.problem, case.ranking
        # when candidates remain tied or the gap is unexplained: the record that would separate them
        with clock.stage("next experiment"):
            nxt = next_experiment(problem, ranking, judgement, found.modes.band, found.modes.freqs, case.readings)
        if nxt is not None:
            say(nxt.line())
        report = _report(case, judgement, found, DiagnosisSettings(
            tuple(str(h) for h in holdout), None if holdout else holdout_fraction, settings), clock, executor)
        report = replace(report, setups=setups, next_experiment=nxt)
        for event in report.events:
            say(f"note: {event}")
        if out is None:
            return Diagnosis(problem, ranking, report, None)
        report = _write(out, problem, ranking, report, case.locs, plots=plots, export=export, targets=targets,
                        clock=clock)
        return Diagnosis(problem, ranking, report, out)
    except BaseException as exc:
        if executor is not None:
            close_refit_pool(executor, now=True)     # Ctrl-C or a failure: the fits in flight are not waited for
            executor = None
        if isinstance(exc, ClusterError) and out is not None:
            raise ClusterError(f"{exc}; nothing was written to {out} (a diagnosis writes its results when it "
                               "ends)") from None
        raise
    finally:
        if executor is not None:
            close_refit_pool(executor, now=False)


def _signed(problem: GapProblem, search: Callable[..., _Found], executor: Any, clock: StageClock,
            say: Callable[[str], None]) -> _Found:
    """The search, and again with the other sign when the force's sign weighed with the mechanisms overturns the
    baseline's (:func:`~diagnosis.search.sign.sign_with_refits`: when no refit reaches the noise floor with the sign
    taken)."""
    found = search(problem)
    with clock.stage("the force's sign with the refits"):
        resign = sign_with_refits(found.problem, found.ranking, found.catalogue, found.polarity, executor)
    if resign is None:
        return found
    say(resign.line())
    if resign.overturned:
        found = search(problem, take=not found.polarity.reversed)
    return replace(found, polarity=replace(found.polarity, with_refits=resign))


def _case(found: _Found, clock: StageClock, say: Callable[[str], None], earlier: Mapping[str, float] | None
          ) -> Case:
    """What the rules judge: the grid's share of the gap (a gap that refining the grid changes is not blamed on
    physics), where the baseline's residual lies, and the evidence measured once."""
    problem, ranking = found.problem, found.ranking
    records, sigma, cfg = problem.records, problem.noise_std, problem.config
    base_cfg, base_params = problem.space.apply(cfg, ranking.baseline.beta)
    f_hi = found.modes.band[1]
    say("numerical adequacy of the model's grid")
    with clock.stage("numerical adequacy"):
        advice = grid_advice(base_cfg, base_params, band_hz=f_hi)
        adequacy = numerical_adequacy(
            base_cfg, base_params, [(r.inputs[:r.fit_end], r.outputs[:r.fit_end]) for r in records if r.has_fit],
            sigma, band_hz=f_hi, advice=advice)
        # what the refined grid would do to the baseline, in its Cramér–Rao deviations (identification.grid_shift)
        fine = replace(problem, config=on_the_grid_of(cfg, adequacy_grid(base_cfg, base_params, f_hi, advice)))
        adequacy = replace(adequacy, shift=shift_between(problem.space, ranking.baseline.beta, problem.residuals,
                                                         fine.residuals, cfg.beam.nodes, fine.config.beam.nodes))
    mf, mz = found.modes.freqs[found.modes.in_band], found.modes.zetas[found.modes.in_band]
    with clock.stage("localisation"):
        base_all = cast(list[np.ndarray], problem.simulate(ranking.baseline.beta, until="all"))   # every record
        locs = tuple(localise(cfg.time.dt, r.inputs, r.outputs, y, cfg.output_names, mf, mz, noise_std=sigma,
                              input_names=cfg.input_names) for r, y in zip(records, base_all))
    where = tuple(f"{r.name}: {s}" for r, loc in zip(records, locs) for s in loc.summary[:2])
    with clock.stage("plausibility and evidence"):
        weighed = _weighed(problem, ranking, f_hi, say, earlier)
    return Case(problem, ranking, weighed, adequacy.share_of_the_gap, grid_line(advice, adequacy),
                found.polarity, where, adequacy=adequacy, advice=advice, locs=locs)


def _weighed(problem: GapProblem, ranking: Ranking, band_hz: float, say: Callable[[str], None],
             earlier: Mapping[str, float] | None) -> Weighed:
    """The evidence on ``ranking`` (:func:`~diagnosis.judgement.weigh.weigh`, from an ``earlier`` diagnosis'
    posteriors when given), what is implausible said."""
    weighed = weigh(problem, ranking, band_hz, earlier)
    for lab, lines in weighed.implausible.items():
        say(f"{lab} needs implausible values: " + "; ".join(lines))
    return weighed


Reading = tuple[str, GapProblem, Ranking, dict[str, list[str]]]


def _apart(case: Case, judgement: Judgement, found: _Found, setups: Setups | None, executor: Any,
           clock: StageClock, say: Callable[[str], None], memo: RefitMemo, earlier: Mapping[str, float] | None
           ) -> tuple[Case, Setups | None, list[Reading]]:
    """When the records and the measured modes disagree more than one structure explains (and no set-ups were
    declared): ranked again with the measured modes taken without the rig parts; the two-set-up case is the one
    judged when it names an effect (adopted), else the one-set-up case, either way with what was tried
    (:class:`~diagnosis.judgement.apart.SetupsApart`, said by the rules).  Also every reading tried, for
    :func:`_readings`."""
    problem, ranking = case.problem, case.ranking
    readings: list[Reading] = [("one set-up", problem, ranking, judgement.weighed.implausible)]
    parts = apart_parts(found.catalogue)
    why = disagreement(problem, ranking, judgement.weighed) if setups is None and parts else None
    if why is None:
        return case, setups, readings
    say(why + f"; ranking again with the measured modes taken without the {', '.join(sorted(parts))}")
    with clock.stage("set-ups apart"):
        two = replace(problem, modes_lack=parts)
        ranking_two = against_the_best_baseline(two, _rank(two, found.baseline, found.catalogue, found.modes, executor,
                                                           clock, say, memo), say)
        case_two = replace(case, problem=two, ranking=ranking_two,
                           weighed=_weighed(two, ranking_two, found.modes.band[1], say, earlier), _chain={})
        verdict_two = judge(case_two).verdict
    adopted = verdict_two.kind is Kind.EFFECT
    apart = SetupsApart(why, parts, verdict_two.name, adopted, verdict_two.text())
    say(f"set-ups apart: {apart.verdict}{' (adopted)' if adopted else ' (one set-up kept)'}")
    readings.append((f"set-ups apart: the measured modes without the {', '.join(sorted(parts))}", two,
                     ranking_two, case_two.weighed.implausible))
    if adopted:
        return replace(case_two, apart=apart), Setups.apart(parts), readings
    return replace(case, apart=apart), setups, readings


def _readings(case: Case, tried: list[Reading], found: _Found, executor: Any, clock: StageClock,
              say: Callable[[str], None]) -> Case:
    """When no effect is named and the closing refits are implausible: each refitted inside the plausibility limits
    for every reading ``tried`` (:func:`~diagnosis.search.plausible.plausible_readings`); the case with them (said
    by the rules)."""
    if judge(case).verdict.kind is Kind.EFFECT:
        return case
    with clock.stage("plausible readings"):
        allowed = plausible_readings(tried, found.catalogue, executor=executor)
    for reading in allowed:
        say("held within plausibility: " + reading.line())
    return replace(case, readings=tuple(allowed))


def _report(case: Case, judgement: Judgement, found: _Found, ran_with: DiagnosisSettings, clock: StageClock,
            executor: Any) -> GapReport:
    """The report (:func:`~diagnosis.report.assemble.gap_report`): the held-out closure per band between the
    modes, the stages' times and what was tried."""
    problem, ranking = case.problem, case.ranking
    modes = found.modes
    mf, f_top, dt = modes.freqs[modes.in_band], modes.f_top, problem.config.time.dt
    edges = np.concatenate([[0.0], 0.5 * (mf[1:] + mf[:-1]), [f_top], [0.5 / dt]])
    with clock.stage("held-out closure per band"):
        rows = effect_rows(problem, ranking, edges, len(mf) + 1)
    assert case.adequacy is not None and case.advice is not None
    report = gap_report(problem, ranking, judgement, modes.band, mf, case.adequacy, case.advice, case.locs, rows,
                        ran_with, found.polarity)
    return replace(report, stage_seconds=dict(clock.seconds), setups_apart=case.apart,
                   plausible_readings=case.readings,
                   events=executor.events() if isinstance(executor, DaskExecutor) else ())


@dataclass(frozen=True, eq=False)
class _Modes:
    """The baseline's band and modes the search works with: the excited band, every mode, which lie in (or a fifth
    above) the band, its top, and how many refits run side by side."""

    band: tuple[float, float]
    freqs: np.ndarray
    zetas: np.ndarray
    in_band: np.ndarray
    f_top: float
    parallel: int
    #: where the measured modes' scan starts (:func:`_scan_start`): frequencies and damping ratios up to ``f_top``,
    #: and the first mode above
    scan: tuple[np.ndarray, np.ndarray, np.ndarray]


def _scan_start(problem: GapProblem, freqs: np.ndarray, zetas: np.ndarray, f_top: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The modes the measured modes' scan starts from (:func:`diagnosis.search.modal_source.modal_source`): the
    baseline's ``freqs`` and ``zetas``, or those of the fit from the records' own start when that fits better or
    places the records' own modes better (:attr:`GapProblem.rival`; measured: a compensating baseline on a
    broadband record put eight modes where the records have six, and the scan around them found two that are not
    there)."""
    if problem.rival is not None:
        freqs, zetas = discrete_frequencies(*problem.space.apply(problem.config, problem.rival.beta))
    inside = freqs <= f_top
    inside[0] = True
    return freqs[inside], zetas[inside], freqs[~inside][:1]


@dataclass(frozen=True, eq=False)
class _Found:
    """What the search found with one sign of the force: the problem (records with that sign, the noise model),
    the baseline its ranking ended from, the check of the sign, the candidates, the modes and the ranking (weighed
    against the best fit without an effect: :func:`~diagnosis.search.rebase.against_the_best_baseline`)."""

    problem: GapProblem
    baseline: Fit
    polarity: PolarityCheck
    catalogue: Catalogue
    modes: _Modes
    ranking: Ranking


def _search(problem: GapProblem, *, beta0: np.ndarray, fit_noise: bool, setups: Setups | None,
            executor: Any, parallel: int, clock: StageClock, say: Callable[[str], None], memo: RefitMemo,
            take: bool | None = None) -> _Found:
    """Stages 1 to 3: the baseline with the force's sign weighed (``take``: that sign, as the refits decided),
    the noise model, the candidates and the search."""
    say("baseline fit, with the force as read and reversed (its sign as evidence)")

    def under_noise(p: GapProblem, fit: Fit) -> GapProblem:
        return noise_of(p, p.simulate(fit.beta, until="all"), clock, say)

    with clock.stage("baseline and the force's sign"):
        problem, baseline, polarity = check_polarity(problem, partial(baseline_fit, beta0=beta0), executor,
                                                     take=take, noise=under_noise if fit_noise else None)
    records, dt = problem.records, problem.config.time.dt
    say(polarity.line())
    band = excited_band([r.inputs for r in records], dt)
    with clock.stage("baseline from the records' start, on the numerics they ask for"):
        problem, found = floor_from_the_records(problem, baseline, band[1], say)
    if fit_noise and found is not baseline:
        # the noise model again, from the residual of the baseline taken (the first one's held its misfit)
        problem, found = under_the_noise(problem, found, clock, say)
    baseline = found
    # stages 2 and 3, the candidates and the search
    if setups is not None:
        say("set-ups: " + setups.describe())
    # the numerics judged again at the leading refit, after each round of the ranking (diagnosis.search.lead)
    numerics = LeadNumerics(problem, band[1], clock, say)
    catalogue, modes, ranking = _ranked(problem, baseline, band, setups, executor, parallel, clock, say, memo,
                                        stop=numerics)
    refined, first = numerics.refined(ranking), lead(ranking)
    if refined is not None and first is not None:
        problem, refit = refined
        if fit_noise:
            # the noise model again, from the residual of the best model there is (the baseline's held the
            # effect's misfit: the strip's 30 g tip mass then left 0.11 of that "noise")
            problem = noise_of(problem, problem.simulate(refit.beta, ranking.effects[first], refit.s, until="all"),
                               clock, say)
        baseline = problem.fit_along_the_level(baseline.beta)
        catalogue, modes, ranking = _ranked(problem, baseline, band, setups, executor, parallel, clock, say, memo,
                                            seeds={first: (ranking.effects[first], refit)}, earlier=ranking)
    return _Found(problem, ranking.baseline, polarity, catalogue, modes,
                  against_the_best_baseline(problem, ranking, say))


def _ranked(problem: GapProblem, baseline: Fit, band: tuple[float, float], setups: Setups | None, executor: Any,
            parallel: int, clock: StageClock, say: Callable[[str], None], memo: RefitMemo,
            seeds: dict[str, tuple[Effect, Fit]] | None = None,
            earlier: Ranking | None = None,
            stop: Callable[[Ranking], bool] | None = None) -> tuple[Catalogue, _Modes, Ranking]:
    """The candidates sized from ``baseline`` and the search among them (the refits of ``seeds`` started from
    them, the modal matches of the ranking on other numerics, ``earlier``, polished; its rounds ended also when
    ``stop`` says so): the catalogue, the baseline's modes and the ranking."""
    dt = problem.config.time.dt
    base_cfg, base_params = problem.space.apply(problem.config, baseline.beta)
    freqs, zetas = discrete_frequencies(base_cfg, base_params)
    f_top = modes_top(band[1], dt)
    in_band = freqs <= f_top
    in_band[0] = True
    catalogue = catalogue_of(problem, base_cfg, base_params, freqs[in_band], band[1], absent=frozenset(
        p for p in RIG_PARTS if setups is not None and not setups.records_have(p)))
    modes = _Modes(band, freqs, zetas, in_band, f_top, parallel, _scan_start(problem, freqs, zetas, f_top))
    with clock.stage("ranking (the rest)"):
        ranking = _rank(problem, baseline, catalogue, modes, executor, clock, say, memo, seeds, None
                        if earlier is None else carried(earlier.patterns, earlier.effects, catalogue), stop)
    return catalogue, modes, ranking


def _rank(problem: GapProblem, baseline: Fit, catalogue: Catalogue, modes: _Modes, executor: Any,
          clock: StageClock, say: Callable[[str], None], memo: RefitMemo,
          seeds: dict[str, tuple[Effect, Fit]] | None = None,
          matches: dict[str, PatternFit] | None = None,
          stop: Callable[[Ranking], bool] | None = None) -> Ranking:
    """The search (:func:`diagnosis.search.rank.rank_effects`) on ``problem`` from ``baseline``, with the
    baseline's ``modes``, the diagnosis' local refits so far (``memo``) and the refits and modal matches to start
    from (``seeds``, ``matches``); its rounds end when a ranking is settled or ``stop`` says so."""
    def done(ranking: Ranking) -> bool:
        return settled(ranking, settings=problem.settings) or (stop is not None and stop(ranking))

    return rank_effects(problem, baseline, catalogue=catalogue, shortlist=problem.settings.shortlist,
                        progress=say, executor=executor, parallel=modes.parallel, rounds=2, clock=clock, memo=memo,
                        modal=modal_source(problem, *modes.scan, modes.band[1]), settled=done, seeds=seeds,
                        matches=matches)


def _write(out: Path, problem: GapProblem, ranking: Ranking, report: GapReport, locs: Sequence[Localisation], *,
           plots: bool, export: bool, targets: Sequence[str], clock: StageClock) -> GapReport:
    """Write ``gap.json``, the plots and the corrected model into ``out`` at once (a temporary directory renamed
    at the end: nothing partial is left on error or interrupt); returns the report with the files it wrote.  The
    export and the figures are stages of their own (``stage_seconds``, written last)."""
    named = report.judged.label
    with staged_dir(out) as tmp:
        rf = ranking.refits.get(named) if named is not None else None
        if export and named is not None and rf is not None:
            from .corrected.export import export_corrected
            from .corrected.summary import corrected_summary

            with clock.stage("corrected model export"):
                effect = ranking.effects[named]
                model = problem.model(rf.fit.beta, effect, rf.fit.s)
                summary = corrected_summary(problem.config, problem.space.to_dict(ranking.baseline.beta),
                                            report.row(named), effect)
                files = export_corrected(model, tmp / "corrected", summary, targets=targets)
            report = replace(report, corrected_files=tuple(f.name for f in files))
        if plots:
            from .report.figures import plot_diagnosis

            with clock.stage("report figures"):
                plot_diagnosis(report, problem, ranking, locs, tmp)
        report = replace(report, stage_seconds=dict(clock.seconds))
        write_json(tmp / GAP_FILE, report.to_dict())
        write_page(tmp / PAGE, "ebb diagnose: where the model and the records disagree, and why",
                   html_sections(report, tmp), subtitle="records: " + ", ".join(r.name for r in problem.records))
    return report
