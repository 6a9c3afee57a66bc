"""Which effect: score test to shortlist, refit, information criteria and held-out error to rank.

Score (Lagrange-multiplier) test
--------------------------------
At the fitted baseline (residuals ``r``, noise-normalised, Jacobian ``J_β``
w.r.t. the baseline unknowns) the effect's variable ``s`` is at its "off"
value.  With ``J_s`` the derivative of the residuals w.r.t. ``s`` there and
``J̃ = (I − P_β) J_s`` its part that the baseline unknowns cannot mimic
(``P_β`` the projector onto the columns of ``J_β`` — this is the score
"scaled by the Fisher information" with the nuisance parameters profiled out),
the statistic

.. math::  LM = \\frac{(\\tilde J^T r)^2}{\\tilde J^T \\tilde J}

is the drop of the residual sum of squares a Gauss–Newton step in ``s`` (with
the baseline re-adjusted) predicts; it is χ²₁ when the effect is absent and the
residual is white noise.  One-sided effects (a spring, a mass, a lag cannot be
negative) score 0 when the first-order improvement needs ``s`` below its off
value.  The point mass has a position that is undefined when the mass is 0 (a
nuisance present only under the alternative): its score is the supremum over a
grid of positions.

Refit and ranking
-----------------
The best-scoring effects are refitted together with the baseline unknowns on
the fit windows, from the best of the score's step and a coarse grid of the
effect.  When that local refit leaves more than 10 % of the fit windows'
excess unexplained — and more than :data:`GAP_THRESHOLD` above the noise
floor, the level at which the verdict would be ``none`` (an excess of 0.7
closed to 0.09 is explained: the rest is the noise estimate's and the
model's own few per cent) — the baseline may sit in a basin that only suited the
model without the effect: the refit is repeated from the other basins of the
baseline's global search.  When still no shortlisted effect explains the gap,
each is refitted once more by *continuation in the record length*: a global
search (differential evolution) over the baseline unknowns and the effect
together on the first :data:`CONTINUATION` fraction of every fit window, where
a few-per-cent frequency error costs a fraction of a cycle instead of whole
cycles, followed by local fits on ever longer windows.  The fit with the
lowest residual on the whole fit windows is kept.  Each refit gets BIC/AIC
(``n ln(RSS/n) + k ln n``) and its gap ratio
on the held-out windows.  Effects are ranked by held-out error among those
whose BIC improves by more than :data:`BIC_MARGIN` (an extra parameter must
pay for itself).  The verdict is ``none`` when the baseline's held-out gap is
within :data:`GAP_THRESHOLD` of the noise floor or no candidate pays for
itself; effects whose held-out improvement is within 5 % of the best are
reported as indistinguishable from it.
"""
from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.stats import chi2

from .effects import Catalogue, Effect
from .fitting import Fit, GapProblem

__all__ = ["EffectScore", "EffectRefit", "Ranking", "better_baseline", "score_effect", "refit_effect", "rank_effects",
           "GAP_THRESHOLD", "BIC_MARGIN"]

#: Relative excess of the held-out residual variance over the noise floor below which there is no gap to explain.
GAP_THRESHOLD = 0.25
#: BIC improvement an effect must reach to count as paying for its parameters.
BIC_MARGIN = 10.0
#: Fractions of the fit windows of the continuation refit (the first one searched globally).
CONTINUATION = (0.1, 0.3, 1.0)
#: Positions tried for the point mass score (fractions of the search interval).
_MASS_GRID = 13


@dataclass(frozen=True)
class EffectScore:
    """Score-test outcome of one effect at the baseline."""

    label: str
    lm: float
    p_value: float
    start: np.ndarray          # suggested start of the refit (Gauss–Newton step), search variables
    n_evaluations: int
    alternatives: tuple[np.ndarray, ...] = ()   # further starts (e.g. another point-mass position)


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


@dataclass(frozen=True, eq=False)
class Ranking:
    """All scores, the refits, the order and the verdict."""

    baseline: Fit
    heldout_before: np.ndarray
    scores: dict[str, EffectScore]
    refits: dict[str, EffectRefit]
    order: list[str]
    verdict: str
    indistinguishable: list[str] = field(default_factory=list)
    reason: str = ""


def _orthogonal(J: np.ndarray, Q: np.ndarray) -> np.ndarray:
    return J - Q @ (Q.T @ J)


def _lm(Jt: np.ndarray, r: np.ndarray, one_sided: bool) -> tuple[float, float]:
    """LM statistic and Gauss–Newton step for one column."""
    d = float(Jt @ Jt)
    if d <= 0:
        return 0.0, 0.0
    g = float(Jt @ r)
    step = -g / d
    if one_sided and step <= 0:
        return 0.0, 0.0
    return g * g / d, step


def score_effect(problem: GapProblem, baseline: Fit, effect: Effect) -> EffectScore:
    """Score test of ``effect`` at the fitted ``baseline`` (see the module docstring)."""
    Q, _ = np.linalg.qr(baseline.jac) if baseline.jac.size else (np.zeros((baseline.n, 0)), None)
    r = baseline.residuals
    lo, hi = np.asarray(effect.lower), np.asarray(effect.upper)
    off = np.asarray(effect.off, dtype=float)
    one_sided = bool(off[0] <= lo[0])
    span = hi - lo
    evals = 0
    starts: list[np.ndarray] = []
    # at the "off" value the augmented model is the baseline: its residuals are known
    if effect.dim == 1:
        J = problem.scaled_jacobian(baseline.beta, effect, off, r0=r)
        evals += 1
        lm, step = _lm(_orthogonal(J, Q)[:, 0], r, one_sided)
        start = off + np.clip(step, -0.5, 0.5) * span
    else:
        # switch variable 0 with nuisance variables (point mass: position) — sup over a grid
        grid: list[tuple[float, float, np.ndarray]] = []
        for frac in np.linspace(0.0, 1.0, _MASS_GRID):
            s = off.copy()
            s[1] = lo[1] + frac * span[1]
            J = problem.scaled_jacobian(baseline.beta, effect, s, r0=r)[:, :1]
            evals += 1
            lm_i, step_i = _lm(_orthogonal(J, Q)[:, 0], r, one_sided)
            grid.append((lm_i, step_i, s))
        grid.sort(key=lambda g: -g[0])
        lm, step, s_best = grid[0]
        start = s_best.copy()
        start[0] = off[0] + np.clip(step, -0.5, 0.5) * span[0]
        # the best position well apart from the first as an alternative start of the refit
        for lm_j, step_j, s_j in grid[1:]:
            if abs(s_j[1] - s_best[1]) > 0.2 * span[1] and lm_j > 0:
                alt = s_j.copy()
                alt[0] = off[0] + np.clip(step_j, -0.5, 0.5) * span[0]
                starts.append(np.clip(alt, lo, hi))
                break
    start = np.clip(start, lo, hi)
    p = float(chi2.sf(lm, 1))
    if effect.dim > 1:
        p = min(1.0, p * _MASS_GRID)   # Bonferroni over the position grid (conservative)
    return EffectScore(effect.label, float(lm), p, start, evals, tuple(starts))


def _best_start(problem: GapProblem, baseline: Fit, effect: Effect, score: EffectScore) -> np.ndarray:
    """The start of a refit with the lowest RSS among the score's Gauss–Newton step(s) and a coarse grid.

    The linearisation at the "off" value can badly misjudge a large effect, so
    the switch variable is also tried on a geometric grid up to its bound (and,
    for the point mass, at every position of a grid), the baseline unknowns
    held at their fitted values.
    """
    lo, hi = np.asarray(effect.lower, float), np.asarray(effect.upper, float)
    off = np.asarray(effect.off, float)
    if off[0] <= lo[0]:
        values = off[0] + (hi[0] - off[0]) * np.geomspace(1e-3, 1.0, 7)
    else:
        mag = (hi[0] - lo[0]) / 2 * np.geomspace(1e-3, 1.0, 4)
        values = np.clip(np.concatenate([off[0] - mag, off[0] + mag]), lo[0], hi[0])
    candidates = [score.start, *score.alternatives]
    positions = [None] if effect.dim == 1 else list(np.linspace(lo[1], hi[1], _MASS_GRID))
    for x in positions:
        for v in values:
            s = off.copy()
            s[0] = v
            if x is not None:
                s[1] = x
            candidates.append(s)

    def rss(s: np.ndarray) -> float:
        r = problem.residuals(baseline.beta, effect, s)
        return float(r @ r)

    return min(candidates, key=rss)


def _explains(fit: Fit, baseline: Fit) -> bool:
    """Whether ``fit`` leaves at most 10 % of the baseline's excess over the noise floor on the fit windows, or
    less than :data:`GAP_THRESHOLD` (nothing the verdict would call a gap)."""
    excess_before = baseline.rss / baseline.n - 1.0
    return excess_before <= GAP_THRESHOLD or fit.rss / fit.n - 1.0 <= max(0.1 * excess_before, GAP_THRESHOLD)


def _continuation_fit(problem: GapProblem, starts: list[tuple[np.ndarray, np.ndarray]], effect: Effect,
                      max_evaluations: int) -> tuple[Fit, int]:
    """Refit by continuation in the record length (see the module docstring); the best fit and evaluations used."""
    short = problem.truncated(CONTINUATION[0])
    beta_g, s_g, used = short.global_search(starts[0][0], effect, starts[0][1])
    best: Fit | None = None
    for beta, s in [(beta_g, s_g), *starts]:
        for fraction in CONTINUATION:
            stage = problem.truncated(fraction) if fraction < 1.0 else problem
            f = stage.fit(beta, effect, s, max_evaluations=max_evaluations)
            used += f.n_evaluations
            beta, s = f.beta, f.s
        if best is None or f.rss < best.rss:
            best = f
    assert best is not None
    return best, used


def _local_refit(problem: GapProblem, baseline: Fit, effect: Effect, score: EffectScore, max_evaluations: int
                 ) -> tuple[Fit, list[tuple[np.ndarray, np.ndarray]]]:
    """Refit from the score's start and, if that leaves the gap, from the baseline's other basins.

    Returns the best fit (its ``n_evaluations`` counting every fit) and the
    starts tried after the first refit's optimum (for a continuation refit).
    """
    fit = problem.fit(baseline.beta, effect, _best_start(problem, baseline, effect, score),
                      max_evaluations=max_evaluations)
    starts: list[tuple[np.ndarray, np.ndarray]] = []
    if not _explains(fit, baseline):
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


def _summarise(problem: GapProblem, baseline: Fit, heldout_before: np.ndarray, effect: Effect, fit: Fit
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


def refit_effect(problem: GapProblem, baseline: Fit, heldout_before: np.ndarray, effect: Effect,
                 score: EffectScore, *, max_evaluations: int = 300, continuation: bool = True) -> EffectRefit:
    """Refit the baseline unknowns and ``effect`` from the score's start; held-out error after.

    Falls back on the other basins of the baseline and (``continuation``) on
    the continuation in the record length when the local refit leaves more
    than 10 % of the fit windows' excess unexplained (module docstring).
    """
    fit, starts = _local_refit(problem, baseline, effect, score, max_evaluations)
    if continuation and not _explains(fit, baseline):
        fit = _continued(problem, fit, starts, effect, max_evaluations)
    return _summarise(problem, baseline, heldout_before, effect, fit)


def _refit_task(problem: GapProblem, catalogue: Catalogue, label: str, baseline: Fit, score: EffectScore,
                max_evaluations: int, previous: tuple[Fit, list] | None = None) -> tuple[Fit, list]:
    """One shortlisted effect's refit, in this or a worker process: the local refit, or (given the local
    refit as ``previous``) the continuation refit from it."""
    effect = catalogue.effect(label)
    if previous is None:
        return _local_refit(problem, baseline, effect, score, max_evaluations)
    return _continued(problem, *previous, effect, max_evaluations), []


def _map_refits(executor: Executor | None, problem: GapProblem, catalogue: Catalogue, labels: list[str],
                baseline: Fit, scores: dict[str, EffectScore], max_evaluations: int,
                previous: dict[str, tuple[Fit, list]] | None = None) -> dict[str, tuple[Fit, list]]:
    """:func:`_refit_task` for every label, on the executor's processes when given (same results: each refit is
    deterministic)."""
    args = [(problem, catalogue, lab, baseline, scores[lab], max_evaluations,
             None if previous is None else previous[lab]) for lab in labels]
    if executor is None or len(labels) < 2:
        return {lab: _refit_task(*a) for lab, a in zip(labels, args)}
    futures = [executor.submit(_refit_task, *a) for a in args]
    return {lab: f.result() for lab, f in zip(labels, futures)}


def better_baseline(problem: GapProblem, baseline: Fit, fits: list[Fit]) -> Fit | None:
    """The best baseline refitted from the baseline unknowns of ``fits`` when it beats ``baseline`` by more than
    0.1 % in RSS, else ``None``: an effect's refit may have moved the baseline unknowns into a better basin, and
    then the baseline itself was not at its optimum (every comparison must be made again)."""
    better = None
    for f in fits:
        cand = problem.fit(f.beta)
        if cand.rss < baseline.rss * (1.0 - 1e-3) and (better is None or cand.rss < better.rss):
            better = cand
    return better


def rank_effects(problem: GapProblem, baseline: Fit, catalogue: Catalogue, *, shortlist: int = 4,
                 max_evaluations: int = 300, progress: Any = None, executor: Executor | None = None,
                 rebaseline: bool = True) -> Ranking:
    """Score every effect, refit the ``shortlist`` best, rank and decide.

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
    rebaseline
        When no local refit explains the gap, first try the baseline from the local refits' baseline
        unknowns (:func:`better_baseline`); if that is better, rank again from it (once) before paying for
        the continuation refits — which would otherwise run twice, from the worse baseline and again.
        The returned :attr:`Ranking.baseline` is the baseline the ranking used.

    Returns
    -------
    Ranking
    """
    say = progress or (lambda _m: None)
    effects = catalogue.effects()
    before, _ = problem.heldout(baseline.beta)
    scores = {}
    for e in effects:
        scores[e.label] = score_effect(problem, baseline, e)
        say(f"score {e.label}: {scores[e.label].lm:.4g}")
    by_score = sorted(effects, key=lambda e: -scores[e.label].lm)
    chosen = [e for e in by_score if scores[e.label].lm > 0][:shortlist]
    labels = [e.label for e in chosen]
    local = _map_refits(executor, problem, catalogue, labels, baseline, scores, max_evaluations)
    for lab, (fit, _) in local.items():
        say(f"local refit {lab}: fit RSS/n {baseline.rss / baseline.n:.4g} -> {fit.rss / fit.n:.4g} "
            f"({fit.n_evaluations} evaluations)")
    if not any(_explains(fit, baseline) for fit, _ in local.values()):
        better = better_baseline(problem, baseline, [fit for fit, _ in local.values()]) if rebaseline else None
        if better is not None:
            say(f"baseline re-fit from a local refit's optimum: RSS {baseline.rss:.4g} -> {better.rss:.4g}; "
                f"ranking again")
            return rank_effects(problem, better, catalogue, shortlist=shortlist, max_evaluations=max_evaluations,
                                progress=progress, executor=executor, rebaseline=False)
        # no local refit explains the gap: the continuation refit for each (module docstring)
        local = _map_refits(executor, problem, catalogue, labels, baseline, scores, max_evaluations, local)
        for lab, (fit, _) in local.items():
            say(f"continuation refit {lab}: fit RSS/n {fit.rss / fit.n:.4g} ({fit.n_evaluations} evaluations)")
    refits = {e.label: _summarise(problem, baseline, before, e, local[e.label][0]) for e in chosen}
    for label, rf in refits.items():
        say(f"refit {label}: held-out gap ratio {np.mean(before):.3g} -> {np.mean(rf.heldout_after):.3g}, "
            f"dBIC {rf.delta_bic:.1f}")
    paying = [lab for lab, rf in refits.items()
              if rf.delta_bic < -BIC_MARGIN and np.mean(rf.heldout_after) < np.mean(before)]
    others = [lab for lab in refits if lab not in paying]
    paying.sort(key=lambda lab: float(np.mean(refits[lab].heldout_after)))
    others.sort(key=lambda lab: float(np.mean(refits[lab].heldout_after)))
    rest = [e.label for e in by_score if e.label not in refits]
    order = paying + others + rest
    excess = float(np.mean(before)) - 1.0
    if excess < GAP_THRESHOLD:
        return Ranking(baseline, before, scores, refits, order, "none", [],
                       f"the held-out residual variance is only {excess:+.0%} above the noise floor "
                       f"(threshold {GAP_THRESHOLD:.0%}): nothing to explain")
    if not paying:
        return Ranking(baseline, before, scores, refits, order, "none", [],
                       f"the held-out residual variance is {excess:+.0%} above the noise floor, but no "
                       f"candidate effect improves BIC by more than {BIC_MARGIN:g} and the held-out error")
    best = refits[paying[0]]
    gain = float(np.mean(before) - np.mean(best.heldout_after))
    ties = [lab for lab in paying[1:]
            if float(np.mean(before) - np.mean(refits[lab].heldout_after)) >= 0.95 * gain]
    reason = (f"{paying[0]} closes {best.closed:.0%} of the held-out gap "
              f"(gap ratio {np.mean(before):.3g} -> {np.mean(best.heldout_after):.3g}, dBIC {best.delta_bic:.1f})")
    if ties:
        reason += "; the data cannot distinguish it from " + ", ".join(ties)
    return Ranking(baseline, before, scores, refits, order, paying[0], ties, reason)
