"""The verdict rule of the diagnosis: which refitted effect, if any, is named — from the refits' held-out gap, BIC
and closure alone, no simulation (:func:`verdict_rule`; :mod:`diagnosis.search.rank` produces the refits).
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..effects import PAIR_SEPARATOR
from ..search.refits import EffectRefit
from ..settings import Thresholds

__all__ = ["INDISTINGUISHABLE", "UNEXPLAINED", "by_evidence", "paying_refits", "verdict_rule"]

#: The verdict when there is a gap that no effect of the catalogue explains.
UNEXPLAINED = "unexplained"
#: The verdict when several candidates explain the records equally well and their evidence does not separate them.
INDISTINGUISHABLE = "indistinguishable"


def paying_refits(refits: Mapping[str, EffectRefit], before: np.ndarray, settings: Thresholds) -> list[str]:
    """The effects whose refit pays for its parameters (BIC by ``settings.bic_margin``) and lowers the held-out
    error, the lowest held-out error first."""
    paying = [lab for lab, rf in refits.items()
              if rf.delta_bic < -settings.bic_margin and np.mean(rf.heldout_after) < np.mean(before)]
    return sorted(paying, key=lambda lab: float(np.mean(refits[lab].heldout_after)))


def _insignificant_part(label: str, refits: Mapping[str, EffectRefit], bic_margin: float) -> bool:
    """Whether ``label`` is a pair one of whose effects does not pay for itself: the pair's BIC is within
    ``bic_margin`` of the other effect refitted alone (a Kelvin–Voigt record "explained" by Kelvin–Voigt plus
    a 26 mg mass)."""
    if PAIR_SEPARATOR not in label:
        return False
    pair = refits[label]
    return any(part in refits and pair.delta_bic > refits[part].delta_bic - bic_margin
               for part in label.split(PAIR_SEPARATOR))


def verdict_rule(before: np.ndarray, refits: Mapping[str, EffectRefit], paying: Sequence[str],
                 settings: Thresholds) -> tuple[str, list[str], str]:
    """The verdict from the refits alone (no simulation): ``(verdict, ties, reason)``.

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
        ``named_closure``).

    Returns
    -------
    tuple
        ``"none"`` when the gap is within ``gap_threshold`` of the noise floor; :data:`UNEXPLAINED` when no
        refit pays or the best closes less than ``named_closure`` of the gap; else the best's label, the
        single effects that close nearly as much (≥ 95 % of its gain) and leave no measurably larger remainder
        (its ties), and the reason in words.
    """
    paying = [lab for lab in paying if not _insignificant_part(lab, refits, settings.bic_margin)]
    excess = float(np.mean(before)) - 1.0
    if excess < settings.gap_threshold:
        return "none", [], (f"the held-out residual variance is {excess + 1:.3g}× the noise variance, within "
                            f"{settings.gap_threshold:.0%} of the noise floor: nothing to explain")
    if not paying:
        return UNEXPLAINED, [], (f"not in the catalogue: the held-out residual variance is {excess + 1:.3g}× the "
                                 f"noise variance, but no candidate effect improves BIC by more than "
                                 f"{settings.bic_margin:g} and the held-out error")
    best = refits[paying[0]]
    if not best.closed >= settings.named_closure:
        return UNEXPLAINED, [], (f"not in the catalogue: the held-out residual variance is {excess + 1:.3g}× the "
                                 f"noise variance and the best candidate, {paying[0]}, closes only {best.closed:.0%} "
                                 f"of the gap (an effect is named from {settings.named_closure:.0%})")
    gain = float(np.mean(before) - np.mean(best.heldout_after))
    # a pair's own parts are not its rivals: the pair has paid for its second effect against the first
    parts = set(paying[0].split(PAIR_SEPARATOR))
    # a rival ties when it closes nearly as much and what it leaves is not measurably more (a rival leaving
    # 349 noise variances where the best leaves 1.1 is decided, even though both close 97-100 %)
    left = float(np.mean(best.heldout_after))
    ties = [lab for lab in paying[1:] if PAIR_SEPARATOR not in lab and lab not in parts
            and float(np.mean(before) - np.mean(refits[lab].heldout_after)) >= 0.95 * gain
            and float(np.mean(refits[lab].heldout_after)) - left <= max(settings.gap_threshold, 0.25 * (left - 1.0))]
    reason = (f"{paying[0]} closes {best.closed:.0%} of the held-out gap "
              f"(gap ratio {np.mean(before):.3g} -> {np.mean(best.heldout_after):.3g}, dBIC {best.delta_bic:.1f})")
    if left - 1.0 > settings.gap_threshold:
        # a share of the gap, not all of it: the dominant cause, named as such, and the remainder said
        reason += (f"; it explains the dominant part only: {left:.3g}x the noise variance remains, which no "
                   f"candidate of the catalogue explains")
    if ties:
        reason += "; the data cannot distinguish it from " + ", ".join(ties)
    return paying[0], ties, reason


def by_evidence(verdict: str, ties: Sequence[str], probabilities: Mapping[str, float], decisive_odds: float
                ) -> tuple[str, list[str], str]:
    """Between the verdict of :func:`verdict_rule` and its ties (candidates whose refits explain the records as
    well), the evidence decides: ``(verdict, listed, sentence)``.

    The most probable of them (posterior ``probabilities``, :mod:`diagnosis.judgement.evidence`) is the verdict when its
    odds against the next reach ``decisive_odds`` (:attr:`~diagnosis.settings.Thresholds.decisive_odds`);
    otherwise the verdict is :data:`INDISTINGUISHABLE` and ``listed`` holds the candidates, the most probable
    first (an actuator's lag and a sensor's lag on a record with one force and one sensor: the two commute, and no
    record of that pair can tell them apart).
    """
    candidates = sorted([verdict, *ties], key=lambda lab: -probabilities.get(lab, 0.0))
    p = [probabilities.get(lab, 0.0) for lab in candidates]
    odds = p[0] / p[1] if p[1] > 0.0 else float("inf")
    if odds >= decisive_odds:
        return candidates[0], [], (f"the evidence decides between them: {candidates[0]} (posterior probability "
                                   f"{p[0]:.3g}) over {candidates[1]} ({p[1]:.2g}), odds {odds:.3g}")
    listed = ", ".join(f"{lab} {v:.2g}" for lab, v in zip(candidates, p))
    return INDISTINGUISHABLE, candidates, (
        f"{' and '.join(candidates)} explain the records equally well and the evidence cannot separate them "
        f"(posterior probabilities {listed}; odds {odds:.3g} < {decisive_odds:g}): records that see their "
        f"difference (another sensor or drive point) or a prior on one of them would; none is exported")
