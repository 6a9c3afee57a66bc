"""Whether a refit explains the data with values a physicist would sign: the effect's parameters inside their
plausible ranges (:attr:`diagnosis.effects.Effect.plausible`), the baseline unknowns consistent with the user's
priors (:mod:`identification.prior`, within :data:`identification.prior.CONFLICT_SIGMA` prior standard
deviations), and its modes consistent with the measured ones when the config gives them
(:mod:`identification.modal_data`).

A flexible wrong effect with compensating parameters can close most of a large gap — a "point mass" of 2.7 kg,
three times the beam, on the accelerometer of a real bench, with the beam's density pushed to its bound.  Such a
refit is not named as the cause (:func:`plausible_verdict`): the verdict goes to the best plausible candidate that
meets the naming rule, or to :data:`diagnosis.verdict.UNEXPLAINED`, and the report says what the implausible one
needed.  Nothing implausible is exported as the corrected model.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Mapping

import numpy as np

from identification.prior import PriorCheck

from .effects import Effect
from .fitting import Fit, GapProblem
from .rank import Ranking
from .verdict import BIC_MARGIN, verdict_rule

__all__ = ["CONFOUNDED", "confounded", "implausibilities", "plausible_verdict", "posterior_std", "prior_checks"]

#: Share of an effect's sensitivity (norm of its Jacobian column on the data) that the baseline unknowns'
#: sensitivities leave unexplained, below which the effect is degenerate with them: the data alone cannot
#: separate the two (a sensor's gain and a common scale of EI, ρA and c), only a prior can.
CONFOUNDED = 1e-3


def posterior_std(problem: GapProblem, fit: Fit) -> np.ndarray:
    """Posterior standard deviations of the baseline unknowns at ``fit`` (Gauss–Newton: its Jacobian, whose
    rows include the priors', in the fit's unit box)."""
    p = problem.space.dim
    J = np.asarray(fit.jac, dtype=float)
    if J.size == 0:
        return np.full(p, np.inf)
    cov = np.linalg.pinv(J.T @ J, rcond=1e-12)
    span = np.asarray(problem.space.upper, dtype=float) - np.asarray(problem.space.lower, dtype=float)
    return span * np.sqrt(np.clip(np.diag(cov)[:p], 0.0, None))


def prior_checks(problem: GapProblem, fit: Fit) -> list[PriorCheck]:
    """Each prior's check at the fit's baseline unknowns (empty without priors)."""
    if problem.prior is None or not problem.prior.count:
        return []
    return problem.prior.judge(fit.beta, posterior_std(problem, fit))


def implausibilities(problem: GapProblem, effect: Effect, fit: Fit) -> list[str]:
    """What is implausible about the refit of ``effect`` (empty: nothing) — one line each."""
    lines = []
    values = effect.physical(fit.s)
    for name, (lo, hi) in effect.plausible.items():
        v, unit = values[name], effect.units.get(name, "")
        if not lo <= v <= hi:
            lines.append(f"{effect.label}: {name} = {v:.3g} {unit} lies outside its plausible range "
                         f"[{lo:.3g}, {hi:.3g}] {unit}")
    lines += [f"{effect.label}: {c.line()}" for c in prior_checks(problem, fit) if c.status == "conflict"]
    if problem.modes is not None:
        m = problem.model(fit.beta, effect, fit.s)
        a = problem.modes.agreement(m.config, m.params)
        if not a["agrees"]:
            model_hz = ", ".join(f"{v:.4g}" for v in a["model_hz"] or [])
            lines.append(f"{effect.label}: its modes ({model_hz} Hz) disagree with the measured ones "
                         f"({', '.join(f'{v:.4g}' for v in a['measured_hz'])} Hz): chi2 {a['chi2']:.3g} > "
                         f"{a['chi2_limit']:.3g}")
    return lines


def plausible_verdict(ranking: Ranking, problem: GapProblem, effects: Mapping[str, Effect]) -> Ranking:
    """The ranking's verdict among its plausible refits only; the implausible ones listed
    (:attr:`Ranking.implausible`) and, when the verdict was one of them, named in the reason."""
    issues = {lab: implausibilities(problem, effects[lab], rf.fit) for lab, rf in ranking.refits.items()}
    issues = {lab: v for lab, v in issues.items() if v}
    if not issues:
        return ranking
    before = ranking.heldout_before
    if ranking.verdict not in issues:
        return replace(ranking, implausible=issues)
    refits = {lab: rf for lab, rf in ranking.refits.items() if lab not in issues}
    paying = [lab for lab in ranking.order if lab in refits and refits[lab].delta_bic < -BIC_MARGIN
              and np.mean(refits[lab].heldout_after) < np.mean(before)]
    verdict, ties, reason = verdict_rule(before, refits, paying)
    why = (f"{ranking.verdict} is not named: its refit needs implausible values ({'; '.join(issues[ranking.verdict])})"
           f" — among the plausible candidates: {reason}")
    return replace(ranking, verdict=verdict, indistinguishable=ties, reason=why, implausible=issues)


def confounded(problem: GapProblem, effect: Effect, fit: Fit) -> str | None:
    """Whether ``effect``'s variables are degenerate with the baseline unknowns at its refit ``fit`` (on the time
    records' rows of its Jacobian): the line saying with which combination, or ``None``."""
    p, k = problem.space.dim, effect.dim
    n_extra = (0 if problem.prior is None else problem.prior.count) + (0 if problem.modes is None else
                                                                        problem.modes.count)
    J = np.asarray(fit.jac, dtype=float)
    if J.size == 0 or J.shape[1] != p + k:
        return None
    J = J[:J.shape[0] - n_extra] if n_extra else J
    Jb, Je = J[:, :p], J[:, p:]
    lines = []
    for j in range(k):
        col = Je[:, j]
        norm = float(np.linalg.norm(col))
        if norm == 0.0:
            continue
        coef = np.linalg.lstsq(Jb, col, rcond=None)[0]
        left = float(np.linalg.norm(col - Jb @ coef)) / norm
        if left < CONFOUNDED:
            big = np.abs(coef) >= 0.1 * np.abs(coef).max()
            names = [n for n, b in zip(problem.space.names, big) if b]
            lines.append(f"{effect.variables[j]} is degenerate with {', '.join(names)} (the data leave "
                         f"{left:.1e} of its effect unexplained by them): only a prior on "
                         f"{'them' if len(names) > 1 else 'it'} separates the two")
    return f"{effect.label}: " + "; ".join(lines) if lines else None
