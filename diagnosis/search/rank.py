"""Which effect: the score test (:mod:`diagnosis.candidates.score`) shortlists; refits (:mod:`diagnosis.search.refits`),
information criteria and held-out error rank.

Refit and ranking
-----------------
The best-scoring effects are refitted together with the baseline unknowns on
the fit windows (the local refit).  When no local refit leaves at most 10 % of
the fit windows' excess unexplained — and more than the gap threshold
above the noise floor, the level at which the verdict would be ``none`` (an
excess of 0.7 closed to 0.09 is explained: the rest is the noise estimate's
and the model's own few per cent) — the modal pattern is tried (below), then
the refit is repeated from the other basins of the baseline's global search,
and when still no shortlisted effect explains the gap, each is refitted once
more by continuation in the record length (:mod:`diagnosis.search.refits`), the most
promising first, until one explains it.  Effects are ranked by held-out error
among those whose BIC improves by more than the BIC margin (an extra
parameter must pay for itself); the naming rule
(:func:`diagnosis.judgement.verdict.settled`, passed in as ``settled``) tells when a ranking is settled,
and the judgement (:mod:`diagnosis.judgement.rules`) makes the verdict from the
ranking.  Effects
whose held-out improvement is within 5 % of the best and whose held-out error
is not measurably higher (by at most the gap threshold or a quarter of the
best's excess) are reported as indistinguishable from it.

Modal pattern
-------------
When no local refit brings the fit windows to the noise floor, the measured modes are matched by every
structural effect and the best matches refitted from their match (:mod:`diagnosis.search.modal_stage`); only then
come the other baseline basins and the continuation refits.  Once the ranking names an effect whose modal match
leaves its place free, it is refitted also from the place the records choose (:func:`_screened_best`).

Two effects at once
-------------------
When the best single effect leaves a significant remainder, a second one is tried at its refit
(:mod:`diagnosis.search.pairs`).  The stages share one :class:`diagnosis.search.state.Search`.
"""
from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping

import numpy as np

from ..effects import PAIR_SEPARATOR, Catalogue, Effect
from ..problem.fitting import Fit, GapProblem
from .modal_pattern import PatternFit, amplitude_screened, moves_modes
from .modal_stage import linear_records, modal_stage
from .mode_match import ModalEvidence
from .exclusions import not_refitted
from .nested import landing_refits
from .pairs import Early, early_pair, pair_explains, pair_with, same_fit
from .refits import EffectRefit, better_baseline, explains, paying_refits, refit_from_match, seeded
from ..candidates.score import EffectScore, score_effect
from .state import Refits, Search
from .reuse import RefitMemo
from ..stages import StageClock
from ..settings import Thresholds
from ..problem.plausibility import implausibilities
from ..problem.ties import tie_ordered

__all__ = ["Ranking", "Refits", "rank_effects", "report_order"]




@dataclass(frozen=True, eq=False)
class Ranking:
    """What the search found: all scores, the refits, the report order, the refits that pay for themselves (best
    first; a pair that pays, first of all) and the effect behind every label ranked (pairs included).  The verdict
    is the judgement's (:func:`diagnosis.judgement.rules.judge`)."""

    baseline: Fit
    heldout_before: np.ndarray
    scores: dict[str, EffectScore]
    refits: dict[str, EffectRefit]
    order: list[str]
    paying: list[str]
    effects: dict[str, Effect]
    patterns: dict[str, PatternFit] = field(default_factory=dict)   # modal-pattern fits, when they were needed
    modal: ModalEvidence | None = None
    #: the candidates with a significant score and no refit, each with why (:mod:`diagnosis.search.exclusions`)
    not_refitted: dict[str, str] = field(default_factory=dict)


# ---------------------------------------------------------------------------
# stage: continuation in the record length
# ---------------------------------------------------------------------------
def _continuation_stage(run: Search, labels: list[str], local: Refits, early: Early,
                        evidence: ModalEvidence | None, patterns: dict[str, PatternFit], parallel: int) -> Refits:
    """Continuation refits (:mod:`diagnosis.search.refits`), the most promising first, ``parallel`` at a time, until one
    explains the gap; skipped for effects no continuation can help.  Returns the refits with theirs."""
    pending = sorted(labels, key=lambda lab: local[lab][0].rss)
    if pair_explains(early, run.baseline, run.problem.settings) or run.explained(local):
        run.say(f"continuation refits of {', '.join(pending)} skipped: the gap is explained")
        pending = []
    if evidence is not None and not linear_records(evidence, run.problem.settings, run.baseline):
        # no set of linear oscillators reproduces the records: no linear time-invariant effect can (unknown
        # evidence: linear)
        lti = [lab for lab in pending if run.time_invariant(lab)]
        if lti:
            run.say(f"continuation refits of {', '.join(lti)} skipped: the measured modes' own fit leaves "
                    f"{evidence.measured.gap_ratio:.3g} noise variances, more than a linear time-invariant effect "
                    f"near the model's modes would leave (so does a channel's delay or filter missing from the config)")
        pending = [lab for lab in pending if lab not in lti]
    if patterns:
        # a structural effect's basin is where its modal pattern put it (or the pattern showed that no effect
        # matches the modes better than the baseline): continuation cannot add to that
        matched = [lab for lab in pending if moves_modes(run.problem, run.baseline.beta, run.effects[lab])]
        if matched:
            run.say(f"continuation refits of {', '.join(matched)} skipped: their modal pattern was weighed")
        pending = [lab for lab in pending if lab not in matched]
    while pending:
        # ``parallel`` at a time, taken in order up to the first that explains the gap: the refits computed beside
        # it are left out, so that the ranking holds the refits a single process would have made, whatever the
        # worker count (tests/test_worker_counts.py)
        group, pending = pending[:max(1, parallel)], pending[max(1, parallel):]
        with run.clock.stage("continuation refits"):
            made = run.refit(group, {lab: local[lab] for lab in group}, stage="continuation")
        for i, lab in enumerate(group):
            local = local | {lab: made[lab]}
            fit = made[lab][0]
            run.say(f"continuation refit {lab}: fit RSS/n {fit.rss / fit.n:.4g} ({fit.n_evaluations} evaluations)")
            if explains(fit, run.baseline, run.problem.settings):
                pending = group[i + 1:] + pending
                break
        else:
            continue
        if pending:
            run.say(f"continuation refits of {', '.join(pending)} skipped: the gap is explained")
        break
    return local


# ---------------------------------------------------------------------------
# the ranking
# ---------------------------------------------------------------------------
def _screened_best(run: Search, evidence: ModalEvidence, match: PatternFit, refits: dict[str, EffectRefit],
                   paying: list[str], order: list[str], by_score: list[str]
                   ) -> tuple[dict[str, EffectRefit], list[str], list[str]]:
    """The refits, the paying ones and their order (``paying``, ``order`` as they are), with the best paying
    effect refitted also from the place of its grid the records' amplitudes choose when its modal ``match`` leaves
    the place free (:func:`~diagnosis.search.modal_pattern.amplitude_screened`), the better refit kept.

    The named effect only, once the ranking has named it: given to every match before the ranking, that start
    lifted a soft segment beside the clamp above the blind family's compliant clamp.  (Measured: one
    accelerometer on a compressed clamped–pinned beam with a stiff spring withheld, two modes: the spring
    matched 49 mm from its place at χ² 1.6 and refitted there to 1.53 noise variances held out; from the place
    the records choose 0.1 mm off, 0.95.)"""
    label = match.label
    screened = amplitude_screened(run.problem, evidence, run.effects[label], match)
    if screened is match:
        return refits, paying, order
    fit, _ = refit_from_match(run.problem, run.catalogue, label, replace(screened, others=()), run.max_evaluations)
    run.say(f"{label}: its modal match leaves the place free; refitted from the place the records choose: fit "
            f"RSS/n {refits[label].fit.rss / fit.n:.4g} -> {fit.rss / fit.n:.4g}")
    if fit.rss >= refits[label].fit.rss:
        return refits, paying, order
    refits = refits | {label: run.summary(run.effects[label], fit)}
    return refits, *report_order(refits, run.before, by_score, run.problem.settings)


def _decide(run: Search, by_score: list[str], labels: list[str], local: Refits,
            early: Early, patterns: dict[str, PatternFit], evidence: ModalEvidence | None) -> Ranking:
    """Rank the refits, and try a pair when the best leaves a significant remainder."""
    before, baseline, say = run.before, run.baseline, run.say
    labels = labels + [lab for lab in local if lab not in labels]    # (an early pair's effect alone)
    refits = {lab: run.summary(run.effects[lab], local[lab][0]) for lab in labels}
    with run.clock.stage("nested refits"):
        refits, dropped = landing_refits(run, refits)
    for label, rf in refits.items():
        say(f"refit {label}: held-out gap ratio {np.mean(before):.3g} -> {np.mean(rf.heldout_after):.3g}, "
            f"dBIC {rf.delta_bic:.1f}")
    paying, order = report_order(refits, before, by_score, run.problem.settings)
    if paying and evidence is not None and paying[0] in patterns:
        refits, paying, order = _screened_best(run, evidence, patterns[paying[0]], refits, paying, order, by_score)
    excess = float(np.mean(before)) - 1.0
    if excess >= run.problem.settings.gap_threshold and paying:
        best = refits[paying[0]]
        # a remainder beyond pair_remainder asks for a second effect too — when the single is one a rig can have
        remainder = (float(np.mean(best.heldout_after)) - 1.0 > run.problem.settings.pair_remainder
                     and _plausible(run, best.label, best))
        if ((not explains(best.fit, baseline, run.problem.settings) or remainder)
                and best.closed >= run.problem.settings.pair_minimum):
            # one effect leaves a significant remainder: a second one at once, when it pays for itself (tried
            # already before the continuation refits when this single's fit has not changed since)
            if early is not None and same_fit(early[0], best.fit):
                pairs = list(early[1])
            else:
                # the pair's effects alone from its optimum, where they beat their refits, rank as singles
                with run.clock.stage("pairs"):
                    pairs, singles = pair_with(run, best, {lab: rf.fit for lab, rf in refits.items()})
                refits |= singles
                paying, order = report_order(refits, before, by_score, run.problem.settings)
            # the pairs the best single's near-equal rivals make: a pair is weighed against them, or the true
            # partner of a rival is never seen (a foundation closing 52.7 % beside a spring closing 54.7 %)
            for lab in _rivals(refits, paying, best, run.problem.settings):
                if not _plausible(run, lab, refits[lab]):
                    continue      # a rival with values no rig has makes no pair worth weighing
                with run.clock.stage("pairs"):
                    rival_pairs, singles = pair_with(run, refits[lab], {k: rf.fit for k, rf in refits.items()})
                refits |= singles
                same = {frozenset(rf.label.split(PAIR_SEPARATOR)) for rf in pairs}
                pairs += [rf for rf in rival_pairs[:1] if frozenset(rf.label.split(PAIR_SEPARATOR)) not in same]
            if pairs:
                paying, order = report_order(refits, before, by_score, run.problem.settings)
                by_label = {rf.label: rf for rf in pairs}
                pairs = [by_label[lab] for lab in tie_ordered(by_label, lambda lab: float(np.mean(
                    by_label[lab].heldout_after)))]
                refits |= {rf.label: rf for rf in pairs}
                order = [rf.label for rf in pairs] + order
                paying = [rf.label for rf in pairs] + paying
    effects = run.effects | {lab: run.catalogue.effect(lab) for lab in refits if lab not in run.effects}
    unseen = not_refitted(run.effects, run.scores, set(refits), patterns, dropped, run.problem.settings,
                          with_prior=run.problem.has_prior)
    for line in unseen.values():
        say(line)
    return Ranking(baseline, before, run.scores, refits, order, paying, effects, patterns=patterns, modal=evidence,
                   not_refitted=unseen)


def _plausible(run: Search, label: str, refit: EffectRefit) -> bool:
    """Whether a single effect's refit is one a rig can have: nothing implausible about it — its values, the
    priors, the measured modes (:func:`diagnosis.problem.plausibility.implausibilities`)."""
    effect = run.effects.get(label)
    return effect is not None and not implausibilities(run.problem, effect, refit.fit)


def _rivals(refits: dict[str, EffectRefit], paying: list[str], best: EffectRefit, settings: Thresholds
            ) -> list[str]:
    """The single effects that close nearly as much as ``best`` (``pair_rival_share`` of its closure) and pay for
    themselves: each is paired too (at most ``pair_rivals``), the closest first."""
    near = [lab for lab in paying if lab != best.label and PAIR_SEPARATOR not in lab
            and refits[lab].closed >= settings.pair_rival_share * best.closed]
    return near[:settings.pair_rivals]


def report_order(refits: dict[str, EffectRefit], before: np.ndarray, by_score: list[str], settings: Thresholds
                 ) -> tuple[list[str], list[str]]:
    """The refits that pay for themselves (best first), and the report order: those, the other refits by held-out
    error, then the effects not refitted by score."""
    paying = paying_refits(refits, before, settings)
    others = tie_ordered((lab for lab in refits if lab not in paying),
                         lambda lab: float(np.mean(refits[lab].heldout_after)))
    return paying, paying + others + [lab for lab in by_score if lab not in refits]


def rank_effects(problem: GapProblem, baseline: Fit, catalogue: Catalogue, *, shortlist: int = 4,
                 max_evaluations: int = 300, progress: Any = None, executor: Executor | None = None,
                 parallel: int = 1, rebaseline: bool = True, rounds: int = 2,
                 modal: Callable[[np.ndarray], ModalEvidence] | None = None,
                 clock: StageClock | None = None, memo: RefitMemo | None = None,
                 settled: Callable[[Ranking], bool] = lambda ranking: False,
                 seeds: Mapping[str, tuple[Effect, Fit]] | None = None,
                 matches: Mapping[str, PatternFit] | None = None) -> Ranking:
    """Score every effect, refit the ``shortlist`` best, rank and decide — again from a better baseline basin
    when the refits reveal one (the one re-baselining loop).

    Parameters
    ----------
    problem
        Records, baseline unknowns and noise level.
    baseline
        The fitted baseline (:meth:`GapProblem.fit` without effect).
    catalogue
        The candidate effects (:class:`diagnosis.effects.Catalogue`).
    shortlist
        How many of the best-scoring effects are refitted.
    max_evaluations
        Budget of each refit.
    progress
        Optional callable ``progress(message)``.
    executor
        Where the shortlisted effects are refitted side by side (a process pool); ``None``: one after another
        in this process.
    parallel
        How many continuation refits run side by side (the executor's workers).  They run the most promising
        first (lowest local-refit RSS), ``parallel`` at a time, and stop once one explains the gap: an effect
        that brings the fit windows to the noise floor leaves nothing for another to close.
    rebaseline
        When no local refit explains the gap, first try the baseline from the local refits' baseline
        unknowns (:func:`better_baseline`); if that is better, rank again from it before paying for the
        continuation refits — which would otherwise run twice, from the worse baseline and again.
    rounds
        After a complete ranking that is not ``settled``, up to ``rounds`` times: the baseline
        from the effects' optima (:func:`better_baseline`); when it is better, the ranking starts again from it.
    modal
        The measured modes with their uncertainties for baseline unknowns ``beta`` (called only when no local
        refit explains the gap): then the modal-pattern stage runs first (module docstring).
    clock
        Where the stages' wall time is counted (:class:`diagnosis.stages.StageClock`); a new one when omitted.
    memo
        The local refits another ranking of the same diagnosis made (:class:`diagnosis.search.reuse.RefitMemo`),
        taken instead of repeated and added to; a new one when omitted.
    settled
        Whether a ranking is final — the judgement's naming rule names an effect whose refit reaches the floor
        (:func:`diagnosis.judgement.verdict.settled`, which the caller binds to its settings: the search does not
        import the judgement that follows it), or its leading refit asks for other numerics, where the rounds
        are better spent (:class:`diagnosis.search.lead.LeadNumerics`); by default never, every round is taken.
    seeds
        Refits an earlier stage found, by label, each with the effect it was made with (the leading refit on the
        numerics it asked for: :func:`diagnosis.baseline.numerics.numerics_at_the_refit`, in the catalogue of the
        baseline before them): each polished on this problem and kept where it fits better than the ranking's own
        refit — the best point any stage found is not lost.
    matches
        Modal matches of ``catalogue``'s effects made on other numerics (:func:`~diagnosis.search.modal_pattern
        .carried`), polished instead of searched again, as a later ranking polishes an earlier one's.

    Returns
    -------
    Ranking
        Its :attr:`Ranking.baseline` is the baseline the final ranking used.
    """
    say = progress or (lambda _m: None)
    clock = clock if clock is not None else StageClock()
    early_rebaseline, left = rebaseline, rounds
    # the modal matches, polished again by a later ranking, and the local refits, taken instead of repeated
    plan = _Plan(catalogue, shortlist, max_evaluations, say, executor, parallel, modal, clock, dict(matches or {}),
                 memo if memo is not None else RefitMemo(), dict(seeds or {}))
    while True:
        outcome = _rank_once(problem, baseline, plan, early_rebaseline)
        if isinstance(outcome, Fit):
            # a local refit's baseline unknowns lie in a better basin: rank from there, before the costly stages
            say(f"baseline re-fit from a local refit's optimum: RSS {baseline.rss:.4g} -> {outcome.rss:.4g}; "
                f"ranking again")
            baseline, early_rebaseline = outcome, False
            continue
        ranking = outcome
        if left == 0 or settled(ranking) or not ranking.refits:
            return ranking      # (without a refit there is no effect's optimum to re-fit the baseline from)
        left -= 1
        # an effect's refit may have moved the baseline unknowns into a better basin (refits.better_baseline)
        say("baseline re-fit from the effects' optima")
        with clock.stage("re-baseline"):
            better = better_baseline(problem, ranking.baseline, [rf.fit for rf in ranking.refits.values()],
                                     executor)
        if better is None:
            return ranking
        say(f"baseline re-fit from an effect's optimum: RSS {ranking.baseline.rss:.4g} -> {better.rss:.4g}; "
            f"ranking again")
        baseline, early_rebaseline = better, rebaseline


def _nothing_to_explain(problem: GapProblem, baseline: Fit, before: np.ndarray) -> bool:
    """Whether no refit can change the verdict: the baseline leaves the fit windows and the held-out records
    within the gap threshold of the noise floor — the verdict is then ``none`` whatever a refit finds
    (:func:`diagnosis.judgement.verdict.name_cause`) — and nothing else could overrule it: no prior on the beam
    (a baseline at the floor only by breaking one yields to a refit that keeps it) and no measured modes (a
    second set-up the baseline may misfit).  Measured on the grid test's record without effect: five local refits
    on the refined grid's 243 nodes, every one leaving the baseline's 1.033 noise variances, took 74 of 175 s."""
    threshold = problem.settings.gap_threshold
    return (baseline.rss / baseline.n - 1.0 < threshold and float(np.mean(before)) - 1.0 < threshold
            and not problem.has_prior and problem.modes is None)


def _shortlist(problem: GapProblem, effects: dict[str, Effect], scores: dict[str, EffectScore], by_score: list[str],
               shortlist: int) -> list[str]:
    """The effects to refit: the ``shortlist`` best-scoring physical ones, and apart from them the measurement
    chain's gains and the special cases at a fixed place.  A gain is degenerate with a common scale of the beam's
    unknowns, so its score at a baseline that took up the scale says little of its worth, and it must not push a
    physical effect off the shortlist (measured: a sensor's gain displaced the right clamp spring in the blind
    family); it is refitted when it scores best of all, and — a prior on the beam breaking the degeneracy —
    whenever its score is significant.  A special case (a transducer's mass, a shaker's armature) is refitted
    where a general effect's refit lands near its place (:mod:`diagnosis.search.nested`), and from its own score
    when that is significant and the best of all: a score at a fixed place must not push a general effect off the
    shortlist, but the candidate the records ask for most is never left out.  When the measured modes come from a
    set-up without some of the records' rig parts (:attr:`GapProblem.modes_lack`), the effects of those parts are
    refitted too: they are what the two set-ups differ by.  An effect the records themselves read
    (:attr:`Effect.read <diagnosis.effects.Effect.read>`) is refitted whatever its rank."""
    significant = problem.settings.score_significance
    chain = {lab for lab in effects if effects[lab].scale_degenerate}
    nested = {lab for lab in effects if effects[lab].nested_in is not None}
    labels = [lab for lab in by_score if scores[lab].lm > 0 and lab not in chain | nested][:shortlist]
    with_prior = problem.has_prior
    extra = [lab for lab in by_score if lab in chain and scores[lab].lm > 0
             and ((with_prior and scores[lab].p_value < significant) or lab == by_score[0])]
    top = by_score[0] if by_score else None
    if top in nested and scores[top].lm > 0 and scores[top].p_value < significant:
        extra.append(top)
    # the measured modes come from a set-up without some of the records' rig parts: the effects of those parts are
    # the hypothesis the two set-ups stand for (a shaker attached for the records only), each refitted
    extra += [lab for lab in by_score if effects[lab].rig_part in problem.modes_lack and scores[lab].lm > 0
              and lab not in labels + extra]
    # what the records themselves read (a delay from their phase) is refitted whatever its rank: scored at a
    # baseline that left it out, it can rank below effects that bend that baseline (an undeclared 8-sample delay
    # on three sensors: rank 6 of 24, the verdict `unexplained`)
    extra += [lab for lab in by_score if effects[lab].read and scores[lab].lm > 0
              and scores[lab].p_value < significant and lab not in labels + extra]
    return labels + extra


@dataclass(frozen=True, eq=False)
class _Plan:
    """What every ranking of one :func:`rank_effects` call shares (its arguments, and the modal matches and local
    refits the rankings pass on to each other)."""

    catalogue: Catalogue
    shortlist: int
    max_evaluations: int
    say: Callable[[str], None]
    executor: Executor | None
    parallel: int
    modal: Callable[[np.ndarray], ModalEvidence] | None
    clock: StageClock
    matches: dict[str, PatternFit]
    memo: RefitMemo
    seeds: dict[str, tuple[Effect, Fit]]


def _rank_once(problem: GapProblem, baseline: Fit, plan: _Plan, rebaseline: bool) -> Ranking | Fit:
    """One ranking from ``baseline`` (the stages of the module docstring), or — with ``rebaseline``, before the
    continuation refits — the better baseline a local refit revealed (:func:`rank_effects` ranks from it)."""
    catalogue, say, executor, modal, clock = plan.catalogue, plan.say, plan.executor, plan.modal, plan.clock
    effects = {e.label: e for e in catalogue.effects()}
    before, _ = problem.heldout(baseline.beta)
    scores = {}
    with clock.stage("score tests"):
        for lab, e in effects.items():
            scores[lab] = score_effect(problem, baseline, e)
            say(f"score {lab}: {scores[lab].lm:.4g}")
    run = Search(problem, baseline, catalogue, effects, before, scores, plan.max_evaluations, executor, say, clock,
                 plan.matches, plan.memo)
    by_score = tie_ordered(effects, lambda lab: -scores[lab].lm)
    if _nothing_to_explain(problem, baseline, before):
        say(f"the baseline leaves the fit windows at {baseline.rss / baseline.n:.3g} and the held-out records at "
            f"{np.mean(before):.3g} noise variances, within {problem.settings.gap_threshold:.0%} of the floor, "
            f"with no prior or measured modes it could contradict: nothing to explain, no effect refitted")
        unseen = not_refitted(effects, scores, set(), {}, {}, problem.settings, with_prior=False, at_floor=True)
        for line in unseen.values():
            say(line)
        return Ranking(baseline, before, scores, {}, list(by_score), [], effects, not_refitted=unseen)
    labels = _shortlist(problem, effects, scores, by_score, plan.shortlist)
    seeds = {lab: fit for lab, fit in plan.seeds.items() if lab in effects}
    labels += [lab for lab in seeds if lab not in labels]
    # with the modal pattern at hand, the other basins wait until it has been tried (it is cheaper)
    with clock.stage("local refits"):
        local = run.refit(labels, stage="local" if modal is None else "first")
    for lab, (fit, _) in local.items():
        say(f"local refit {lab}: fit RSS/n {baseline.rss / baseline.n:.4g} -> {fit.rss / fit.n:.4g} "
            f"({fit.n_evaluations} evaluations)")
    patterns: dict[str, PatternFit] = {}
    evidence = None
    early: Early = None
    if modal is not None and not run.at_noise_floor(local):
        # also when a refit explains the dominant part only: the effect that leaves 11 noise variances may be
        # another's stand-in found first (a spring to ground 0.5 m off, measured), its modal match puts it right
        with clock.stage("measured modes"):
            evidence = modal(baseline.beta)
        patterns, labels, early, local = modal_stage(run, evidence, labels, local)
    if not run.explained(local) and not pair_explains(early, baseline, problem.settings):
        with clock.stage("re-baseline"):
            better = (better_baseline(problem, baseline, [fit for fit, _ in local.values()], executor)
                      if rebaseline else None)
        if better is not None:
            return better
        if evidence is None:     # (the modal stage, when it ran, has tried the pair already)
            with clock.stage("pairs"):
                early, local = early_pair(run, labels, local)
        local = _continuation_stage(run, labels, local, early, evidence, patterns, plan.parallel)
    # the seeds last: a seed at the floor would stop the stages that may find a better optimum (the strip's crack:
    # the seed polished to 1.036 noise variances, held-out 1.61; the modal match 0.994, held-out 1.06)
    local = seeded(problem, effects, local, seeds, plan.max_evaluations, say)
    return _decide(run, by_score, labels, local, early, patterns, evidence)
