"""Two effects at once: a second effect tried at the best single effect's refit.

When the best effect pays for itself but leaves more than 10 % of the fit
windows' excess (and closes at least ``pair_minimum`` of the held-out
gap), every other effect is score-tested again *at that effect's refit* — the
baseline fit may have hidden it (a foundation absorbed into the axial load
scores 0 at the baseline) — and the ``pair_partners`` best are refitted
together with it.  A pair is reported when it improves BIC over the single
effect by the BIC margin and lowers the held-out error; it is then named
(``first+second``) under the same named-closure rule (thresholds: :class:`diagnosis.settings.Thresholds`).  The pair is
tried before the other baseline basins and the continuation refits (from the
best local refit, when that effect is linear time-invariant: the nonlinear
simulation of drift and stretching makes their pairs dearer than their
continuation): when it explains the gap, they are skipped — no single effect
is left to find.  A pair must pay against its first effect refitted alone
from the pair's optimum (:func:`pair_with`).
"""
from __future__ import annotations

import numpy as np

from ..effects import PAIR_SEPARATOR, on_top_of
from ..problem.fitting import Fit
from ..problem.ties import tie_ordered
from ..settings import Thresholds
from .refits import RSS_RESOLUTION, EffectRefit, explains, pair_refit, paying_refits
from ..candidates.score import score_effect
from .state import Refits, Search

__all__ = ["Early", "best_pair", "early_pair", "pair_explains", "pair_with", "same_fit"]


#: An early pair: ``(the single's fit it was tried at, its pairs: the best first, then the near-equal rivals;
#: empty when none pays)``; ``None`` when not tried.
Early = tuple[Fit, list[EffectRefit]] | None


def best_pair(run: Search, single: EffectRefit, partners: list[str]) -> list[EffectRefit]:
    """The pairs of ``single`` and one of ``partners`` that pay for their extra parameters against ``single``
    (BIC better by the BIC margin, lower held-out error): the one with the lowest BIC first — of pairs that
    explain the records alike, the one with fewer parameters (a three-variable weak segment can mimic what a
    foundation adds beyond the axial load the baseline gave it) —, then its near-equal rivals, the paying pairs
    whose held-out gain reaches ``pair_rival_share`` of the best's (a foundation's and a spring's pair with the
    same lag: the evidence weighs them, or the tie is stated); empty if none pays."""
    labels = [f"{single.label}{PAIR_SEPARATOR}{p}" for p in partners]
    fits = run.side_by_side(pair_refit, [(run.problem, run.catalogue, lab, single.fit, run.max_evaluations)
                                         for lab in labels])
    paying = []
    for lab, fit in zip(labels, fits):
        rf = run.summary(run.catalogue.effect(lab), fit)
        run.say(f"pair refit {lab}: held-out gap ratio {np.mean(run.before):.3g} -> "
                f"{np.mean(rf.heldout_after):.3g}, dBIC vs {single.label} alone {rf.bic - single.bic:.1f}")
        if (rf.bic < single.bic - run.problem.settings.bic_margin
                and np.mean(rf.heldout_after) < np.mean(single.heldout_after)):
            paying.append(rf)
    if not paying:
        return []
    best = min(paying, key=lambda rf: rf.bic)
    share = run.problem.settings.pair_rival_share
    gain = float(np.mean(run.before) - np.mean(best.heldout_after))
    rivals = [rf for rf in paying if rf is not best
              and float(np.mean(run.before) - np.mean(rf.heldout_after)) >= share * gain]
    return [best] + sorted(rivals, key=lambda rf: rf.bic)


def pair_with(run: Search, single: EffectRefit, known: dict[str, Fit]
              ) -> tuple[list[EffectRefit], dict[str, EffectRefit]]:
    """The best pair of ``single`` and a second effect that pays for itself (:func:`best_pair`), the partners
    score-tested afresh at ``single``'s refit (the baseline may have hidden them), and each of the pair's effects
    refitted alone from the pair's optimum where that beats its refit so far (``known``, by label; ``single``'s
    own).

    A pair must pay against *each* of its effects refitted alone from the pair's optimum:

    * against the first: a pair refit also re-optimises the first effect, and when ``single`` had stopped short
      of its optimum (a local refit left 830 noise variances where the effect alone reaches 1.09) the pair's gain
      is that, with nothing for the second effect to add;
    * against the second: the second may be the whole cause and the first a passenger that the pair's refit has
      shrunk to nothing (a Kelvin–Voigt record was once named ``point_mass+kelvin_voigt`` with a 26 mg mass).

    Such a pair is not returned (nor its rivals: the list is empty); the effects alone are, and are ranked with
    the other single refits.  The best pair's near-equal rivals (:func:`best_pair`) come after it.
    """
    first = run.catalogue.effect(single.label)
    with_prior = run.problem.has_prior
    # a chain's gain as the second effect only where a prior breaks its degeneracy (as on the shortlist); a
    # special case never (the general effect that nests it stands in for it: diagnosis.search.nested)
    rescored = {e.label: score_effect(run.problem, single.fit, on_top_of(first, single.fit.s, e)).lm
                for e in run.effects.values() if e.name != first.name and e.nested_in is None
                and (with_prior or not e.scale_degenerate)}
    partners = [lab for lab in tie_ordered(rescored, lambda k: -rescored[k])
                if rescored[lab] > 0][:run.problem.settings.pair_partners]
    run.say(f"second-effect scores at the {single.label} refit: "
            + ", ".join(f"{lab} {rescored[lab]:.4g}" for lab in partners))
    pairs = best_pair(run, single, partners)
    if not pairs:
        return [], {}
    pair = pairs[0]
    second = run.catalogue.effect(pair.label.split(PAIR_SEPARATOR, 1)[1])
    pays, singles = True, {}
    for effect, s in ((first, pair.fit.s[:first.dim]), (second, pair.fit.s[first.dim:])):
        fit = run.problem.fit(pair.fit.beta, effect, s, max_evaluations=run.max_evaluations)
        alone = run.summary(effect, fit)
        run.say(f"{effect.label} alone from the pair's optimum: fit RSS/n {fit.rss / fit.n:.4g}, "
                f"dBIC of the pair against it {pair.bic - alone.bic:.1f}")
        pays = pays and pair.bic < alone.bic - run.problem.settings.bic_margin
        before = single.fit if effect is first else known.get(effect.label)
        if before is None or fit.rss < before.rss * (1.0 - RSS_RESOLUTION):     # not the same optimum again
            singles[effect.label] = alone
    return (pairs if pays else []), singles


def early_pair(run: Search, labels: list[str], local: Refits) -> tuple[Early, Refits]:
    """Two effects before the other basins and the continuation refits (module docstring): the best local
    refit's effect paired, when it pays, closes ``pair_minimum`` and is linear time-invariant (pairs with
    drift or stretching need the costly nonlinear simulation, dearer than their continuation).  Returns the
    early pair and the refits, with the pair's effects refitted alone from its optimum where that is better."""
    now = {lab: run.summary(run.catalogue.effect(lab), local[lab][0]) for lab in labels}
    lead = paying_refits(now, run.before, run.problem.settings)[:1]
    if not (lead and now[lead[0]].closed >= run.problem.settings.pair_minimum and run.time_invariant(lead[0])):
        return None, local
    pairs, singles = pair_with(run, now[lead[0]], {lab: fit for lab, (fit, _) in local.items()})
    local = local | {lab: (rf.fit, local[lab][1] if lab in local else [(rf.fit.beta, rf.fit.s)])
                     for lab, rf in singles.items()}
    if pairs and explains(pairs[0].fit, run.baseline, run.problem.settings):
        run.say(f"the pair {pairs[0].label} explains the gap: no other basins, re-baselining or continuation refits")
    return (now[lead[0]].fit, pairs), local     # (a single improved here is paired again at the end)


def pair_explains(early: Early, baseline: Fit, settings: Thresholds) -> bool:
    """Whether the pair tried early explains the gap."""
    return early is not None and bool(early[1]) and explains(early[1][0].fit, baseline, settings)


def same_fit(a: Fit, b: Fit) -> bool:
    """Whether two refits ended at the same point (a later stage that did not improve keeps the point)."""
    return a.rss == b.rss and np.array_equal(a.beta, b.beta) and np.array_equal(a.s, b.s)


