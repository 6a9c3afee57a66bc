"""Set-ups apart: when the records and the measured modes disagree more than one structure explains, the diagnosis
says so and tries them as two set-ups (:func:`disagreement`, :func:`apart_parts`, :class:`SetupsApart`).

A bench measured twice — a hammer test of the bare beam, then time records with the shaker bolted on — read as one
structure: a refit closes the records' gap, but its modes misfit the measured ones, and every refit that closes
the gap is vetoed so.  That is the signature of evidence from two set-ups.  Without a ``[[setups]]`` table
(:mod:`diagnosis.setups`) the diagnosis then ranks again with the measured modes taken from a set-up without the
rig parts the catalogue models (a rig part's effect off in the modes' rows, :attr:`GapProblem.modes_lack`), and
adopts that reading only when it names a plausible effect; either way the report says what was tried.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..effects import Catalogue
from ..search.rank import Ranking
from .weigh import Weighed
from ..problem.fitting import GapProblem


__all__ = ["SetupsApart", "disagreement", "apart_parts"]


def apart_parts(catalogue: Catalogue) -> frozenset[str]:
    """The rig parts the catalogue's effects model (a shaker's armature, a transducer's mass)."""
    return frozenset(e.rig_part for e in catalogue.effects() if e.rig_part is not None)


def disagreement(problem: GapProblem, ranking: Ranking, weighed: Weighed) -> str | None:
    """The sentence saying that the records and the measured modes disagree more than one structure explains —
    refits close the records' gap (``named_closure``) but every one of them is implausible, and at least one
    misfits the measured modes —, or ``None`` (no measured modes, set-ups already apart, or one structure
    explains both)."""
    if problem.modes is None or problem.modes_lack:
        return None
    closing = [lab for lab, rf in ranking.refits.items() if rf.closed >= problem.settings.named_closure]
    vetoed = [lab for lab in closing if not weighed.modal_data.get(lab, {}).get("agrees", True)]
    if not vetoed or any(lab not in weighed.implausible for lab in closing):
        return None
    chi2 = sorted(float(weighed.modal_data[lab]["chi2"]) for lab in vetoed)
    limit = float(weighed.modal_data[vetoed[0]]["chi2_limit"])
    return (f"the records and the measured modes disagree more than one structure explains: {len(closing)} "
            f"refit(s) close at least {problem.settings.named_closure:.0%} of the records' gap, each needing "
            f"implausible values, {len(vetoed)} misfitting the modes (chi2 {chi2[0]:.3g}"
            f"{'' if len(chi2) == 1 else f' to {chi2[-1]:.3g}'} > {limit:.3g})")


@dataclass(frozen=True)
class SetupsApart:
    """What trying the set-ups apart found: why it was tried, the rig parts the modes were taken without, the
    verdict of that reading and whether it was adopted."""

    why: str
    parts: frozenset[str]
    verdict: str
    adopted: bool
    reason: str

    def text(self) -> str:
        """One sentence for the verdict's reasons."""
        without = ", ".join(sorted(self.parts))
        if self.adopted:
            return (f"{self.why}; read as two set-ups (the measured modes without the {without}), {self.verdict} "
                    f"explains both — the set-ups were inferred, declare them ([[setups]]) if that is how the bench "
                    f"was measured")
        return (f"{self.why}; read as two set-ups (the measured modes without the {without}) the verdict is "
                f"{self.verdict}, no better: one set-up kept")

    def to_dict(self) -> dict[str, Any]:
        """JSON values (``gap.json``'s ``setups_apart``)."""
        return {"why": self.why, "modes_without": sorted(self.parts), "verdict": self.verdict,
                "adopted": self.adopted, "reason": self.reason}
