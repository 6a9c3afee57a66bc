"""The measured force's sign as evidence, not as a setting: the baseline fitted to the records as read and with
the force reversed, and the evidence of the two compared (:func:`check_polarity`).

A load cell mounted the other way round, a channel wired with its poles swapped, a convention taken for the other
(push or pull positive): each reverses the measured force, common in real labs.  No continuous refit reaches it —
a gain passing from +1 to −1 goes through a reading of zero —, and with transducer positions among the unknowns a
reversed force can even be half absorbed: moving a sensor across a node of the excited mode also reverses its
reading.  So the diagnosis fits its baseline both ways.  The sign whose baseline has the greater evidence (the
Laplace evidence of :mod:`diagnosis.problem.evidence`: fit, priors and measured modes together) is taken when its odds
reach the decisive odds (:attr:`~diagnosis.settings.Thresholds.decisive_odds`) and the fits' likelihood ratio
does too, the same way (the Occam factors alone do not decide a sign), and — for the force reversed — when the
reversed force removes at least half the misfit the force as read leaves above the noise floor
(:data:`SIGN_REMOVES`).  Otherwise the records are taken as read and the report says that they cannot decide the
sign.  The share matters on records the baseline cannot explain either way: a channel delay or an acquisition
filter left out of the config turns the response's phase near the band's top as a reversed force would (a hint
family's record with its sensors two samples late: 824 noise variances as read, 566 reversed, ln odds +1.8e5 —
31 % of the misfit — was called REVERSED).  Reversing every sensor instead is the same hypothesis
(the outputs change sign with the force); one sensor reversed among several is not tested here.

The baseline's evidence decides the sign only as far as the baseline describes the records.  When no refit brings
the records to the noise floor, the mechanism that explains them may need the other sign (an attachment that moves
a resonance across the excited band turns the response's phase), so the sign is weighed with the mechanisms too
(:func:`diagnosis.search.sign.sign_with_refits`): the candidates are scored and refitted with the other sign as
well, and when a model with the other sign has decisively more evidence than every model with the sign taken, the
sign is overturned and the diagnosis ranks again with it.
"""
from __future__ import annotations

import math
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from ..problem.evidence import laplace_log_evidence
from ..problem.fitting import Fit, GapProblem


__all__ = ["SIGN_REMOVES", "PolarityCheck", "SignWithRefits", "check_polarity", "reversed_force"]

#: The force reversed is taken only when it removes this share of the misfit the force as read leaves above the
#: noise floor (module docstring).  Measured: an undeclared two-sample delay 31 % (a false reversal); the real
#: bench's load cell mounted in compression 83 % (11,841 to 2,003 noise variances); a shaker's armature that turns
#: the phase 80 % (2.9e4 to 5.7e3, its sign then weighed with the refits); a reversed force on a correct model
#: all of it.  Half sits between the false reading and the nearest true one.
SIGN_REMOVES = 0.5


@dataclass(frozen=True)
class SignWithRefits:
    """The sign weighed with the refits: per model (``"none"``: the baseline) its log evidence with the sign taken
    and with the other (``None`` where it was refitted with one sign only); ``overturned`` when a model with the
    other sign is decisively the best."""

    taken_reversed: bool
    log_evidence: dict[str, tuple[float | None, float | None]]      # model -> (sign taken, other sign)
    decisive_odds: float

    def _best(self, k: int) -> tuple[str, float]:
        vals = {lab: v[k] for lab, v in self.log_evidence.items() if v[k] is not None}
        lab = max(vals, key=lambda m: float(vals[m]))      # type: ignore[arg-type]
        return lab, float(vals[lab])                       # type: ignore[arg-type]

    @property
    def log_odds(self) -> float:
        """ln odds of the best model with the other sign against the best with the sign taken."""
        return self._best(1)[1] - self._best(0)[1]

    @property
    def overturned(self) -> bool:
        """Whether the other sign is decisively better once the mechanisms are weighed with it."""
        return self.log_odds >= math.log(self.decisive_odds)

    def line(self) -> str:
        """One sentence."""
        taken = "reversed" if self.taken_reversed else "as read"
        other = "as read" if self.taken_reversed else "reversed"
        if self.overturned:
            return (f"the measured force's sign is OVERTURNED by the mechanisms: the baseline alone preferred the "
                    f"force {taken}, but {self._best(1)[0]} with the force {other} has ln odds {self.log_odds:+.3g} "
                    f"over every model with it {taken} (decisive from {math.log(self.decisive_odds):.2g}); the "
                    f"diagnosis uses the force {other}")
        return (f"the force's sign weighed with the refits ({len(self.log_evidence) - 1} refitted with the force "
                f"{other}): {taken} stays (best with the force {other}: {self._best(1)[0]}, ln odds "
                f"{self.log_odds:+.3g})")

    def to_dict(self) -> dict[str, Any]:
        """JSON values (``gap.json``'s ``force_sign.with_refits``)."""
        return {"log_evidence": {k: {"sign_taken": t, "other_sign": o} for k, (t, o) in self.log_evidence.items()},
                "log_odds_other_sign": self.log_odds, "overturned": self.overturned}


@dataclass(frozen=True)
class PolarityCheck:
    """The baseline's fit and evidence with the force as read and reversed, and the sign taken."""

    log_evidence: dict[str, float]
    gap: dict[str, float]
    reversed: bool
    decided: bool
    #: the odds from which the evidence decides (:attr:`~diagnosis.settings.Thresholds.decisive_odds`)
    decisive_odds: float
    #: the other sign's baseline unknowns (where its refits start), not written
    other_beta: np.ndarray | None = field(default=None, repr=False, compare=False)
    #: the sign weighed with the refits (:func:`diagnosis.search.sign.sign_with_refits`), when it was
    with_refits: SignWithRefits | None = None
    #: the share of the misfit above the noise floor that the force reversed removes from the force as read's
    removed: float = 0.0

    @property
    def overturned(self) -> bool:
        """Whether the refits overturned the baseline's sign (:attr:`with_refits`)."""
        return self.with_refits is not None and self.with_refits.overturned

    @property
    def log_odds(self) -> float:
        """ln of the odds of the reversed force against the force as read."""
        return self.log_evidence["reversed"] - self.log_evidence["as_read"]

    def line(self) -> str:
        """One sentence."""
        if self.with_refits is not None and self.with_refits.overturned:
            return self.with_refits.line()
        both = (f"baseline fit {self.gap['as_read']:.3g} (as read) and {self.gap['reversed']:.3g} (reversed) "
                f"times the noise variance, ln odds {self.log_odds:+.3g}")
        if not self.decided and self.log_odds >= math.log(self.decisive_odds) and self.removed < SIGN_REMOVES:
            return (f"the force reversed fits the records better but leaves most of the misfit ({both}: it removes "
                    f"{100 * max(self.removed, 0.0):.0f} %, a reversed force {100 * SIGN_REMOVES:.0f} % or more) — "
                    "the records do not read as a reversed force (a channel's delay or filter, or an effect near a "
                    "resonance, also turns the response's phase): taken as read")
        if not self.decided:
            return (f"the records cannot decide the measured force's sign ({both}; decisive from "
                    f"{math.log(self.decisive_odds):.2g}): taken as read")
        if self.reversed:
            return (f"the measured force's sign is REVERSED: the baseline explains the records far better with the "
                    f"force reversed ({both}); the diagnosis uses the reversed force — check the load cell's "
                    f"mounting and wiring, or read it with a gain of -1")
        return f"the measured force's sign is as read ({both})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        out = {"log_evidence": dict(self.log_evidence), "fit_gap_ratio": dict(self.gap),
               "reversed": self.reversed, "decided": self.decided, "log_odds_reversed": self.log_odds,
               "share_removed_reversed": self.removed}
        if self.with_refits is not None:
            out["with_refits"] = self.with_refits.to_dict()
        return out


def reversed_force(problem: GapProblem) -> GapProblem:
    """``problem`` with every record's force reversed (no other basins, no rival: they belong to the other sign)."""
    return replace(problem, records=tuple(replace(r, inputs=-r.inputs) for r in problem.records), other_starts=(),
                   rival=None)


def check_polarity(problem: GapProblem, fit_baseline: Callable[[GapProblem], tuple[GapProblem, Fit]],
                   executor: Executor | None = None, *, take: bool | None = None,
                   noise: Callable[[GapProblem, Fit], GapProblem] | None = None
                   ) -> tuple[GapProblem, Fit, PolarityCheck]:
    """The problem and baseline fit with the sign the evidence takes (module docstring), and the check.

    ``fit_baseline`` fits a problem's baseline (``(problem with its other basins, fit)``), the same way for both
    signs; with an ``executor`` the reversed one runs on it while this process fits the records as read
    (``fit_baseline`` must then pickle: a module-level function or a partial of one).  ``take`` (``True``:
    reversed) takes that sign whatever the baselines say — the sign the refits decided
    (:func:`diagnosis.search.sign.sign_with_refits`).  ``noise`` (a problem under the noise model of a fit's
    residual, :func:`diagnosis.baseline.noise.noise_of`): the sign is weighed under the noise as it is in the
    records, not under the first estimate the fits started from (measured on a hint record: that estimate 5.5
    times the noise model's standard deviation, and the line quoted 0.032 noise variances for a baseline the
    report put at 0.99) — the noise model from the better sign's residual, both signs refitted under it from
    their better fits, the sign taken's baseline too (the report starts from it).
    """
    flipped = reversed_force(problem)
    pending = executor.submit(fit_baseline, flipped) if executor is not None else None
    problem, baseline = fit_baseline(problem)
    flipped, flipped_fit = pending.result() if pending is not None else fit_baseline(flipped)
    # each sign by its better fit, from the start given or from the records' own (measured: a withheld tip mass
    # called the force REVERSED from the start given, where the records' start fitted the force as read best)
    best, best_flipped = _best(problem, baseline), _best(flipped, flipped_fit)
    if noise is not None:
        (problem, baseline, best), (flipped, flipped_fit, best_flipped) = _under_the_noise(
            noise, executor, (problem, baseline, best), (flipped, flipped_fit, best_flipped))
    logz = {"as_read": laplace_log_evidence(problem, best), "reversed": laplace_log_evidence(flipped, best_flipped)}
    gap = {"as_read": float(best.rss / best.n), "reversed": float(best_flipped.rss / best_flipped.n)}
    log_odds = logz["reversed"] - logz["as_read"]
    # the fits themselves must carry the decision: the likelihood ratio as decisive as the evidence, the same way
    # (the evidence's Occam factors alone once called a force REVERSED at 1.31 noise variances both ways)
    log_ratio = 0.5 * (best.rss - best_flipped.rss)
    decisive = math.log(problem.settings.decisive_odds)
    decided = abs(log_odds) >= decisive and abs(log_ratio) >= decisive and (log_odds > 0) == (log_ratio > 0)
    # the force reversed is a claim only when it explains most of what the force as read leaves (module docstring)
    over = gap["as_read"] - 1.0
    removed = (gap["as_read"] - gap["reversed"]) / over if over > 0.0 else 0.0
    decided = decided and (log_odds < 0 or removed >= SIGN_REMOVES)
    rev = decided and log_odds > 0 if take is None else take
    check = PolarityCheck(logz, gap, rev, decided or take is not None, problem.settings.decisive_odds,
                          other_beta=best.beta if rev else best_flipped.beta, removed=removed)
    if rev:
        return flipped, flipped_fit, check
    return problem, baseline, check


#: a sign's problem, its baseline and its better fit (the baseline or the problem's rival)
_Side = tuple[GapProblem, Fit, Fit]


def _under_the_noise(noise: Callable[[GapProblem, Fit], GapProblem], executor: Executor | None, as_read: _Side,
                     flipped: _Side) -> tuple[_Side, _Side]:
    """Both signs under the noise model of the better one's residual (``noise``), each refitted from its
    baseline and its better fit (the reversed one on ``executor`` when there is one)."""
    better = as_read if as_read[2].rss <= flipped[2].rss else flipped
    model = noise(better[0], better[2]).noise_model
    a, f = as_read[0].with_noise(model), flipped[0].with_noise(model)
    pending = executor.submit(_refitted, f, flipped[1], flipped[2]) if executor is not None else None
    a_fits = _refitted(a, as_read[1], as_read[2])
    f_fits = pending.result() if pending is not None else _refitted(f, flipped[1], flipped[2])
    return (a, *a_fits), (f, *f_fits)


def _refitted(problem: GapProblem, baseline: Fit, best: Fit) -> tuple[Fit, Fit]:
    """``baseline`` refitted under ``problem``'s noise model, and the sign's better fit: that refit, or ``best``
    (the problem's rival) refitted when it is the better."""
    again = problem.fit(baseline.beta)
    if best is baseline:
        return again, again
    other = problem.fit(best.beta)
    return again, (other if other.rss < again.rss else again)


def _best(problem: GapProblem, fit: Fit) -> Fit:
    """``fit`` or the problem's fit from the records' own start (:attr:`GapProblem.rival`), the better."""
    rival = problem.rival
    return rival if rival is not None and rival.rss < fit.rss else fit
