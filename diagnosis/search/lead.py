"""The ranking's leading single effect, and the numerics its refit asks for (:class:`LeadNumerics`).

The baseline's numerics are judged where the model lacks the effect; the diagnosis judges them again where the
model has the effect the records ask for most — the first single effect of a ranking's order that was refitted (a
pair's second part is often what the numerics leave, and a drifting load is slow to simulate on a finer grid: the
mid-span mass's pair with an axial drift took 164 s to judge) — by
:func:`diagnosis.baseline.numerics.numerics_at_the_refit`.  It is asked after every round of the ranking, not only
after the last: once the leading refit asks for other numerics, the rounds that would follow on the coarser ones
(a baseline from the effects' optima, every refit and pair again) are not run, and the ranking starts again on the
numerics asked for.  (Measured on the hint family's record 45, a withheld 0.25 kg mass: three rounds on 80 nodes
and the cubic between samples, each ending with ten pair refits, before the soft segment that led the first
round asked for 323 nodes and the band-limited force, where the mass reached the floor.)
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ..baseline.numerics import numerics_at_the_refit
from ..problem.fitting import Fit, GapProblem
from ..stages import StageClock
from .rank import Ranking

__all__ = ["LeadNumerics", "lead"]


def lead(ranking: Ranking) -> str | None:
    """The leading single effect of ``ranking``'s order that was refitted (``None``: none was)."""
    return next((lab for lab in ranking.order if lab in ranking.refits and not ranking.effects[lab].members), None)


@dataclass(eq=False)
class LeadNumerics:
    """Whether a ranking's leading refit asks for other numerics (called as a stop rule of the ranking's rounds),
    the last ranking judged kept with its answer (module docstring).  The ranking itself is held, not its
    ``id``: a round's ranking that was let go can leave its ``id`` to the next one's."""

    problem: GapProblem
    band_hz: float
    clock: StageClock
    say: Callable[[str], None]
    _last: tuple[Ranking, tuple[GapProblem, Fit] | None] | None = None

    def __call__(self, ranking: Ranking) -> bool:
        return self.refined(ranking) is not None

    def refined(self, ranking: Ranking) -> tuple[GapProblem, Fit] | None:
        """The problem on the numerics ``ranking``'s leading refit asks for and that refit on them, or ``None``
        (no leading refit, or it asks for none)."""
        label = lead(ranking)
        if label is None:
            return None
        if self._last is None or self._last[0] is not ranking:
            with self.clock.stage("numerics the leading refit asks for"):
                self._last = (ranking, numerics_at_the_refit(self.problem, ranking.refits[label].fit,
                                                             ranking.effects[label], self.band_hz, self.say))
        return self._last[1]
