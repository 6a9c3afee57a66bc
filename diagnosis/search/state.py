"""What the stages of one ranking share (:mod:`diagnosis.search.rank`, :mod:`diagnosis.search.pairs`): the problem, the
baseline and its held-out gap, the scores, the refits' budget and where they run, and the progress callback."""
from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..effects import Catalogue, Effect
from ..problem.fitting import Fit, GapProblem
from .modal_pattern import PatternFit, time_invariant
from .refits import EffectRefit, explains, map_refits, summarise
from .reuse import RefitMemo
from ..candidates.score import EffectScore
from ..stages import StageClock
from .workers import side_by_side

__all__ = ["Refits", "Search"]

#: The refits so far: label → (fit, the starts it was refitted from).  Stages take it and return a new one.
Refits = dict[str, tuple[Fit, list]]


@dataclass(frozen=True, eq=False)
class Search:
    """What the stages of one ranking share: the problem, the baseline and its held-out gap, the scores, the
    refits' budget and where they run, the progress callback, the stages' clock and the modal matches so far."""

    problem: GapProblem
    baseline: Fit
    catalogue: Catalogue
    effects: dict[str, Effect]               # the candidates by label, in catalogue order
    before: np.ndarray                        # the baseline's held-out gap ratios
    scores: dict[str, EffectScore]
    max_evaluations: int
    executor: Executor | None
    say: Callable[[str], None]
    clock: StageClock
    #: the effects' modal matches so far, shared by the rankings of one diagnosis (the modal stage adds its own
    #: and polishes a later ranking's from them: :func:`diagnosis.search.modal_pattern.pattern_fits`)
    matches: dict[str, PatternFit]
    #: the local refits made so far by the rankings of one diagnosis (:mod:`diagnosis.search.reuse`)
    memo: RefitMemo

    def refit(self, labels: list[str], previous: dict[str, tuple[Fit, list]] | None = None, *, stage: str
              ) -> dict[str, tuple[Fit, list]]:
        """The refits of ``labels`` at ``stage`` (:func:`diagnosis.search.refits.map_refits`); a local refit
        another ranking of the diagnosis made already is taken from :attr:`memo`."""
        if previous is not None:
            return map_refits(self.executor, self.problem, self.catalogue, labels, self.baseline, self.scores,
                              self.max_evaluations, previous, stage=stage)
        keys = {lab: self.memo.key(self.problem, self.baseline, self.effects[lab], self.scores[lab], stage,
                                   self.max_evaluations) for lab in labels}
        known = {lab: self.memo.get(keys[lab]) for lab in labels}
        todo = [lab for lab in labels if known[lab] is None]
        made = map_refits(self.executor, self.problem, self.catalogue, todo, self.baseline, self.scores,
                          self.max_evaluations, stage=stage) if todo else {}
        for lab, refit in made.items():
            self.memo.put(keys[lab], self.problem, refit)
        return {lab: made[lab] if (hit := known[lab]) is None else hit for lab in labels}

    def explained(self, local: dict[str, tuple[Fit, list]]) -> bool:
        """Whether one of the refits explains the gap."""
        return any(explains(fit, self.baseline, self.problem.settings) for fit, _ in local.values())

    def at_noise_floor(self, local: dict[str, tuple[Fit, list]]) -> bool:
        """Whether one of the refits leaves the fit windows within the gap threshold of the noise floor
        (nothing left for another basin or effect to explain)."""
        return any(fit.rss / fit.n - 1.0 <= self.problem.settings.gap_threshold for fit, _ in local.values())

    def summary(self, effect: Effect, fit: Fit) -> EffectRefit:
        """The refit's held-out gap, BIC and closure (:func:`diagnosis.search.refits.summarise`)."""
        return summarise(self.problem, self.baseline, self.before, effect, fit)

    def time_invariant(self, label: str) -> bool:
        """Whether the effect keeps the model linear and time-invariant."""
        return time_invariant(self.problem, self.baseline.beta, self.catalogue.effect(label))

    def side_by_side(self, task: Callable[..., Any], args: list[tuple]) -> list[Any]:
        """``task(*a)`` for each of ``args`` (:func:`diagnosis.search.workers.side_by_side`)."""
        return side_by_side(self.executor, task, args)
