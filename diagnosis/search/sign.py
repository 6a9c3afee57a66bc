"""The force's sign weighed with the mechanisms, not on the baseline alone (:func:`sign_with_refits`).

The baseline's evidence decides the measured force's sign (:mod:`diagnosis.baseline.polarity`) only as far as the
baseline describes the records.  When no refit brings the records to the noise floor with the sign taken, both
baselines were far from it, and the mechanism that explains the records may need the other sign: an attachment
that moves a resonance across the excited band turns the response's phase, which the bare baseline reads as a
reversed load cell.  Then the candidates are scored at the other sign's baseline and the best-scoring ones, with
the leading refits of the sign taken, are refitted with the other sign (local refits, side by side).  When a
model with the other sign has decisively more evidence (``decisive_odds``) than every model with the sign taken,
the sign is overturned and the diagnosis ranks again with it; either way the comparison is in ``gap.json``
(``force_sign.with_refits``).
"""
from __future__ import annotations

from concurrent.futures import Executor

import numpy as np

from ..baseline.polarity import PolarityCheck, SignWithRefits, reversed_force
from ..candidates.score import score_effect
from ..effects import Catalogue
from ..problem.evidence import laplace_log_evidence
from ..problem.fitting import GapProblem
from ..problem.ties import tie_ordered
from .rank import Ranking
from .refits import map_refits

__all__ = ["sign_with_refits"]

#: Leading refits of the sign taken (the lowest held-out error first) refitted with the other sign too.
LEADING = 3
#: Budget of each refit with the other sign (a local refit's).
MAX_EVALUATIONS = 300


def sign_with_refits(problem: GapProblem, ranking: Ranking, catalogue: Catalogue, check: PolarityCheck,
                     executor: Executor | None = None) -> SignWithRefits | None:
    """The sign weighed with the mechanisms (module docstring); ``None`` when a refit brings the fit windows to
    the noise floor with the sign taken (the other sign cannot do decisively better there) or nothing was
    refitted."""
    floor = 1.0 + problem.settings.gap_threshold
    fits = {lab: rf.fit for lab, rf in ranking.refits.items()}
    if not fits or any(f.rss / f.n <= floor for f in fits.values()) or check.other_beta is None:
        return None
    other = reversed_force(problem)
    other_base = other.fit(check.other_beta)
    effects = {e.label: e for e in catalogue.effects()}
    scores = {lab: score_effect(other, other_base, e) for lab, e in effects.items()}
    singles = [lab for lab in tie_ordered(effects, lambda lab: -scores[lab].lm) if scores[lab].lm > 0
               and not effects[lab].scale_degenerate][:problem.settings.shortlist]
    leading = [lab for lab in sorted(fits, key=lambda lab: float(np.mean(ranking.refits[lab].heldout_after)))
               if lab in effects][:LEADING]
    labels = singles + [lab for lab in leading if lab not in singles]
    refits = map_refits(executor, other, catalogue, labels, other_base, scores, MAX_EVALUATIONS, stage="local")
    logz: dict[str, tuple[float | None, float | None]] = {
        "none": (laplace_log_evidence(problem, ranking.baseline), laplace_log_evidence(other, other_base))}
    for lab in set(fits) | set(refits):
        logz[lab] = (laplace_log_evidence(problem, fits[lab]) if lab in fits else None,
                     laplace_log_evidence(other, refits[lab][0]) if lab in refits else None)
    return SignWithRefits(check.reversed, logz, problem.settings.decisive_odds)
