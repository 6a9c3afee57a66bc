"""The refit stages of the diagnosis: an effect refitted together with the baseline unknowns.

Every stage refits the baseline unknowns and one effect (or a pair) on the fit
windows and is judged by :func:`explains` — whether the refit leaves at most
10 % of the baseline's excess over the noise floor (or less than
the gap threshold, no gap at all):

* **local** — from the best of the score test's step and a coarse grid of the
  effect, the baseline unknowns at their fitted values;
* **other basins** — from the other basins of the baseline's global search,
  when the local refit leaves the gap: the baseline may sit in a basin that
  only suited the model without the effect;
* **from a modal match** — from an effect's modal-pattern fit
  (:mod:`diagnosis.search.modal_pattern`);
* **continuation in the record length** — a global search (differential
  evolution) over the baseline unknowns and the effect together on the first
  :data:`CONTINUATION` fraction of every fit window, where a few-per-cent
  frequency error costs a fraction of a cycle instead of whole cycles, then
  local fits on ever longer windows from the search's best and the earlier
  refits' optima, the better half of them going on to each longer window;
* **pairs** — a second effect on top of a first effect's refit.

:func:`summarise` gives a refit its held-out error, fraction of the gap closed
and information criteria (BIC/AIC, ``n ln(RSS/n) + k ln n``).  The ``*_task``
functions run in this or a worker process (every refit is deterministic, so
the results do not depend on where it ran); the order of the stages and the
verdict are :mod:`diagnosis.search.rank`'s.
"""
from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass, replace
from typing import Callable, Mapping

import numpy as np


from ..effects import Catalogue, Effect, mirror_image, variables_for
from ..problem.fitting import Fit, GapProblem
from ..problem.ties import tie_ordered
from ..settings import Thresholds
from .modal_pattern import PatternFit
from ..candidates.score import EffectScore, effect_trials
from .workers import side_by_side

__all__ = ["EffectRefit", "explains", "summarise", "map_refits", "refit_from_match", "pair_refit",
           "better_baseline", "paying_refits", "seeded", "CONTINUATION", "RSS_RESOLUTION"]

#: Two fits of one model whose RSS differ by less than this share are taken as the same optimum: a margin, not a
#: measured figure, well above the refits' own tolerances (the cost's relative change 1e-12, the step 1e-10 of the
#: scaled unknowns, identification.least_squares) against two restarts of one basin ending a hair apart; only a
#: larger improvement counts as a better basin (a better baseline, a single effect better alone than in its pair).
RSS_RESOLUTION = 1e-3

#: Fractions of the fit windows of the continuation refit (the first one searched globally).
CONTINUATION = (0.1, 0.3, 1.0)


@dataclass(frozen=True)
class EffectRefit:
    """Refit of one shortlisted effect together with the baseline unknowns."""

    label: str
    fit: Fit
    physical: dict[str, float]
    bic: float
    aic: float
    delta_bic: float
    delta_aic: float
    heldout_after: np.ndarray   # gap ratio per sensor on the held-out windows
    closed: float               # fraction of the held-out gap closed (overall)
    closed_per_sensor: np.ndarray


def _best_start(problem: GapProblem, baseline: Fit, effect: Effect, score: EffectScore) -> np.ndarray:
    """The start of a refit with the lowest RSS among the score's Gauss–Newton step(s) and a coarse grid of the
    effect (:func:`~diagnosis.candidates.score.effect_trials`), the baseline unknowns held at their fitted values."""
    candidates = [score.start, *score.alternatives, *effect_trials(effect)]

    def rss(s: np.ndarray) -> float:
        r = problem.residuals(baseline.beta, effect, s)
        return float(r @ r)

    return min(candidates, key=rss)


def explains(fit: Fit, baseline: Fit, settings: Thresholds) -> bool:
    """Whether ``fit`` leaves at most ``explained_share`` of the baseline's excess over the noise floor on the fit
    windows, or less than ``gap_threshold`` (:class:`~diagnosis.settings.Thresholds`: nothing the verdict would
    call a gap)."""
    excess_before = baseline.rss / baseline.n - 1.0
    floor = settings.gap_threshold
    return excess_before <= floor or fit.rss / fit.n - 1.0 <= max(settings.explained_share * excess_before, floor)


def _continuation_fit(problem: GapProblem, starts: list[tuple[np.ndarray, np.ndarray]], effect: Effect,
                      max_evaluations: int) -> tuple[Fit, int]:
    """Refit by continuation in the record length (see the module docstring); the best fit and evaluations used."""
    short = problem.truncated(CONTINUATION[0])
    beta_g, s_g, used = short.global_search(starts[0][0], effect, starts[0][1])
    chains = [(beta_g, s_g), *starts]
    fits: list[Fit] = []
    for i, fraction in enumerate(CONTINUATION):
        if i > 0:
            # successive halving: only the better half of the chains goes on to the longer windows
            keep = sorted(range(len(fits)), key=lambda k: fits[k].rss)[:max(1, len(fits) // 2)]
            chains = [(fits[k].beta, fits[k].s) for k in keep]
        stage = problem.truncated(fraction) if fraction < 1.0 else problem
        fits = [stage.fit(beta, effect, s, max_evaluations=max_evaluations) for beta, s in chains]
        used += sum(f.n_evaluations for f in fits)
    return min(fits, key=lambda f: f.rss), used


def _local_refit(problem: GapProblem, baseline: Fit, effect: Effect, score: EffectScore, max_evaluations: int,
                 basins: bool = True) -> tuple[Fit, list[tuple[np.ndarray, np.ndarray]]]:
    """Refit from the score's start and (``basins``), if that leaves the gap, from the baseline's other basins.

    Returns the best fit (its ``n_evaluations`` counting every fit) and the
    starts tried after the first refit's optimum (for a continuation refit).
    """
    fit = problem.fit(baseline.beta, effect, _best_start(problem, baseline, effect, score),
                      max_evaluations=max_evaluations)
    fit = _mirrored(problem, effect, _rescaled(problem, effect, fit, max_evaluations), max_evaluations)
    fit = _from_the_records(problem, baseline, effect, fit, max_evaluations)
    return _basin_refits(problem, baseline, effect, score, fit, [], max_evaluations) if basins else (fit, [])


def _rescaled(problem: GapProblem, effect: Effect, fit: Fit, max_evaluations: int) -> Fit:
    """``fit``, or the refit from the effect's rescaled start (:attr:`Effect.rescale`: along a direction the
    data cannot see, to where the priors are best) when that is better."""
    if effect.rescale is None or problem.prior is None or not problem.prior.count:
        return fit
    start = effect.rescale(problem.space.names, fit.beta, fit.s, problem.prior)
    if start is None:
        return fit
    lo, hi = problem.box(effect).lower, problem.box(effect).upper
    z = np.clip(np.concatenate(start), lo, hi)
    p = problem.space.dim
    moved = problem.fit(z[:p], effect, z[p:], max_evaluations=max_evaluations)
    best = moved if moved.rss < fit.rss else fit
    return replace(best, n_evaluations=fit.n_evaluations + moved.n_evaluations)


def _from_the_records(problem: GapProblem, baseline: Fit, effect: Effect, fit: Fit, max_evaluations: int) -> Fit:
    """``fit``, or, when it leaves a gap and that is better, the refit from each box the records themselves put
    the effect in (:attr:`Effect.read <diagnosis.effects.Effect.read>`: a delay read from their phase): by
    continuation in the record length (:func:`_continuation_fit`) with the effect held in the box, then freed.
    A local refit from the baseline is not enough: the baseline that left the effect out can sit in another
    basin (a hint record 10 samples late, half its first mode's period: its baseline had skipped the first mode,
    and the local refit with the delay read stayed there, 36 noise variances; held in the reading's box, the
    floor, 1.009)."""
    if not effect.read or fit.rss / fit.n - 1.0 <= problem.settings.gap_threshold:
        return fit
    best, used = fit, fit.n_evaluations
    for lower, upper in effect.read:
        held = replace(effect, lower=lower, upper=upper)
        start = (np.asarray(lower, dtype=float) + np.asarray(upper, dtype=float)) / 2
        near, n = _continuation_fit(problem, [(baseline.beta, start)], held, max_evaluations)
        freed = problem.fit(near.beta, effect, near.s, max_evaluations=max_evaluations)
        used += n + freed.n_evaluations
        best = freed if freed.rss < best.rss else best
    return replace(best, n_evaluations=used)


def _mirrored(problem: GapProblem, effect: Effect, fit: Fit, max_evaluations: int) -> Fit:
    """``fit``, or the refit from the mirror image of the effect's place on a beam that is the same seen from
    either end (:func:`~diagnosis.effects.base.mirror_image`) when ``fit`` leaves a gap and that is better."""
    if fit.rss / fit.n - 1.0 <= problem.settings.gap_threshold:
        return fit
    at, _params = problem.space.apply(problem.config, fit.beta)
    s = mirror_image(effect, at, fit.s)
    if s is None:
        return fit
    moved = problem.fit(fit.beta, effect, s, max_evaluations=max_evaluations)
    best = moved if moved.rss < fit.rss else fit
    return replace(best, n_evaluations=fit.n_evaluations + moved.n_evaluations)


def _basin_refits(problem: GapProblem, baseline: Fit, effect: Effect, score: EffectScore, fit: Fit,
                  starts: list[tuple[np.ndarray, np.ndarray]], max_evaluations: int
                  ) -> tuple[Fit, list[tuple[np.ndarray, np.ndarray]]]:
    """``fit``, or the refit from the baseline's other basins when that is better and ``fit`` leaves the gap;
    ``starts`` gains the starts tried."""
    starts = list(starts)
    if not explains(fit, baseline, problem.settings):
        # the baseline unknowns may sit in a basin that only suited the model without the effect
        used = fit.n_evaluations
        starts.append((fit.beta, fit.s))
        for beta_alt in problem.other_starts:
            s_alt = _best_start(problem, replace(baseline, beta=beta_alt), effect, score)
            starts.append((beta_alt, s_alt))
            alt = problem.fit(beta_alt, effect, s_alt, max_evaluations=max_evaluations)
            used += alt.n_evaluations
            if alt.rss < fit.rss:
                fit = alt
        fit = replace(fit, n_evaluations=used)
    return fit, starts


def _continued(problem: GapProblem, fit: Fit, starts: list[tuple[np.ndarray, np.ndarray]], effect: Effect,
               max_evaluations: int) -> Fit:
    """``fit``, or the continuation refit from it and ``starts`` when that fits the whole windows better."""
    others = [st for st in starts if not (np.array_equal(st[0], fit.beta) and np.array_equal(st[1], fit.s))]
    cont, used = _continuation_fit(problem, [(fit.beta, fit.s), *others], effect, max_evaluations)
    best = cont if cont.rss < fit.rss else fit
    return replace(best, n_evaluations=fit.n_evaluations + used)


def summarise(problem: GapProblem, baseline: Fit, heldout_before: np.ndarray, effect: Effect, fit: Fit
               ) -> EffectRefit:
    """Held-out error, % closed and information criteria of an effect's refit."""
    p = problem.space.dim
    after, _ = problem.heldout(fit.beta, effect, fit.s)
    b_excess = heldout_before - 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        per = np.where(b_excess > 1e-12, (heldout_before - after) / b_excess, np.nan)
    tot_b, tot_a = float(np.mean(heldout_before)), float(np.mean(after))
    closed = (tot_b - tot_a) / (tot_b - 1.0) if tot_b > 1.0 else float("nan")
    bic = fit.bic(p + effect.dim)
    aic = fit.aic(p + effect.dim)
    return EffectRefit(effect.label, fit, effect.physical(fit.s), bic, aic,
                       bic - baseline.bic(p), aic - baseline.aic(p), after, float(closed), per)


def _refit_task(problem: GapProblem, catalogue: Catalogue, label: str, baseline: Fit, score: EffectScore,
                max_evaluations: int, previous: tuple[Fit, list] | None = None, stage: str = "local"
                ) -> tuple[Fit, list]:
    """One shortlisted effect's refit, in this or a worker process: the local refit (``"local"``: with the
    other basins, ``"first"``: without), or, given the refit so far as ``previous``, the other basins'
    refits (``"basins"``) or the continuation refit (``"continuation"``)."""
    effect = catalogue.effect(label)
    if previous is None:
        return _local_refit(problem, baseline, effect, score, max_evaluations, basins=stage == "local")
    if stage == "basins":
        return _basin_refits(problem, baseline, effect, score, *previous, max_evaluations)
    return _continued(problem, *previous, effect, max_evaluations), []


def refit_from_match(problem: GapProblem, catalogue: Catalogue, label: str, match: PatternFit, max_evaluations: int
                     ) -> tuple[Fit, list]:
    """Refit of one effect from its modal-pattern match, and from the other baselines' matches the modes cannot
    tell from it (:attr:`PatternFit.others`), in this or a worker process; the best refit is kept."""
    effect = catalogue.effect(label)
    starts = [match, *match.others]
    fit = min((problem.fit(m.beta, effect, m.s, max_evaluations=max_evaluations) for m in starts),
              key=lambda f: f.rss)
    return _mirrored(problem, effect, fit, max_evaluations), [(m.beta, m.s) for m in starts]


def map_refits(executor: Executor | None, problem: GapProblem, catalogue: Catalogue, labels: list[str],
                baseline: Fit, scores: dict[str, EffectScore], max_evaluations: int,
                previous: dict[str, tuple[Fit, list]] | None = None, stage: str = "local"
                ) -> dict[str, tuple[Fit, list]]:
    """:func:`_refit_task` for every label, on the executor's processes when given (same results: each refit is
    deterministic)."""
    args = [(problem, catalogue, lab, baseline, scores[lab], max_evaluations,
             None if previous is None else previous[lab], stage) for lab in labels]
    return dict(zip(labels, side_by_side(executor, _refit_task, args)))


def _pair_start(problem: GapProblem, first: Fit, pair: Effect, k: int) -> np.ndarray:
    """Start of a pair's refit: the first effect's refit, the partner's variables the best of a coarse grid
    (:func:`~diagnosis.candidates.score.effect_trials`) with everything else held."""
    def rss(s2: np.ndarray) -> float:
        r = problem.residuals(first.beta, pair, np.concatenate([first.s, s2]))
        return float(r @ r)

    return np.concatenate([first.s, min(effect_trials(pair.members[1]), key=rss)])


def pair_refit(problem: GapProblem, catalogue: Catalogue, label: str, first: Fit, max_evaluations: int) -> Fit:
    """Refit of a pair of effects (``first`` is the first effect's refit), in this or a worker process."""
    pair = catalogue.effect(label)
    start = _pair_start(problem, first, pair, first.s.size)
    return problem.fit(first.beta, pair, start, max_evaluations=max_evaluations)


def better_baseline(problem: GapProblem, baseline: Fit, fits: list[Fit], executor: Executor | None = None
                    ) -> Fit | None:
    """The best baseline refitted from the baseline unknowns of ``fits`` when it beats ``baseline`` by more than
    :data:`RSS_RESOLUTION` in RSS, else ``None``: an effect's refit may have moved the baseline unknowns into a
    better basin, and then the baseline itself was not at its optimum (every comparison must be made again).  The
    refits run on ``executor``'s processes when given."""
    candidates = side_by_side(executor, problem.fit, [(f.beta,) for f in fits])
    better = None
    for cand in candidates:
        if cand.rss < baseline.rss * (1.0 - RSS_RESOLUTION) and (better is None or cand.rss < better.rss):
            better = cand
    return better


def paying_refits(refits: Mapping[str, EffectRefit], before: np.ndarray, settings: Thresholds) -> list[str]:
    """The effects whose refit pays for its parameters (BIC by ``settings.bic_margin``) and lowers the held-out
    error, the lowest held-out error first (an exact tie by label: :mod:`diagnosis.problem.ties`)."""
    paying = [lab for lab, rf in refits.items()
              if rf.delta_bic < -settings.bic_margin and np.mean(rf.heldout_after) < np.mean(before)]
    return tie_ordered(paying, lambda lab: float(np.mean(refits[lab].heldout_after)))


def seeded(problem: GapProblem, effects: Mapping[str, Effect], local: dict[str, tuple[Fit, list]],
           seeds: Mapping[str, tuple[Effect, Fit]], max_evaluations: int, say: Callable[[str], None]
           ) -> dict[str, tuple[Fit, list]]:
    """``local`` (the refits so far by label, :data:`~diagnosis.search.state.Refits`) with each of ``seeds`` — a
    refit an earlier stage made, with the effect it was made with — polished on ``problem``, kept where it fits
    better.  A seed's variables are taken to ``effects``' by their physical values
    (:func:`~diagnosis.effects.variables_for`: the catalogues of two baselines size a mass by two values of ρA L —
    the pinned beam's 55 g mass, seeded by its share of the other, was polished from 1.02 noise variances to
    1.20)."""
    out = dict(local)
    for lab, (made_with, seed) in seeds.items():
        effect = effects[lab]
        s = variables_for(effect, made_with.physical(seed.s), seed.s)
        if s is None:
            continue
        fit = problem.fit(seed.beta, effect, s, max_evaluations=max_evaluations)
        say(f"refit {lab} from the earlier stage's: fit RSS/n {fit.rss / fit.n:.4g}")
        if lab not in out or fit.rss < out[lab][0].rss:
            out[lab] = (fit, [(seed.beta, s)])
    return out
