"""The search's comparisons weighed against the best fit without an effect.

The search starts from the baseline fitted from the start given (the config's values or an identification), which
may sit in a basin where the records' own start fits better without reaching the noise floor
(:func:`diagnosis.baseline.fit.floor_from_the_records`).  It searches from that basin on purpose — ranked from the
better, compensating one, a spring at a pinned end taken up by the axial load was named a crack — and refits every
shortlisted effect from both.  But the model *without* an effect is the better fit: reported as the baseline, and
every refit's held-out closure and BIC weighed against it, the evidence for ``none`` is its best, and the
diagnosis' baseline is never worse than what ``identify`` finds on the same records (issue 71; measured on the
blind family: a spring at the right end, an actuator's lag, a point mass reported at χ² 504,807, 259,641 and 1.10e6
where identify's point had 30,668, 25,922 and 1.05e6 on 8,400 residuals).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Callable

from ..effects import PAIR_SEPARATOR
from ..problem.fitting import GapProblem
from .rank import Ranking, report_order
from .refits import RSS_RESOLUTION, summarise

__all__ = ["against_the_best_baseline"]


def against_the_best_baseline(problem: GapProblem, ranking: Ranking, say: Callable[[str], None]) -> Ranking:
    """``ranking``, or — when the fit from the records' own start (:attr:`GapProblem.rival`, polished on
    ``problem`` as it is now: numerics and noise model may have changed since) is better than its baseline by more
    than :data:`~diagnosis.search.refits.RSS_RESOLUTION` — the same refits summarised against that fit: their
    held-out closures, BICs, which of them pay and the order (the search itself, and what it found, unchanged)."""
    if problem.rival is None:
        return ranking
    best = problem.fit(problem.rival.beta)
    if best.rss >= ranking.baseline.rss * (1.0 - RSS_RESOLUTION):
        return ranking
    say(f"the fit from the records' own start, without an effect, is better than the baseline the search started "
        f"from ({best.rss / best.n:.4g} against {ranking.baseline.rss / ranking.baseline.n:.4g} noise variances): "
        f"the baseline, every refit weighed against it")
    before, _ = problem.heldout(best.beta)
    refits = {lab: summarise(problem, best, before, ranking.effects[lab], rf.fit)
              for lab, rf in ranking.refits.items()}
    unrefitted = [lab for lab in ranking.order if lab not in refits]
    paying, order = report_order(refits, before, unrefitted, problem.settings)
    # a pair that pays comes first, as the search ranked it (diagnosis.search.rank)
    pairs = [lab for lab in ranking.paying if PAIR_SEPARATOR in lab and lab in paying]
    return replace(ranking, baseline=best, heldout_before=before, refits=refits,
                   order=pairs + [lab for lab in order if lab not in pairs],
                   paying=pairs + [lab for lab in paying if lab not in pairs])
