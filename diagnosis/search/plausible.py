"""Readings held within plausibility: when every refit that closes the records' gap needs implausible values, each
is fitted again with the plausibility limits as constraints (:func:`plausible_readings`).

The likelihood the refits maximise treats the records' misfit as noise.  When no candidate reaches the noise floor
the misfit is model error, thousands of noise variances of it, and in that likelihood a few per cent less misfit
outweighs any prior and any measured mode: a refit trades the strip's documented size and the hammer test's
frequencies for a small gain on the records (a chain gain of 0.15 with the beam's modes 21 % low, where a gain of
0.32 with the documented beam predicts the held-out part about as well).  Once no candidate explains the records
as noise, the question a physicist asks is another one: *which candidates predict the records with values I would
sign, and how well?*  So each refit that closes the named share of the gap but is implausible is refitted inside
the limits the plausibility checks (:mod:`diagnosis.problem.plausibility`) apply — each prior within
:data:`~identification.prior.CONFLICT_SIGMA` σ, the priors jointly at the same tail probability, the measured
modes' χ² below its 99.9 % point, the effect's parameters inside their plausible ranges — each limit a hinge row
that is zero inside it and steep outside (at :data:`MARGIN` of the limit, so that the fit lands inside).  A reading
is kept when the refit so held passes every plausibility check and still closes the named share of the held-out
gap; the readings are listed with their held-out prediction and their posterior probabilities (Laplace evidence
among them, :mod:`diagnosis.problem.evidence`).  They are readings, not a verdict: the report says the records
alone do not decide between them and that the probabilities still weigh the misfit as noise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from concurrent.futures import Executor
from typing import Any

import numpy as np
from scipy import stats

from identification.least_squares import fit_least_squares
from identification.prior import CONFLICT_SIGMA

from ..effects import Catalogue, Effect
from ..problem.evidence import laplace_log_evidence
from ..problem.plausibility import implausibilities
from ..problem.fitting import Fit, GapProblem
from .rank import Ranking
from .refits import EffectRefit, summarise
from .workers import side_by_side

__all__ = ["HELD_EVALUATIONS", "MARGIN", "PlausibleReading", "held_start", "held_within", "plausible_readings",
           "readings_text"]

#: Each hinge starts at this share of its limit, so that the constrained optimum lies inside the limit itself.
MARGIN = 0.95
#: ``least_squares``' evaluations of a held refit (its Jacobian's on top): on the real ARTS record the gain's held
#: refit ends within 0.5 % of the misfit it reaches with five times as many.
HELD_EVALUATIONS = 60
#: Weight of a hinge row per unit of excess (σ of a prior, √χ² of the modes, a plausible range's width), in units
#: of the refit's root sum of squares: one unit beyond a limit costs a hundred times the whole misfit.
STEEPNESS = 10.0


@dataclass(frozen=True)
class PlausibleReading:
    """A candidate refitted inside the plausibility limits: the set-up reading it belongs to, its refit (held-out
    gap, closure, parameters) and its posterior probability among the readings."""

    label: str
    effect: Effect = field(repr=False, compare=False)
    reading: str                     # "one set-up" or the set-ups apart's description
    refit: EffectRefit
    nrmse: float                     # held-out NRMSE (residual RMS over the record's RMS), all sensors
    modes_chi2: float | None
    probability: float

    @property
    def heldout_gap(self) -> float:
        """The held-out gap ratio over every sensor (1 = the noise floor)."""
        return float(np.mean(self.refit.heldout_after))

    def line(self) -> str:
        """One line: the reading, its values, its held-out prediction and probability."""
        values = ", ".join(f"{k}={v:.4g}" for k, v in self.refit.physical.items())
        modes = "" if self.modes_chi2 is None else f", modes chi2 {self.modes_chi2:.3g}"
        return (f"{self.label} ({self.reading}): {values}; held-out gap {self.heldout_gap:.3g} "
                f"noise variances (NRMSE {self.nrmse:.1%}, {self.refit.closed:.0%} closed){modes}; "
                f"probability {self.probability:.2g}")

    def to_dict(self) -> dict[str, Any]:
        """JSON values (an entry of ``gap.json``'s ``plausible_readings``)."""
        return {"effect": self.label, "reading": self.reading, "parameters": dict(self.refit.physical),
                "baseline_unknowns": [float(v) for v in self.refit.fit.beta],
                "heldout_gap_ratio": [float(v) for v in self.refit.heldout_after],
                "heldout_nrmse": self.nrmse, "closed": self.refit.closed, "modes_chi2": self.modes_chi2,
                "probability": self.probability}


def _excess(problem: GapProblem, effect: Effect, z: np.ndarray, r: np.ndarray) -> np.ndarray:
    """How far ``z`` lies beyond each plausibility limit (at :data:`MARGIN` of it), in σ, √χ² or range widths;
    zero inside.  ``r`` are the problem's residuals at ``z`` (records, then modes, then priors)."""
    p = problem.space.dim
    n_modes = 0 if problem.modes is None else problem.modes.count
    n_prior = 0 if problem.prior is None else problem.prior.count
    n_records = r.size - n_modes - n_prior
    out = []
    if problem.modes is not None:
        limit = math.sqrt(problem.modes.chi2_limit)
        out.append(max(0.0, float(np.linalg.norm(r[n_records:n_records + n_modes])) - MARGIN * limit))
    if n_prior:
        prior = problem.prior
        assert prior is not None
        tail = 2.0 * float(stats.norm.sf(CONFLICT_SIGMA))
        joint = math.sqrt(float(stats.chi2.isf(tail, n_prior)))
        out.append(max(0.0, float(np.linalg.norm(r[n_records + n_modes:])) - MARGIN * joint))
        g = prior.given
        zscore = np.abs(z[:p][g] - prior.mean[g]) / prior.std[g]
        out += [max(0.0, float(v) - MARGIN * CONFLICT_SIGMA) for v in zscore]
    values = effect.physical(z[p:])
    for name, (lo, hi) in effect.plausible.items():
        # each limit moved inwards by the margin's share of itself (a bound at zero, an effect's "off", stays)
        width = max(hi - lo, 1e-300)
        top = hi * MARGIN if hi > 0 else hi / MARGIN
        bottom = lo / MARGIN if lo > 0 else lo * MARGIN
        out.append(max(0.0, (values[name] - top) / width, (bottom - values[name]) / width))
    return np.nan_to_num(np.asarray(out, dtype=float), nan=1e6, posinf=1e6)


def held_within(problem: GapProblem, effect: Effect, fit: Fit, start: np.ndarray, *, max_evaluations: int) -> Fit:
    """The refit of ``effect`` inside the plausibility limits from ``start`` (the baseline unknowns and the
    effect's variables stacked); the returned fit's residuals and Jacobian are the problem's own (the hinge rows
    dropped)."""
    p, n = problem.space.dim, problem.n_fit
    weight = STEEPNESS * math.sqrt(max(float(fit.rss), 1.0))

    def rows(z: np.ndarray) -> np.ndarray:
        r = problem.residuals(z[:p], effect, z[p:])
        return np.concatenate([r, weight * _excess(problem, effect, z, r)])

    local = fit_least_squares(lambda Z: np.array([rows(z) for z in Z]), start, problem.box(effect),
                              max_evaluations=max_evaluations)
    r = np.asarray(local.residuals[:n], dtype=float)
    return Fit(local.x[:p], local.x[p:], float(r @ r), int(n), np.asarray(local.jac)[:n], r, local.n_evaluations)


def held_start(problem: GapProblem, effect: Effect, fit: Fit) -> np.ndarray:
    """Where a held refit starts: the refit's optimum with the unknowns that have a prior at its mean (the
    measurement chain's scale moved along the data's flat valley first, :attr:`Effect.rescale`) — the implausible
    optimum itself lies across the limits, a start at the priors' centre inside them; without priors, the
    refit's optimum."""
    prior = problem.prior
    if prior is None or not prior.count:
        return np.concatenate([fit.beta, fit.s])
    beta, s = np.array(fit.beta, dtype=float), np.array(fit.s, dtype=float)
    if effect.rescale is not None:
        moved = effect.rescale(problem.space.names, beta, s, prior)
        if moved is not None:
            beta, s = np.asarray(moved[0], dtype=float), np.asarray(moved[1], dtype=float)
    g = prior.given
    beta[g] = prior.mean[g]
    box = problem.box(effect)
    return np.clip(np.concatenate([beta, s]), box.lower, box.upper)


def _task(problem: GapProblem, catalogue: Catalogue, label: str, fit: Fit, max_evaluations: int) -> Fit:
    """One held refit, in this or a worker process (the effect looked up there: effects do not pickle)."""
    effect = catalogue.effect(label)
    return held_within(problem, effect, fit, held_start(problem, effect, fit), max_evaluations=max_evaluations)


def _nrmse(problem: GapProblem, refit: EffectRefit) -> float:
    """Held-out residual RMS over the records' held-out RMS, all sensors (in the noise's units: the gap ratio
    times the noise variance against the record's own mean square)."""
    sigma2 = np.asarray(problem.noise_std, dtype=float) ** 2
    held = [r.outputs[r.hold_start:] for r in problem.records if r.has_holdout]
    if not held:
        return float("nan")
    power = np.mean(np.concatenate(held) ** 2, axis=0)
    return float(math.sqrt(np.sum(np.asarray(refit.heldout_after) * sigma2) / np.sum(power)))


def candidates_to_hold(problem: GapProblem, ranking: Ranking, implausible: dict[str, list[str]]) -> list[str]:
    """The refits that close the named share of the held-out gap but need implausible values."""
    return [lab for lab, rf in ranking.refits.items()
            if rf.closed >= problem.settings.named_closure and lab in implausible]


def plausible_readings(readings: list[tuple[str, GapProblem, Ranking, dict[str, list[str]]]], catalogue: Catalogue,
                       *, executor: Executor | None = None, max_evaluations: int = HELD_EVALUATIONS
                       ) -> list[PlausibleReading]:
    """The plausible readings of the records: for each ``(name, problem, ranking, implausible)`` — a set-up
    reading, its ranking and what is implausible about its refits — every refit that closes the named share but is
    implausible, refitted inside the plausibility limits (once: a later reading refits only the effects of the rig
    parts it takes away); kept when it then passes every check and still closes the named share.  Most probable
    first (Laplace evidence across every reading kept)."""
    jobs, queued = [], set()
    for name, problem, ranking, implausible in readings:
        for lab in candidates_to_hold(problem, ranking, implausible):
            # an effect that models no rig part the reading takes away is the same model in every reading
            if lab in queued and ranking.effects[lab].rig_part not in problem.modes_lack:
                continue
            queued.add(lab)
            jobs.append((name, problem, ranking, lab))
    fits = side_by_side(executor, _task, [(problem, catalogue, lab, ranking.refits[lab].fit, max_evaluations)
                                          for _, problem, ranking, lab in jobs])
    kept = []
    for (name, problem, ranking, lab), fit in zip(jobs, fits):
        effect = ranking.effects[lab]
        if implausibilities(problem, effect, fit):
            continue
        refit = summarise(problem, ranking.baseline, ranking.heldout_before, effect, fit)
        if not refit.closed >= problem.settings.named_closure:
            continue
        chi2 = None
        if problem.modes is not None:
            m = problem.modes_model(fit.beta, effect, fit.s)
            chi2 = float(problem.modes.agreement(m.config, m.params)["chi2"])
        kept.append((PlausibleReading(lab, effect, name, refit, _nrmse(problem, refit), chi2, 0.0),
                     laplace_log_evidence(problem, fit)))
    if not kept:
        return []
    top = max(v for _, v in kept)
    w = [math.exp(v - top) for _, v in kept]
    total = sum(w)
    out = [replace(reading, probability=wi / total) for (reading, _), wi in zip(kept, w)]
    return sorted(out, key=lambda r: -r.probability)


def readings_text(readings: list[PlausibleReading]) -> str:
    """The verdict's reason: what the records allow once every refit is held within plausibility."""
    listed = "; ".join(r.line() for r in readings)
    return (f"no effect is named, but held within plausibility (the priors, the measured modes and the effects' "
            f"ranges as limits) the records allow {len(readings)} reading(s): {listed} — readings, not a verdict: "
            f"the probabilities still weigh the records' misfit as noise")
