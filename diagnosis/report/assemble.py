"""The typed result of a diagnosis (:class:`~diagnosis.report.result.GapReport`, what ``gap.json`` holds) assembled
from the stages' values: the search's ranking, the judgement, the localisation, the grid's adequacy."""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ebb_model.modal.modal import discrete_frequencies

from ..baseline.polarity import PolarityCheck
from ..judgement.rules import Judgement
from ..localise import Localisation
from ..problem.fitting import GapProblem
from ..search.rank import Ranking
from .result import BandClosure, BaselineSummary, DiagnosisSettings, EffectRow, GapReport, PatternMatch, RefitSummary

__all__ = ["band_closure", "effect_rows", "gap_report", "modes_hz"]


def band_closure(before: Sequence[np.ndarray], after: Sequence[np.ndarray], dt: float,
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


def modes_hz(model: Any, k: int) -> list[float]:
    """The first ``k`` modal frequencies [Hz] of an augmented model (its beam; lags and drift do not move them)."""
    freqs, _ = discrete_frequencies(model.config, model.params)
    return [float(v) for v in freqs[:k]]


def effect_rows(problem: GapProblem, ranking: Ranking, edges: np.ndarray, n_modes: int) -> tuple[EffectRow, ...]:
    """The report's row of every effect in ranking order: score, and for refitted ones what the refit closes
    (per sensor and per band between ``edges``) and its first ``n_modes`` modal frequencies."""
    names, dt, space = problem.config.output_names, problem.config.time.dt, problem.space
    _, res_before = problem.heldout(ranking.baseline.beta)
    rows = []
    for rank_i, lab in enumerate(ranking.order, start=1):
        e, sc = ranking.effects[lab], ranking.scores.get(lab)   # a pair has no score of its own
        rf = ranking.refits.get(lab)
        refit = None
        if rf is not None:
            _, res_after = problem.heldout(rf.fit.beta, e, rf.fit.s)
            refit = RefitSummary(
                rf.physical, space.to_dict(rf.fit.beta), rf.delta_bic, rf.delta_aic,
                dict(zip(names, map(float, ranking.heldout_before))), dict(zip(names, map(float, rf.heldout_after))),
                rf.closed, {n: (None if not np.isfinite(v) else float(v)) for n, v in zip(names, rf.closed_per_sensor)},
                band_closure(res_before, res_after, dt, edges), rf.fit.n_evaluations,
                tuple(modes_hz(problem.model(rf.fit.beta, e, rf.fit.s), n_modes)))
        pf = ranking.patterns.get(lab)
        match = None if pf is None else PatternMatch(pf.chi2, tuple(map(float, pf.freq_hz)),
                                                     tuple(map(float, pf.damping)))
        rows.append(EffectRow(rank_i, lab, e.name, e.target, e.description, None if sc is None else sc.lm,
                              None if sc is None else sc.p_value, lab in ranking.refits, refit, match,
                              ranking.not_refitted.get(lab)))
    return tuple(rows)


def gap_report(problem: GapProblem, ranking: Ranking, judgement: Judgement, band: tuple[float, float],
               mf: np.ndarray, adequacy: Any, advice: Any, locs: Sequence[Localisation],
               effect_rows: Sequence[EffectRow], settings: DiagnosisSettings, polarity: PolarityCheck) -> GapReport:
    """The typed result of a diagnosis (what ``gap.json`` holds) from its parts."""
    names, space, baseline = problem.config.output_names, problem.space, ranking.baseline
    weighed = judgement.weighed
    return GapReport(
        judgement.verdict, dict(zip(names, map(float, problem.noise_std))), band,
        BaselineSummary(space.to_dict(baseline.beta), float(baseline.rss / baseline.n),
                        dict(zip(names, map(float, ranking.heldout_before))), baseline.bic(space.dim),
                        baseline.n_evaluations, tuple(map(float, mf)), adequacy, advice),
        None if ranking.modal is None else ranking.modal.measured,
        ranking.patterns["baseline"].chi2 if ranking.patterns else None,
        {r.name: loc for r, loc in zip(problem.records, locs)}, tuple(s for loc in locs for s in loc.summary),
        tuple(effect_rows), settings, implausible={k: tuple(v) for k, v in weighed.implausible.items()},
        priors=tuple(weighed.priors), evidence=weighed.evidence, log_posterior=weighed.log_posterior,
        confounded=judgement.confounded,
        modal_data=weighed.modal_data, polarity=polarity)
