"""Which effect, first step: the score test of an effect at the fitted baseline.

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
grid of positions (its p-value Bonferroni-corrected over the grid).  An effect of
two sizes, both off at their bound (a shaker's moving mass and its suspension),
has no nuisance: its statistic is the largest drop a step with both sizes
non-negative predicts (the columns taken together, non-negative least squares),
under the null a χ̄² mixture of χ²₀, χ²₁ and χ²₂ whose χ²₁ weight is ½ — its
p-value takes the χ²₂ weight as ½ too, an upper bound.  (Treating the second
size as a position — evaluating the first's derivative with the second already
on — scored an effect that was not off: 4.7e6 for an armature on the real bench,
34× the next candidate on a record whose only effect was rotary inertia.)

An effect with a direction the data cannot see (:attr:`Effect.rescale <diagnosis.effects.Effect.rescale>`: a
transducer's gain against the beam's level — EI, ρA, c and N scaled together) is scored by a step along that
direction too, evaluated rather than linearised: to the valley's point where the priors are best.  Its drop of the
residual sum of squares is the priors' (the data's residuals are unchanged along the direction), and the statistic
is the larger of the two — when that step moves two or more unknowns with a prior: along the level, a single prior
is met by any wrong value of its own (a prior on EI 30 % off the truth is met by every gain of 1.3 as well), so the
data and one prior cannot tell a chain's gain from that prior's error; priors on EI and ρA (a geometry) that the
step meets together are evidence of a gain (a wrong thickness moves EI by its cube, ρA by itself).  The linearised
score alone misses it on a lightly damped record: the baseline's forward-difference Jacobian is a secant across a
resonance's bandwidth, so its columns do not span the gain's (measured: the steel strip under a broadband force,
its accelerometer read 1.3 high, a geometry prior 16 σ from the baseline: the gain's column 51 % outside the
baseline's, LM 0.03 where the valley's step drops χ² by 260).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import optimize
from scipy.stats import chi2

from ..effects import Effect
from ..problem.fitting import Fit, GapProblem

__all__ = ["EffectScore", "MASS_GRID", "score_effect", "trial_values", "effect_trials"]

#: A second start of a placed effect's refit (the best-scoring position well apart from the best) lies at least
#: this share of the position's range from the first: a start, not a decision (the refit moves from it freely).
ALTERNATIVE_APART = 0.2

#: Positions tried for the point mass score (fractions of the search interval).
MASS_GRID = 13


@dataclass(frozen=True)
class EffectScore:
    """Score-test outcome of one effect at the baseline."""

    label: str
    lm: float
    p_value: float
    start: np.ndarray          # suggested start of the refit (Gauss–Newton step), search variables
    n_evaluations: int
    alternatives: tuple[np.ndarray, ...] = ()   # further starts (e.g. another point-mass position)


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


def _lm_sizes(Jt: np.ndarray, r: np.ndarray) -> tuple[float, np.ndarray]:
    """LM statistic and Gauss–Newton step of several one-sided sizes together: the largest drop of the residual
    sum of squares a step with every size non-negative predicts (non-negative least squares on the columns
    orthogonal to the baseline unknowns)."""
    if not np.any(Jt):
        return 0.0, np.zeros(Jt.shape[1])
    step, _ = optimize.nnls(Jt, -r)
    left = r + Jt @ step
    return max(0.0, float(r @ r - left @ left)), step


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
    if effect.dim == 2 and off[1] <= lo[1]:
        # two sizes, both off at their bound (a shaker's mass and suspension): no nuisance — the second is not a
        # position to take the supremum over but a size whose nonzero value is itself the effect
        J = problem.scaled_jacobian(baseline.beta, effect, off, r0=r)
        evals += effect.dim
        lm, step2 = _lm_sizes(_orthogonal(J, Q), r)
        start = off + np.clip(step2, 0.0, 0.5) * span
        p = min(1.0, 0.5 * float(chi2.sf(lm, 1)) + 0.5 * float(chi2.sf(lm, 2)))
        return EffectScore(effect.label, float(lm), p, np.clip(start, lo, hi), evals)
    if effect.dim == 1:
        J = problem.scaled_jacobian(baseline.beta, effect, off, r0=r)
        evals += 1
        lm, step = _lm(_orthogonal(J, Q)[:, 0], r, one_sided)
        start = off + np.clip(step, -0.5, 0.5) * span
    else:
        # switch variable 0 with nuisance variables (point mass: position) — sup over a grid
        grid: list[tuple[float, float, np.ndarray]] = []
        for frac in np.linspace(0.0, 1.0, MASS_GRID):
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
            if abs(s_j[1] - s_best[1]) > ALTERNATIVE_APART * span[1] and lm_j > 0:
                alt = s_j.copy()
                alt[0] = off[0] + np.clip(step_j, -0.5, 0.5) * span[0]
                starts.append(np.clip(alt, lo, hi))
                break
    start = np.clip(start, lo, hi)
    along = _along_the_valley(problem, baseline, effect)
    if along is not None and along[0] > lm:
        lm, start = along[0], np.clip(along[1], lo, hi)
        evals += 1
    looks = MASS_GRID if effect.dim > 1 else 1
    if effect.trials:
        drop, best = _over_the_trials(problem, baseline, effect)
        evals += len(effect.trials)
        looks += len(effect.trials)
        if drop > lm:
            lm, start = drop, np.clip(best, lo, hi)
    p = float(chi2.sf(lm, 1))
    if looks > 1:
        p = min(1.0, p * looks)   # Bonferroni over the position grid or the trials (conservative)
    return EffectScore(effect.label, float(lm), p, start, evals, tuple(starts))


def _over_the_trials(problem: GapProblem, baseline: Fit, effect: Effect) -> tuple[float, np.ndarray]:
    """The largest drop of the residual sum of squares from the baseline over ``effect``'s own trial values
    (:attr:`Effect.trials <diagnosis.effects.Effect.trials>`: where its χ² is not unimodal, a linearisation at
    "off" sees only the nearest valley — a delay of four samples scored 30× below its drop), the baseline
    unknowns held, and the trial that gives it."""
    rss0 = float(baseline.residuals @ baseline.residuals)
    drops = []
    for s in effect.trials:
        r = problem.residuals(baseline.beta, effect, s)
        drops.append(rss0 - float(r @ r))
    k = int(np.argmax(drops))
    return max(0.0, drops[k]), np.asarray(effect.trials[k], dtype=float)


def _along_the_valley(problem: GapProblem, baseline: Fit, effect: Effect) -> tuple[float, np.ndarray] | None:
    """The drop of the residual sum of squares from the baseline to the point of ``effect``'s unseen direction
    where the priors are best (module docstring), and the effect's variables there; ``None`` for an effect
    without such a direction or a problem without priors."""
    if effect.rescale is None or problem.prior is None or not problem.prior.count:
        return None
    moved = effect.rescale(problem.space.names, baseline.beta, np.asarray(effect.off, dtype=float), problem.prior)
    if moved is None:
        return None
    box = problem.box(effect)
    z = np.clip(np.concatenate(moved), box.lower, box.upper)
    p = problem.space.dim
    if np.count_nonzero((z[:p] != baseline.beta) & np.isfinite(problem.prior.std)) < 2:
        return None
    r = problem.residuals(z[:p], effect, z[p:])
    return float(baseline.residuals @ baseline.residuals - r @ r), z[p:]


def trial_values(lower: ArrayLike, upper: ArrayLike, off: ArrayLike) -> list[np.ndarray]:
    """A coarse grid of an effect's variables around "off": the switch variable on a geometric grid up to its
    bound (both ways for a two-sided effect), times :data:`MASS_GRID` positions when there is a second variable
    — or, when the second is a one-sided size too (its off value on its lower bound: a shaker's suspension
    beside its mass), times that size on the same geometric grid and at its off value.  The linearisation at
    "off" can badly misjudge a large effect; refits start from the best of these."""
    lo, hi, off = (np.asarray(v, dtype=float) for v in (lower, upper, off))
    if off[0] <= lo[0]:
        values = off[0] + (hi[0] - off[0]) * np.geomspace(1e-3, 1.0, 7)
    else:
        mag = (hi[0] - lo[0]) / 2 * np.geomspace(1e-3, 1.0, 4)
        values = np.clip(np.concatenate([off[0] - mag, off[0] + mag]), lo[0], hi[0])
    if off.size == 1:
        positions: list[float | None] = [None]
    elif off[1] <= lo[1]:
        positions = [float(off[1])] + list(off[1] + (hi[1] - off[1]) * np.geomspace(1e-3, 1.0, 7))
    else:
        positions = list(np.linspace(lo[1], hi[1], MASS_GRID))
    out = []
    for x in positions:
        for v in values:
            s = off.copy()
            s[0] = v
            if x is not None:
                s[1] = x
            out.append(s)
    return out


def effect_trials(effect: Effect) -> list[np.ndarray]:
    """The trial starts of ``effect``'s refit: its own (:attr:`Effect.trials <diagnosis.effects.Effect.trials>`)
    where it has them, else :func:`trial_values`' coarse grid."""
    return list(effect.trials) or trial_values(effect.lower, effect.upper, effect.off)
