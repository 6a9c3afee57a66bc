"""The ranking's modal-pattern stage (:func:`modal_stage`): the measured modes matched by every structural effect,
the best matches refitted from their match, then a pair and the baseline's other basins while the gap is unexplained.

When no local refit brings the fit windows to the noise floor (one that explains the dominant part only may be
another effect's stand-in: a point mass 0.5 m away from a withheld spring to ground, on accelerometers, left 11
noise variances), the measured modes (:mod:`diagnosis.search.modal_estimate`) are matched by every structural
effect with the baseline unknowns profiled out (:mod:`diagnosis.search.modal_pattern`), and the
``pattern_candidates`` best matches (and a special case at a fixed place, :mod:`diagnosis.search.nested`, beside
them when it matches best) are refitted from their match — in the right basin even when the baseline had
compensated the effect and its one-sided score was 0.  When the baseline itself matches the measured modes within
the BIC margin of χ² no effect can match them better by the margin (a χ² is a sum of squares) and the effects'
pattern fits are not made.  Only then come the other baseline basins (and, in :mod:`diagnosis.search.rank`, the
continuation refits).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..problem.fitting import Fit
from ..settings import Thresholds
from .modal_pattern import PatternFit, pattern_fits
from .mode_match import ModalEvidence
from .pairs import Early, early_pair, pair_explains
from .refits import explains, refit_from_match
from .state import Refits, Search

__all__ = ["linear_records", "modal_stage"]


def linear_records(evidence: ModalEvidence | None, settings: Thresholds, baseline: Fit) -> bool:
    """Whether the measured modes' oscillators reproduce the records as far as the verdict counts a gap explained
    (:func:`~diagnosis.search.refits.explains`: their excess over the noise floor at most ``explained_share`` of
    the ``baseline``'s, or under ``gap_threshold``): if not, no linear time-invariant effect can explain the gap
    (unknown evidence: assume they do).  The floor itself was the gate before: oscillators that left 1.4 noise
    variances of a baseline's 374 (a cantilever with a spring withheld, two sensors) skipped the modal patterns and
    the continuation refits that would have weighed the spring, and the verdict named a pair."""
    if evidence is None:
        return True
    excess = evidence.measured.gap_ratio - 1.0
    return excess <= max(settings.explained_share * (baseline.rss / baseline.n - 1.0), settings.gap_threshold)


def _refit_from_matches(run: Search, patterns: dict[str, PatternFit], labels: list[str], local: Refits) -> Refits:
    """Refit ``labels`` from their modal match, side by side: the refits ``local`` with them added (or the better
    of the two kept)."""
    fits = run.side_by_side(refit_from_match, [(run.problem, run.catalogue, lab, patterns[lab], run.max_evaluations)
                                               for lab in labels])
    local = dict(local)
    for lab, (fit, starts) in zip(labels, fits):
        run.say(f"refit {lab} from its modal match: fit RSS/n {fit.rss / fit.n:.4g} ({fit.n_evaluations} evaluations)")
        if lab in local:
            old, old_starts = local[lab]
            best = fit if fit.rss < old.rss else old
            local[lab] = (replace(best, n_evaluations=old.n_evaluations + fit.n_evaluations), old_starts + starts)
        else:
            local[lab] = (fit, starts)
    return local


def _pattern_stage(run: Search, evidence: ModalEvidence, local: Refits) -> tuple[dict[str, PatternFit], Refits]:
    """Match the measured modes by every structural effect and refit the ``pattern_candidates`` best
    matches from their match (module docstring): the pattern fits, and the refits with theirs."""
    if not linear_records(evidence, run.problem.settings, run.baseline):
        run.say(f"measured modes: their oscillators, scanned from the model's modes, leave "
                f"{evidence.measured.gap_ratio:.3g} noise variances — a mode lies outside the scan, a channel's delay "
                f"or filter is missing from the config, or the records are not those of a linear time-invariant "
                f"system: no modal pattern to compare")
        return {}, local
    with run.clock.stage("modal pattern fits"):
        patterns = pattern_fits(run.problem, evidence, run.baseline.beta, run.catalogue, run.executor,
                                margin=run.problem.settings.bic_margin, previous=run.matches)
    run.matches.update({lab: pf for lab, pf in patterns.items() if lab != "baseline"})
    base = patterns["baseline"].chi2
    if len(patterns) == 1:
        run.say(f"measured modes {np.round(evidence.measured.freq_hz, 3)} Hz: the baseline matches them (modal "
                f"pattern chi2 {base:.4g} for {evidence.n_modes} modes, within the BIC margin "
                f"{run.problem.settings.bic_margin:g}): no "
                f"effect can match them better, no effect's pattern fitted")
        return patterns, local
    run.say(f"measured modes {np.round(evidence.measured.freq_hz, 3)} Hz (their fit leaves "
            f"{evidence.measured.gap_ratio:.3g} noise variances); modal pattern chi2 ({evidence.n_modes} modes; "
            f"baseline {base:.4g}): "
            + ", ".join(f"{lab} {pf.chi2:.4g}" for lab, pf in patterns.items() if lab != "baseline"))
    margin = run.problem.settings.bic_margin
    matching = sorted((lab for lab in patterns if lab != "baseline" and patterns[lab].chi2 < base - margin),
                      key=lambda lab: patterns[lab].chi2)
    # a special case at a fixed place (an armature at the drive point) is refitted beside the general matches
    # when it matches best of all, never in their place: with three modes every two-variable structural effect
    # matches within the errors, and a sprung mass at the drive point stood in for a spring 0.25 m away
    general = [lab for lab in matching if run.effects[lab].nested_in is None]
    special = [lab for lab in matching if run.effects[lab].nested_in is not None][:1]
    ranked = general[:run.problem.settings.pattern_candidates]
    if ranked:   # a match far worse than the best one does not match: 2 per mode is a match within the errors
        limit = run.problem.settings.pattern_rival * max(patterns[ranked[0]].chi2, 2.0 * evidence.n_modes)
        ranked = [lab for lab in ranked if patterns[lab].chi2 <= limit]
        special = [lab for lab in special if patterns[lab].chi2 < patterns[ranked[0]].chi2]
    with run.clock.stage("refits from modal matches"):
        local = _refit_from_matches(run, patterns, ranked + special, local)
    rest = [lab for lab in general if lab not in ranked][:run.problem.settings.pattern_candidates]
    if (rest and not any(explains(local[lab][0], run.baseline, run.problem.settings) for lab in ranked)
            and not run.at_noise_floor({lab: local[lab] for lab in special})):
        # the closest matches do not explain the records: the next ones (a pattern fit can stop short of its
        # optimum, and its match still lies in the right basin for the time-domain refit)
        with run.clock.stage("refits from modal matches"):
            local = _refit_from_matches(run, patterns, rest, local)
    return patterns, local


def modal_stage(run: Search, evidence: ModalEvidence, labels: list[str], local: Refits
                 ) -> tuple[dict[str, PatternFit], list[str], Early, Refits]:
    """The modal pattern, then a pair, then the other baseline basins, each only while the gap is unexplained
    (module docstring).  Returns the pattern fits, the refitted labels (the shortlist and the matches, in
    catalogue order after the shortlist), the early pair and the refits with the stage's."""
    patterns, local = _pattern_stage(run, evidence, local)   # (its parts are timed inside)
    labels = labels + [lab for lab in run.effects if lab in local and lab not in labels]
    early: Early = None
    if not run.explained(local):
        with run.clock.stage("pairs"):
            early, local = early_pair(run, labels, local)
    if not run.explained(local) and not pair_explains(early, run.baseline, run.problem.settings):
        # (a better basin cannot make a linear time-invariant effect explain records no such model can)
        linear = linear_records(evidence, run.problem.settings, run.baseline)
        tried = [lab for lab in labels if linear or not run.time_invariant(lab)]
        with run.clock.stage("other basins"):
            local = local | run.refit(tried, {lab: local[lab] for lab in tried}, stage="basins")
    return patterns, labels, early, local
