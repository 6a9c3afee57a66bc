"""No candidate dropped unseen: for every effect whose score test is significant and that has no refit, the
reason, in words (:func:`not_refitted`; ``gap.json``'s ``not_refitted``, the report and the console say it).

The shortlist orders the work; what it leaves out is said, with the score, its rank and why the stage that could
have refitted it did not — a special case at a fixed place that no general effect landed near, a chain's gain
degenerate with the beam's scale, a structural effect whose modal pattern was not among the matches refitted, or
an effect beyond the shortlist.
"""
from __future__ import annotations

from typing import Mapping

from ..candidates.score import EffectScore
from ..effects import Effect
from ..problem.ties import tie_ordered
from ..settings import Thresholds
from .modal_pattern import PatternFit

__all__ = ["not_refitted"]


def _why(effect: Effect, patterns: Mapping[str, PatternFit], settings: Thresholds, with_prior: bool) -> str:
    """Why a stage that could have refitted ``effect`` did not."""
    lab = effect.label
    if effect.landings:
        sources = " or ".join(sorted({landing.source for landing in effect.landings}))
        reach = max(landing.reach for landing in effect.landings)
        return (f"a special case at a fixed place, refitted only where a {sources} refit lands within "
                f"{reach:.0%} of the beam's length of it: none did")
    if effect.nested_in is not None:
        return f"a special case of {effect.nested_in}, which stands in for it"
    if effect.scale_degenerate:
        return ("a gain of the measurement chain, degenerate with a common scale of the beam's unknowns: refitted "
                "beside the shortlist only when it scores best of all"
                + ("" if with_prior else " or a prior on the beam breaks the degeneracy (none is given)"))
    why = f"beyond the shortlist of the {settings.shortlist} best-scoring effects"
    if lab in patterns:
        best = min(pf.chi2 for k, pf in patterns.items() if k != "baseline")
        why += (f"; its modal pattern (chi2 {patterns[lab].chi2:.3g}, the best match {best:.3g}) was not among the "
                f"{settings.pattern_candidates} refitted")
    return why


def not_refitted(effects: Mapping[str, Effect], scores: Mapping[str, EffectScore], refitted: set[str],
                 patterns: Mapping[str, PatternFit], dropped: Mapping[str, str], settings: Thresholds, *,
                 with_prior: bool, at_floor: bool = False) -> dict[str, str]:
    """For each effect whose score's p-value is below ``settings.score_significance`` and that is not among
    ``refitted``, the line saying so and why (``dropped``: the effects refitted but dropped, with the reason;
    ``at_floor``: no effect was refitted, the baseline leaving nothing to explain), in score order."""
    by_score = tie_ordered(scores, lambda lab: -scores[lab].lm)
    out = {}
    for rank, lab in enumerate(by_score, start=1):
        sc = scores[lab]
        if lab in refitted or not sc.p_value < settings.score_significance:
            continue
        head = f"score {sc.lm:.3g} (rank {rank} of {len(by_score)}, p {sc.p_value:.2g})"
        if lab in dropped:
            out[lab] = f"{head}, refitted but dropped: {dropped[lab]}"
        elif at_floor:
            out[lab] = (f"{head}, not refitted: the baseline is within {settings.gap_threshold:.0%} of the noise "
                        f"floor, nothing to explain")
        else:
            out[lab] = f"{head}, not refitted: {_why(effects[lab], patterns, settings, with_prior)}"
    return out
