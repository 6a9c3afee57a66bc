"""The local refits one diagnosis would repeat, made once (:class:`RefitMemo`).

When the records and the measured modes disagree more than one structure explains, the diagnosis ranks again with
the modes taken without the records' rig parts (:mod:`diagnosis.judgement.apart`).  That problem differs from the
first only in :attr:`~diagnosis.problem.fitting.GapProblem.modes_lack`, which changes the residuals of an effect
that models one of those parts and of no other: an effect that models none of them has the same residuals, the
same score and, from the same baseline, the same local refit — each refit is deterministic.  On the real bench
the second ranking repeated six local refits (3,800 evaluations) to the last digit before this.

A refit is looked up by what it depends on: the effect, the stage and budget, the baseline's unknowns, the
score's start, and the problem's records, noise model, priors, measured modes, settings and other starts (held
by reference while the memo lives, so an identity stands for its object); its :attr:`modes_lack` enters only
through the effects it touches, which are never looked up.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..candidates.score import EffectScore
from ..effects import Effect
from ..problem.fitting import Fit, GapProblem

__all__ = ["RefitMemo"]

#: The stages whose refits depend on nothing but the key (the later stages continue from earlier refits).
_STAGES = ("local", "first")


@dataclass(eq=False)
class RefitMemo:
    """The local refits of one diagnosis, shared by its rankings (module docstring)."""

    _done: dict[tuple, tuple[tuple[Fit, list], tuple[Any, ...]]] = field(default_factory=dict)

    @staticmethod
    def key(problem: GapProblem, baseline: Fit, effect: Effect, score: EffectScore, stage: str,
            max_evaluations: int) -> tuple | None:
        """What the refit of ``effect`` at ``stage`` depends on, or ``None`` when it is not reusable (a later
        stage, or an effect that models a rig part the measured modes' set-up lacks)."""
        if stage not in _STAGES or any(e.rig_part in problem.modes_lack for e in (effect.members or (effect,))):
            return None
        held = _held(problem)
        return (effect.label, stage, max_evaluations, baseline.beta.tobytes(), score.lm, score.p_value,
                score.start.tobytes(), tuple(a.tobytes() for a in score.alternatives),
                tuple(b.tobytes() for b in problem.other_starts), tuple(id(o) for o in held))

    def get(self, key: tuple | None) -> tuple[Fit, list] | None:
        """The refit made under ``key``, or ``None``."""
        found = None if key is None else self._done.get(key)
        return None if found is None else found[0]

    def put(self, key: tuple | None, problem: GapProblem, refit: tuple[Fit, list]) -> None:
        """Keep ``refit`` under ``key`` (nothing for ``None``), holding the objects the key names."""
        if key is not None:
            self._done[key] = (refit, _held(problem))


def _held(problem: GapProblem) -> tuple[Any, ...]:
    """The objects of ``problem`` a refit depends on, named in a key by identity."""
    return (problem.config, problem.space, problem.records, problem.noise, problem.prior, problem.modes,
            problem.settings)
