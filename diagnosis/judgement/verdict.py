"""The verdict as a value, and the naming rule that makes the first one from the refits alone (no simulation).

A :class:`Verdict` is a kind (:class:`Kind`), the named effect's label when it names one, the candidates the data
cannot tell from it (its ties), and the reasons for it as values (:class:`Reason`: which rule said what).  The
rules of :mod:`diagnosis.judgement.rules` each take one and return one; its text is rendered once, from the
reasons (:meth:`Verdict.text`).  :func:`name_cause` is the first rule's decision (the search uses it too, to know
when a ranking is settled); :func:`by_evidence` decides between tied candidates by their posterior odds.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from enum import Enum
from typing import Any, Mapping, Sequence

import numpy as np

from ..effects import PAIR_SEPARATOR
from ..problem.ties import tie_ordered
from ..search.refits import EffectRefit
from ..settings import Thresholds

__all__ = ["Kind", "Reason", "Verdict", "by_evidence", "name_cause", "settled"]


class Kind(Enum):
    """What a verdict says: no gap, an effect named, a gap no candidate explains, candidates the evidence cannot
    separate, or the model's own discretisation error."""

    NONE = "none"
    EFFECT = "effect"
    UNEXPLAINED = "unexplained"
    INDISTINGUISHABLE = "indistinguishable"
    GRID = "grid"


@dataclass(frozen=True)
class Reason:
    """One reason for a verdict: the rule that gave it (:data:`diagnosis.judgement.rules.RULES`) and what it says."""

    rule: str
    text: str


@dataclass(frozen=True)
class Verdict:
    """A verdict: its kind, the named effect (``label``, for :attr:`Kind.EFFECT` only), the candidates the data
    cannot tell from it (``ties``; for :attr:`Kind.INDISTINGUISHABLE` the candidates, the most probable first) and
    the reasons, in the order the rules gave them."""

    kind: Kind
    label: str | None = None
    ties: tuple[str, ...] = ()
    reasons: tuple[Reason, ...] = ()

    def __post_init__(self) -> None:
        if (self.kind is Kind.EFFECT) != (self.label is not None):
            raise ValueError(f"a verdict of kind {self.kind.value} {'needs' if self.label is None else 'has no'} "
                             f"an effect's label")

    @property
    def name(self) -> str:
        """What ``gap.json`` calls it: the effect's label, or the kind (``none``, ``unexplained``,
        ``indistinguishable``, ``grid``)."""
        return self.label if self.label is not None else self.kind.value

    def text(self) -> str:
        """The reasons in words, in order (the verdict's ``reason`` in ``gap.json`` and on the console)."""
        return "; ".join(r.text for r in self.reasons)

    def said(self, rule: str, text: str) -> Verdict:
        """This verdict with one more reason."""
        return replace(self, reasons=(*self.reasons, Reason(rule, text)))

    def to_dict(self) -> dict[str, Any]:
        """The verdict as JSON values (``gap.json``'s ``judgement``)."""
        return {"kind": self.kind.value, "label": self.label, "ties": list(self.ties),
                "reasons": [{"rule": r.rule, "text": r.text} for r in self.reasons]}


def named(label: str, ties: Sequence[str] = (), reasons: Sequence[Reason] = ()) -> Verdict:
    """A verdict naming ``label`` (an effect or a pair of effects)."""
    return Verdict(Kind.EFFECT, label, tuple(ties), tuple(reasons))


def _insignificant_part(label: str, refits: Mapping[str, EffectRefit], bic_margin: float) -> bool:
    """Whether ``label`` is a pair one of whose effects does not pay for itself: the pair's BIC is within
    ``bic_margin`` of the other effect refitted alone (a Kelvin–Voigt record "explained" by Kelvin–Voigt plus
    a 26 mg mass)."""
    if PAIR_SEPARATOR not in label:
        return False
    pair = refits[label]
    return any(part in refits and pair.delta_bic > refits[part].delta_bic - bic_margin
               for part in label.split(PAIR_SEPARATOR))


def name_cause(before: np.ndarray, refits: Mapping[str, EffectRefit], paying: Sequence[str], settings: Thresholds,
               *, rule: str = "naming") -> Verdict:
    """The verdict from the refits alone (no simulation).

    Parameters
    ----------
    before
        Held-out gap ratio per sensor of the baseline (1 = noise floor).
    refits
        The refits by label (their held-out gap ratio after, closure and ΔBIC are used).
    paying
        Labels of the refits that pay for themselves (:func:`paying_refits`), best first; a pair, when one was
        refitted and pays, first (dropped when one of its effects does not pay for itself against the other
        refitted alone).
    settings
        The thresholds (:class:`~diagnosis.settings.Thresholds`: ``gap_threshold``, ``bic_margin``,
        ``named_closure``, ``tie_gain``, ``tie_excess``).
    rule
        The rule the reasons are credited to.

    Returns
    -------
    Verdict
        :attr:`Kind.NONE` when the gap is within ``gap_threshold`` of the noise floor; :attr:`Kind.UNEXPLAINED`
        when no refit pays or the best closes less than ``named_closure`` of the gap; else the best named, with
        the single effects that close nearly as much (``tie_gain`` of its gain) and leave no measurably larger
        remainder as its ties.
    """
    paying = [lab for lab in paying if not _insignificant_part(lab, refits, settings.bic_margin)]
    excess = float(np.mean(before)) - 1.0
    if excess < settings.gap_threshold:
        return Verdict(Kind.NONE, reasons=(Reason(rule, (
            f"the held-out residual variance is {excess + 1:.3g}× the noise variance, within "
            f"{settings.gap_threshold:.0%} of the noise floor: nothing to explain")),))
    if not paying:
        return Verdict(Kind.UNEXPLAINED, reasons=(Reason(rule, (
            f"not in the catalogue: the held-out residual variance is {excess + 1:.3g}× the noise variance, but no "
            f"candidate effect improves BIC by more than {settings.bic_margin:g} and the held-out error")),))
    best = refits[paying[0]]
    if not best.closed >= settings.named_closure:
        return Verdict(Kind.UNEXPLAINED, reasons=(Reason(rule, (
            f"not in the catalogue: the held-out residual variance is {excess + 1:.3g}× the noise variance and the "
            f"best candidate, {paying[0]}, closes only {best.closed:.0%} of the gap (an effect is named from "
            f"{settings.named_closure:.0%})")),))
    gain = float(np.mean(before) - np.mean(best.heldout_after))
    # a pair's own parts are not its rivals (the pair has paid for its second effect against the first); another
    # pair is (the pairs of near-equal rivals: a spring or a foundation, each with a lag), a pair never a single's
    parts = set(paying[0].split(PAIR_SEPARATOR))
    pair_named = PAIR_SEPARATOR in paying[0]
    # a rival ties when it closes nearly as much and what it leaves is not measurably more (a rival leaving
    # 349 noise variances where the best leaves 1.1 is decided, even though both close 97-100 %)
    left = float(np.mean(best.heldout_after))
    ties = [lab for lab in paying[1:] if (pair_named or PAIR_SEPARATOR not in lab) and lab not in parts
            and float(np.mean(before) - np.mean(refits[lab].heldout_after)) >= settings.tie_gain * gain
            and float(np.mean(refits[lab].heldout_after)) - left
            <= max(settings.gap_threshold, settings.tie_excess * (left - 1.0))]
    reasons = [Reason(rule, f"{paying[0]} closes {best.closed:.0%} of the held-out gap "
                            f"(gap ratio {np.mean(before):.3g} -> {np.mean(best.heldout_after):.3g}, "
                            f"dBIC {best.delta_bic:.1f})")]
    if left - 1.0 > settings.gap_threshold:
        # a share of the gap, not all of it: the dominant cause, named as such, and the remainder said
        reasons.append(Reason(rule, f"it explains the dominant part only: {left:.3g}x the noise variance remains, "
                                    f"which no candidate of the catalogue explains"))
    if ties:
        reasons.append(Reason(rule, "the held-out records alone do not tell it from " + ", ".join(ties)
                              + " (each closes nearly as much and leaves no measurably more)"))
    return named(paying[0], ties, reasons)


def by_evidence(verdict: Verdict, probabilities: Mapping[str, float], decisive_odds: float,
                *, remains: float | None = None, rule: str = "evidence and ties") -> Verdict:
    """Between a named ``verdict`` and its ties (candidates whose refits explain the records as well), the
    evidence decides.

    The most probable of them (posterior ``probabilities``, :mod:`diagnosis.problem.evidence`) is named, with
    the sentence after the verdict's reasons, when its odds against the next reach ``decisive_odds``
    (:attr:`~diagnosis.settings.Thresholds.decisive_odds`); otherwise the verdict is
    :attr:`Kind.INDISTINGUISHABLE` with the candidates the evidence does not put decisively below the most
    probable, the most probable first, as its ties and the sentence
    before its reasons (an actuator's lag and a sensor's lag on a record with one force and one sensor: the two
    commute, and no record of that pair can tell them apart).

    ``remains``: the held-out gap ratio the named candidate leaves when it is above the noise floor (``None`` at
    the floor).  The Laplace evidence is a posterior probability only among candidates one of which describes the
    records; when the best leaves a gap, every candidate misses part of them and the same numbers only rank their
    fits — the sentence then says so and quotes no probability (measured: "posterior probability 1, odds inf" was
    printed beside 161 noise variances left).
    """
    # exact ties (one model under two names: their probabilities apart by round-off) by the tie rule, not the rounding
    candidates = tie_ordered([verdict.name, *verdict.ties], lambda lab: -probabilities.get(lab, 0.0),
                             rtol=EVIDENCE_TIE_RTOL)
    p = [probabilities.get(lab, 0.0) for lab in candidates]
    odds = p[0] / p[1] if p[1] > 0.0 else float("inf")
    ratio = f"{odds:.3g}" if odds < _LARGEST_RATIO else f"above {_LARGEST_RATIO:.0e}"
    if odds >= decisive_odds:
        if remains is not None:
            return named(candidates[0], (), verdict.reasons).said(rule, (
                f"their fits decide between them: {candidates[0]} over {candidates[1]} (evidence ratio {ratio}; "
                f"not a posterior probability: the best leaves {remains:.3g}x the noise variance, so each "
                "candidate misses part of the records)"))
        return named(candidates[0], (), verdict.reasons).said(rule, (
            f"the evidence decides between them: {candidates[0]} (posterior probability {p[0]:.3g}) over "
            f"{candidates[1]} ({p[1]:.2g}), odds {ratio}"))
    # a tie the evidence puts decisively below the most probable is no rival of it (a delay beside two lags that
    # commute: ln odds 30 against either)
    kept = [k for k, v in enumerate(p) if v > 0.0 and p[0] < decisive_odds * v]
    candidates, p = [candidates[k] for k in kept], [p[k] for k in kept]
    listed = ("" if remains is not None else
              "posterior probabilities " + ", ".join(f"{lab} {v:.2g}" for lab, v in zip(candidates, p)) + "; ")
    sentence = Reason(rule, (
        f"{' and '.join(candidates)} explain the records equally well and the evidence cannot separate them "
        f"({listed}{'evidence ratio' if remains is not None else 'odds'} {ratio} < {decisive_odds:g}): records "
        "that see their difference (another sensor or drive point) or a prior on one of them would; none is "
        "exported"))
    return Verdict(Kind.INDISTINGUISHABLE, None, tuple(candidates), (sentence, *verdict.reasons))


#: Posterior probabilities within this relative difference (ln odds below it) are one model's: two equivalent
#: refits' log evidences (thousands, sums over every sample) differ by their rounding, 1e-12 of them — measured
#: ln odds 3.5e-10 and 4.2e-9 for the two commuting lags of ``tests/test_evidence.py`` in two processes; a record
#: tells models apart only from ln odds of order 1 (:attr:`~diagnosis.settings.Thresholds.decisive_odds`).
EVIDENCE_TIE_RTOL = 1e-6

#: Evidence ratios from here up are printed as a bound (the probabilities behind them underflow to 0).
_LARGEST_RATIO = 1e300


def settled(ranking: Any, settings: Thresholds) -> bool:
    """Whether the effect the naming rule names (:func:`name_cause`) for ``ranking`` (a
    :class:`~diagnosis.search.rank.Ranking`) has a refit that leaves at most the gap threshold above the noise
    floor on the fit windows: then a better baseline basin cannot change the verdict (another effect could at most
    tie), and the ranking is final.  The search asks it through the callable it is given
    (:func:`~diagnosis.search.rank.rank_effects`' ``settled``): the stages point one way."""
    verdict = name_cause(ranking.heldout_before, ranking.refits, ranking.paying, settings)
    if verdict.kind is not Kind.EFFECT or verdict.label not in ranking.refits:
        return False
    fit = ranking.refits[verdict.label].fit
    return fit.rss / fit.n - 1.0 <= settings.gap_threshold
