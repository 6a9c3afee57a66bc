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

import math
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..baseline.polarity import PolarityCheck, reversed_force
from ..candidates.score import score_effect
from ..effects import Catalogue
from ..judgement.evidence import laplace_log_evidence
from ..problem.fitting import GapProblem
from .rank import Ranking
from .refits import map_refits

__all__ = ["SignWithRefits", "sign_with_refits"]

#: Leading refits of the sign taken (the lowest held-out error first) refitted with the other sign too.
LEADING = 3
#: Budget of each refit with the other sign (a local refit's).
MAX_EVALUATIONS = 300


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
    singles = [lab for lab in sorted(effects, key=lambda lab: -scores[lab].lm) if scores[lab].lm > 0
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
