"""The gap diagnosis as one API call (what ``ebb diagnose`` runs).

config + data (+ held-out records or a held-out tail of each record) →
baseline fit on the fit windows (started from an identification result or the
nominal values) → noise level → localisation of the residual (where) → score
tests of every candidate effect, refit of the shortlist, ranking by held-out
error and BIC (which) → held-out gap before/after per sensor and per band
(how far) → ``gap.json`` and report plots.

Bad input is detected before anything is written, and the output directory
appears only when complete (built under a temporary name, then renamed).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from concurrent.futures import Executor
from functools import partial
from typing import Any, Callable, Mapping, Sequence, cast

import numpy as np

from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError
from ebb_model.adequacy import excited_band, numerical_adequacy
from ebb_model.htmlio import PAGE, write_page
from ebb_model.grid_advice import grid_advice
from ebb_model.jsonio import write_json
from ebb_model.output import check_new_output_dir, staged_dir
from ebb_model.modal import discrete_frequencies
from ebb_model.threads import one_blas_thread

from identification.data import Experiment
from identification.export_targets import DEFAULT_TARGETS, check_targets
from identification.noise import given_noise_std, records_noise_std
from identification.noise_model import estimate_noise_model
from identification.parameters import parameter_space
from identification.modal_data import modal_data
from identification.cluster import parse_local_address
from identification.prior import Prior
from identification.result import IdentificationResult
from identification.run import load_identification_config, read_data

from .effects import Catalogue, Effect
from .problem.fitting import Fit, GapProblem
from .localise import Localisation, localise
from .search.modal_estimate import MeasuredModes, estimate_modes
from .search.modal_pattern import ModalEvidence, modal_evidence
from .judgement.plausibility import plausible_verdict, prior_checks
from .baseline.polarity import PolarityCheck, check_polarity
from .judgement.weigh import Weighed, weigh
from .search.rank import Ranking, rank_effects
from .stages import StageClock
from .judgement.verdict import UNEXPLAINED
from .settings import Thresholds, thresholds_from_config
from .report.html import html_sections
from .baseline.fit import baseline_fit, floor_from_the_records, start_from_result
from .candidates.catalogue import catalogue_of
from .problem.records import split_records
from .report.result import (BandClosure, BaselineSummary, DiagnosisSettings, EffectRow, GapReport, PatternMatch,
                     RefitSummary)
from .search.workers import DaskExecutor, refit_pool

__all__ = ["Diagnosis", "diagnose", "excited_band", "GAP_FILE", "GRID_VERDICT"]

GAP_FILE = "gap.json"
#: The verdict when the gap is the model's own discretisation error.
GRID_VERDICT = "grid"


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """Outcome of :func:`diagnose`: the ranking, what was found (:class:`~diagnosis.report.result.GapReport`) and where
    it was written."""

    ranking: Ranking
    report: GapReport
    out_dir: Path | None

    @property
    def verdict(self) -> str:
        """Label of the effect that explains the gap, ``"none"``, ``"unexplained"`` (a gap no effect of the
        catalogue explains) or ``"grid"`` (the model's own discretisation error)."""
        return self.report.verdict

    @property
    def document(self) -> dict[str, Any]:
        """The ``gap.json`` document (:meth:`GapReport.to_dict`)."""
        return self.report.to_dict()


def _ordered(config: BeamConfig, e: Experiment) -> tuple[str, np.ndarray, np.ndarray]:
    idx = [e.output_names.index(s.name) for s in config.sensors]
    return e.name, np.asarray(e.inputs, dtype=float), np.asarray(e.outputs, dtype=float)[:, idx]


def _band_closure(before: Sequence[np.ndarray], after: Sequence[np.ndarray], dt: float,
                  edges: np.ndarray) -> tuple[BandClosure, ...]:
    """Held-out gap ratio per frequency band before/after, and the fraction of the band's gap closed.

    For noise-normalised residuals, white unit-variance noise has an expected
    periodogram ``|R_k|²/n = 1`` in every bin, so a band's gap ratio is the
    mean of ``|R_k|²/n`` over its bins (and sensors).
    """
    nb = len(edges) - 1
    eb, ea, cnt = np.zeros(nb), np.zeros(nb), np.zeros(nb)
    for rb, ra in zip(before, after):
        n = rb.shape[0]
        f = np.fft.rfftfreq(n, dt)
        Pb = np.sum(np.abs(np.fft.rfft(rb, axis=0)) ** 2, axis=1) / n
        Pa = np.sum(np.abs(np.fft.rfft(ra, axis=0)) ** 2, axis=1) / n
        band = np.searchsorted(edges, f, side="right") - 1
        for i in range(nb):
            m = band == i
            eb[i] += Pb[m].sum()
            ea[i] += Pa[m].sum()
            cnt[i] += m.sum() * rb.shape[1]
    rows = []
    for i in range(nb):
        b = eb[i] / cnt[i] if cnt[i] else float("nan")
        a = ea[i] / cnt[i] if cnt[i] else float("nan")
        rows.append(BandClosure((float(edges[i]), float(edges[i + 1])), float(b), float(a),
                                float((b - a) / (b - 1.0)) if b > 1.05 else None))
    return tuple(rows)


def _numerical_verdict(ranking: Ranking, share: float, advice: str, settings: Thresholds) -> Ranking:
    """The ranking with its verdict replaced by :data:`GRID_VERDICT` when the grid's share of the gap is above
    ``settings.numerical_share_limit``, or its reason qualified when the share is above a tenth.

    A held-out gap within ``settings.gap_threshold`` of the noise floor is no gap: the verdict
    stays ``none`` whatever share of that remainder the grid makes (a share of almost nothing).
    """
    if float(np.mean(ranking.heldout_before)) - 1.0 < settings.gap_threshold:
        return ranking
    if share > settings.numerical_share_limit:
        instead = f" (the best-ranked effect, {ranking.verdict}, is not blamed)" if ranking.verdict != "none" else ""
        return replace(ranking, verdict=GRID_VERDICT, reason=(
            f"the model's grid: refining it changes the model by {100 * share:.0f} % of the baseline gap, so the "
            f"gap is largely the model's own discretisation error{instead}; {advice}"))
    if share > 0.1 and ranking.verdict != "none":
        return replace(ranking, reason=f"{ranking.reason} (caution: {100 * share:.0f} % of the baseline gap is the "
                                       f"model's grid; {advice})")
    return ranking


def corrected_summary(config: BeamConfig, baseline: Mapping[str, float], row: EffectRow | None, effect: Effect
                      ) -> dict[str, Any]:
    """What ``corrected.json`` says: the effect and its parameters with units (the effect's own,
    :attr:`Effect.units`), the refitted baseline, and the held-out gap before/after.

    Raises
    ------
    ValueError
        ``row`` has no refit (only a refitted effect is exported).
    """
    from ebb_model.beam import PARAMETER_UNITS

    rf = None if row is None else row.refit
    if row is None or rf is None:
        raise ValueError(f"{effect.label}: only a refitted effect is exported")
    units = effect.units

    def unit(k: str) -> str:
        return PARAMETER_UNITS.get(k, "m" if k.startswith("x_") else "")

    return {"effect": row.label, "description": row.description,
            "effect_parameters": {k: {"value": v, "unit": units.get(k, "")} for k, v in rf.effect_parameters.items()},
            "parameters": {k: {"value": v, "unit": unit(k)} for k, v in rf.baseline_parameters.items()},
            "baseline_without_effect": {k: {"value": v, "unit": unit(k)} for k, v in baseline.items()},
            "heldout_gap_ratio_before": dict(rf.heldout_gap_ratio_before),
            "heldout_gap_ratio_after": dict(rf.heldout_gap_ratio_after), "closed": rf.closed,
            "sensors": {s.name: s.unit for s in config.sensors}}


def _modal_source(problem: GapProblem, freq_hz: np.ndarray, damping: np.ndarray, above_hz: np.ndarray,
                  band_hz: float) -> Callable[[np.ndarray], ModalEvidence]:
    """The measured modes' evidence at baseline unknowns ``beta`` (:mod:`diagnosis.search.modal_pattern`); the modes
    are estimated from the fit windows once, when first asked for, starting from the baseline's ``freq_hz``.

    Only the modes the baseline puts inside the excited band (up to ``band_hz``) and estimated inside it (the
    first always) are evidence: a mode above it is seen only through the band's edge, and its oscillator takes up
    what the others leave — its frequency, with a standard error that knows nothing of that, can be far from any
    mode (measured: a cantilever's fourth mode at 60.8 Hz, the top of a 60 Hz multisine, estimated at 74.9 Hz 73
    standard errors away, which then dominated every modal match) or land on the edge inside the band (a
    compressed beam's fifth mode, 118.6 Hz, above a 2–100 Hz sweep, estimated at 99.0 Hz in one run).  It still
    takes part in the modal fit as a regressor."""
    measured: list[MeasuredModes] = []

    def evidence(beta: np.ndarray) -> ModalEvidence:
        if not measured:
            fit = [r for r in problem.records if r.has_fit]
            modes = estimate_modes([r.inputs[:r.fit_end] for r in fit], [r.outputs[:r.fit_end] for r in fit],
                                   problem.noise_std, problem.config.time.dt, freq_hz, damping, above_hz=above_hz)
            keep = (modes.freq_hz <= band_hz) & (freq_hz <= band_hz)
            keep[0] = True
            measured.append(modes.select(keep))
        return modal_evidence(problem, beta, measured[0])

    return evidence


def _modes_hz(model: Any, k: int) -> list[float]:
    """The first ``k`` modal frequencies [Hz] of an augmented model (its beam; lags and drift do not move them)."""
    freqs, _ = discrete_frequencies(model.config, model.params)
    return [float(v) for v in freqs[:k]]


@one_blas_thread
def diagnose(config: BeamConfig | str | Path, data: Sequence[str | Path], out_dir: str | Path | None, *,
             holdout: Sequence[str | Path] = (), result: IdentificationResult | str | Path | None = None,
             holdout_fraction: float = 0.3, shortlist: int | None = None, noise_std: Sequence[float] | None = None,
             plots: bool = True, export: bool = True, targets: Sequence[str] = DEFAULT_TARGETS, workers: int = 2,
             dask: Any = None, progress: Callable[[str], None] | None = None) -> Diagnosis:
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
    targets = check_targets(targets)
    out = Path(out_dir) if out_dir is not None else None
    if out is not None:
        check_new_output_dir(out)
    exps = read_data(cfg, data)
    held = read_data(cfg, holdout) if holdout else ()
    records = split_records([_ordered(cfg, e) for e in exps], [_ordered(cfg, e) for e in held],
                            holdout_fraction=holdout_fraction)
    space = parameter_space(cfg)
    beta0 = start_from_result(result, space.names) if result is not None else np.asarray(space.nominal)
    dt = cfg.time.dt
    given = given_noise_std(cfg, noise_std)
    sigma = given if given is not None else records_noise_std([r.inputs for r in records],
                                                              [r.outputs for r in records], dt)
    problem = GapProblem(cfg, space, records, sigma, prior=Prior.of(cfg, space.names), modes=modal_data(cfg),
                         settings=settings)
    clock = StageClock()
    executor = refit_pool(workers, dask)
    try:
        # the measured force's sign is evidence too: the baseline fitted with the force as read and reversed (side
        # by side when there are workers)
        say("baseline fit, with the force as read and reversed (its sign as evidence)")
        with clock.stage("baseline and the force's sign"):
            problem, baseline, polarity = check_polarity(problem, partial(baseline_fit, beta0=beta0), executor)
        records = problem.records
        say(polarity.line())
        if given is None:
            # the noise as it is in each record (level and colour), from the baseline's residual, and the
            # baseline fitted again under it
            with clock.stage("noise model"):
                problem = problem.with_noise(estimate_noise_model([r.inputs for r in records], [
                    r.outputs - y for r, y in zip(records, problem.simulate(baseline.beta, until="all"))], dt))
                baseline = problem.fit(baseline.beta)
            say("noise model: " + "; ".join(problem.noise_model.describe(cfg.output_names, [r.name for r in records])))
        with clock.stage("baseline from the records' start"):
            baseline = floor_from_the_records(problem, baseline, say)
        sigma = problem.noise_std
        base_cfg, base_params = space.apply(cfg, baseline.beta)
        f_lo, f_hi = excited_band([r.inputs for r in records], dt)
        freqs, zetas = discrete_frequencies(base_cfg, base_params)
        # the modes up to a fifth above the excited band, below Nyquist (an impact excites up to it)
        f_top = min(1.2 * f_hi, 0.98 * 0.5 / dt)
        in_band = freqs <= f_top
        in_band[0] = True
        mf, mz = freqs[in_band], zetas[in_band]
        fit_records = [r for r in records if r.has_fit]
        catalogue = catalogue_of(problem, base_cfg, base_params, mf, f_hi)
        with clock.stage("ranking (the rest)"):
            ranking = _ranking(problem, baseline, catalogue, settings.shortlist, executor, workers,
                               _modal_source(problem, mf, mz, freqs[~in_band][:1], f_hi), say, clock)
        baseline = ranking.baseline
        # the model's own discretisation error: a gap that refining the grid changes is not blamed on physics
        say("numerical adequacy of the model's grid")
        with clock.stage("numerical adequacy"):
            adequacy = numerical_adequacy(
                base_cfg, base_params, [(r.inputs[:r.fit_end], r.outputs[:r.fit_end]) for r in fit_records], sigma,
                band_hz=f_hi)
            advice = grid_advice(base_cfg, base_params, band_hz=f_hi)
        ranking = _numerical_verdict(ranking, float(np.max(adequacy.numerical_share)), advice.summary(), settings)
        by_label = {e.label: e for e in catalogue.effects()} | {lab: catalogue.effect(lab) for lab in ranking.refits}
        # a refit that explains the data with values no rig has is not the cause (diagnosis.judgement.plausibility)
        with clock.stage("plausibility and evidence"):
            ranking = plausible_verdict(ranking, problem, by_label)
            for lab, lines in ranking.implausible.items():
                say(f"{lab} needs implausible values: " + "; ".join(lines))
            ranking, weighed = weigh(problem, ranking, by_label)
        if polarity.reversed or not polarity.decided:
            ranking = replace(ranking, reason=f"{ranking.reason}; {polarity.line()}")
        say(f"verdict: {ranking.verdict}")

        # where: localisation of the baseline residual per record
        with clock.stage("localisation"):
            base_all = cast(list[np.ndarray], problem.simulate(baseline.beta, until="all"))   # every record
            locs = [localise(dt, r.inputs, r.outputs, y, cfg.output_names, mf, mz, noise_std=sigma,
                             input_names=cfg.input_names)
                    for r, y in zip(records, base_all)]
        if ranking.verdict == UNEXPLAINED:
            # what the localisation found is the user's lead, not the least-bad name
            found = [f"{r.name}: {s}" for r, loc in zip(records, locs) for s in loc.summary[:2]]
            if found:
                ranking = replace(ranking, reason=f"{ranking.reason}; where the gap is: " + "; ".join(found))
        edges = np.concatenate([[0.0], 0.5 * (mf[1:] + mf[:-1]), [f_top], [0.5 / dt]])
        with clock.stage("held-out closure per band"):
            effect_rows = _effect_rows(problem, ranking, by_label, edges, len(mf) + 1)
        ran_with = DiagnosisSettings(tuple(str(h) for h in holdout), None if holdout else holdout_fraction, settings)
        report = replace(_report(problem, ranking, (f_lo, f_hi), mf, adequacy, advice, locs, effect_rows, ran_with,
                                 weighed, polarity), stage_seconds=dict(clock.seconds))
        if out is None:
            return Diagnosis(ranking, report, None)
        report = _write(out, problem, ranking, report, by_label, locs, plots=plots, export=export,
                        targets=targets)
        return Diagnosis(ranking, report, out)
    finally:
        if executor is not None:
            executor.shutdown(cancel_futures=True)


def _report(problem: GapProblem, ranking: Ranking, band: tuple[float, float], mf: np.ndarray, adequacy: Any,
            advice: Any, locs: Sequence[Localisation], effect_rows: Sequence[EffectRow],
            settings: DiagnosisSettings, weighed: Weighed, polarity: PolarityCheck) -> GapReport:
    """The typed result of a diagnosis (what ``gap.json`` holds) from its parts."""
    names, space, baseline = problem.config.output_names, problem.space, ranking.baseline
    return GapReport(
        ranking.verdict, ranking.reason, tuple(ranking.indistinguishable),
        dict(zip(names, map(float, problem.noise_std))), band,
        BaselineSummary(space.to_dict(baseline.beta), float(baseline.rss / baseline.n),
                        dict(zip(names, map(float, ranking.heldout_before))), baseline.bic(space.dim),
                        baseline.n_evaluations, tuple(map(float, mf)), adequacy, advice),
        None if ranking.modal is None else ranking.modal.measured,
        ranking.patterns["baseline"].chi2 if ranking.patterns else None,
        {r.name: loc for r, loc in zip(problem.records, locs)}, tuple(s for loc in locs for s in loc.summary),
        tuple(effect_rows), settings, implausible={k: tuple(v) for k, v in ranking.implausible.items()},
        priors=tuple(prior_checks(problem, baseline)), evidence=weighed.evidence, confounded=weighed.confounded,
        modal_data=weighed.modal_data, polarity=polarity)


def _ranking(problem: GapProblem, baseline: Fit, catalogue: Catalogue, shortlist: int, executor: Executor | None,
             workers: int, modal: Callable[[np.ndarray], ModalEvidence], say: Callable[[str], None],
             clock: StageClock) -> Ranking:
    """:func:`diagnosis.search.rank.rank_effects` on the executor's processes or Dask workers (ranked again, up to
    twice, from a better baseline basin that an effect's refit revealed)."""
    parallel = executor.workers if isinstance(executor, DaskExecutor) else workers
    return rank_effects(problem, baseline, catalogue=catalogue, shortlist=shortlist, progress=say,
                        executor=executor, parallel=parallel, rounds=2, modal=modal, clock=clock)


def _effect_rows(problem: GapProblem, ranking: Ranking, by_label: Mapping[str, Effect], edges: np.ndarray,
                 n_modes: int) -> tuple[EffectRow, ...]:
    """The report's row of every effect in ranking order: score, and for refitted ones what the refit closes
    (per sensor and per band between ``edges``) and its first ``n_modes`` modal frequencies."""
    names, dt, space = problem.config.output_names, problem.config.time.dt, problem.space
    _, res_before = problem.heldout(ranking.baseline.beta)
    rows = []
    for rank_i, lab in enumerate(ranking.order, start=1):
        e, sc = by_label[lab], ranking.scores.get(lab)   # a pair has no score of its own
        rf = ranking.refits.get(lab)
        refit = None
        if rf is not None:
            _, res_after = problem.heldout(rf.fit.beta, e, rf.fit.s)
            refit = RefitSummary(
                rf.physical, space.to_dict(rf.fit.beta), rf.delta_bic, rf.delta_aic,
                dict(zip(names, map(float, ranking.heldout_before))), dict(zip(names, map(float, rf.heldout_after))),
                rf.closed, {n: (None if not np.isfinite(v) else float(v)) for n, v in zip(names, rf.closed_per_sensor)},
                _band_closure(res_before, res_after, dt, edges), rf.fit.n_evaluations,
                tuple(_modes_hz(problem.model(rf.fit.beta, e, rf.fit.s), n_modes)))
        pf = ranking.patterns.get(lab)
        match = None if pf is None else PatternMatch(pf.chi2, tuple(map(float, pf.freq_hz)),
                                                     tuple(map(float, pf.damping)))
        rows.append(EffectRow(rank_i, lab, e.name, e.target, e.description, None if sc is None else sc.lm,
                              None if sc is None else sc.p_value, lab in ranking.refits, refit, match))
    return tuple(rows)


def _write(out: Path, problem: GapProblem, ranking: Ranking, report: GapReport, by_label: Mapping[str, Effect],
           locs: Sequence[Localisation], *, plots: bool, export: bool, targets: Sequence[str]) -> GapReport:
    """Write ``gap.json``, the plots and the corrected model into ``out`` at once (a temporary directory renamed
    at the end: nothing partial is left on error or interrupt); returns the report with the files it wrote."""
    with staged_dir(out) as tmp:
        rf = ranking.refits.get(ranking.verdict)
        if export and rf is not None:
            from .corrected.export import export_corrected

            model = problem.model(rf.fit.beta, by_label[ranking.verdict], rf.fit.s)
            summary = corrected_summary(problem.config, problem.space.to_dict(ranking.baseline.beta),
                                        report.row(ranking.verdict), by_label[ranking.verdict])
            files = export_corrected(model, tmp / "corrected", summary, targets=targets)
            report = replace(report, corrected_files=tuple(f.name for f in files))
        write_json(tmp / GAP_FILE, report.to_dict())
        if plots:
            from .report.figures import plot_diagnosis

            plot_diagnosis(report, problem, ranking, by_label, locs, tmp)
        write_page(tmp / PAGE, "ebb diagnose: where the model and the records disagree, and why",
                   html_sections(report, tmp), subtitle="records: " + ", ".join(r.name for r in problem.records))
    return report
