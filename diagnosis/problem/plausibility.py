"""Whether a refit explains the data with values a physicist would sign: the effect's parameters inside their
plausible ranges (:attr:`diagnosis.effects.Effect.plausible`), the baseline unknowns consistent with the user's
priors (:mod:`identification.prior`, within :data:`identification.prior.CONFLICT_SIGMA` prior standard
deviations), and its modes consistent with the measured ones when the config gives them
(:mod:`identification.modal_data`).

A flexible wrong effect with compensating parameters can close most of a large gap — a "point mass" of 2.7 kg,
three times the beam, on the accelerometer of a real bench, with the beam's density pushed to its bound.  Such a
refit is not named as the cause (the plausibility rule, :func:`diagnosis.judgement.rules.plausibility`): the
verdict goes to the best plausible candidate that meets the naming rule, or is ``unexplained``, and the report says
what the implausible one needed.  Nothing implausible is exported as the corrected model.  This module measures;
the rule decides.
"""
from __future__ import annotations

import numpy as np

from identification.prior import PriorCheck

from ..effects import Effect
from .fitting import Fit, GapProblem

__all__ = ["confounded", "implausibilities", "posterior_std", "prior_checks"]

#: The baseline unknowns a degeneracy names: those whose coefficient in the effect's column is at least this share
#: of the largest (a wording choice for the sentence, not a decision: whether the effect is degenerate is
#: ``Thresholds.confounded``'s).
NAMED_SHARE = 0.1


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
        m = problem.modes_model(fit.beta, effect, fit.s)
        a = problem.modes.agreement(m.config, m.params)
        if not a["agrees"]:
            model_hz = ", ".join(f"{v:.4g}" for v in a["model_hz"] or [])
            lines.append(f"{effect.label}: its modes ({model_hz} Hz) disagree with the measured ones "
                         f"({', '.join(f'{v:.4g}' for v in a['measured_hz'])} Hz): chi2 {a['chi2']:.3g} > "
                         f"{a['chi2_limit']:.3g}")
    return lines


def _central_jacobian(problem: GapProblem, effect: Effect, z: np.ndarray, *, step: float = 1e-4) -> np.ndarray:
    """Central-difference Jacobian of the time records' whitened residuals w.r.t. the baseline unknowns and
    ``effect``'s variables ``z`` in the unit box (the fits' own forward-difference Jacobians are a few per cent
    off in a lightly damped record's damping — too coarse to tell a degeneracy from a near one)."""
    box = problem.box(effect)
    u = box.to_unit(z)
    p = problem.space.dim
    n = problem.n_fit - (0 if problem.prior is None else problem.prior.count) \
        - (0 if problem.modes is None else problem.modes.count)
    cols = []
    for j in range(u.size):
        h = np.zeros(u.size)
        h[j] = step
        lo, hi = np.clip(u - h, 0.0, 1.0), np.clip(u + h, 0.0, 1.0)
        rp, rm = (problem.residuals(x[:p], effect, x[p:]) for x in (box.from_unit(hi), box.from_unit(lo)))
        cols.append((rp[:n] - rm[:n]) / (hi[j] - lo[j]))
    return np.column_stack(cols)


def confounded(problem: GapProblem, effect: Effect, fit: Fit, *, at_baseline: bool = False) -> str | None:
    """Whether ``effect``'s variables are degenerate with the baseline unknowns (on the time records' residuals):
    the line saying with which combination, or ``None``.  ``fit`` is the effect's refit, or with ``at_baseline``
    the baseline fit (the effect then at its "off" value)."""
    p = problem.space.dim
    s = np.asarray(effect.off if at_baseline else fit.s, dtype=float)
    J = _central_jacobian(problem, effect, np.concatenate([np.asarray(fit.beta, dtype=float), s]))
    Jb, Je = J[:, :p], J[:, p:]
    lines = []
    for j in range(effect.dim):
        col = Je[:, j]
        norm = float(np.linalg.norm(col))
        if norm == 0.0:
            continue
        coef = np.linalg.lstsq(Jb, col, rcond=None)[0]
        left = float(np.linalg.norm(col - Jb @ coef)) / norm
        if left < problem.settings.confounded:
            big = np.abs(coef) >= NAMED_SHARE * np.abs(coef).max()
            names = [n for n, b in zip(problem.space.names, big) if b]
            lines.append(f"{effect.variables[j]} is degenerate with {', '.join(names)} (the data leave "
                         f"{left:.1e} of its effect unexplained by them): only a prior on "
                         f"{'them' if len(names) > 1 else 'it'} separates the two")
    return f"{effect.label}: " + "; ".join(lines) if lines else None
