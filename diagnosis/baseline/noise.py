"""The noise as it is in each record (level and colour), from a model's residual
(:func:`identification.noise_model.estimate_noise_model`), and the baseline fitted again under it."""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from identification.noise_model import estimate_noise_model

from ..problem.fitting import Fit, GapProblem
from ..stages import StageClock

__all__ = ["noise_of", "under_the_noise"]


def noise_of(problem: GapProblem, simulated: Sequence[np.ndarray | None], clock: StageClock,
             say: Callable[[str], None]) -> GapProblem:
    """``problem`` under the noise as it is in each record (level and colour), from the residual of the model
    outputs ``simulated`` (every record's whole length)."""
    records, cfg = problem.records, problem.config
    with clock.stage("noise model"):
        problem = problem.with_noise(estimate_noise_model([r.inputs for r in records], [
            r.outputs - y for r, y in zip(records, simulated)], cfg.time.dt))
    say("noise model: " + "; ".join(problem.noise_model.describe(cfg.output_names, [r.name for r in records])))
    return problem


def under_the_noise(problem: GapProblem, baseline: Fit, clock: StageClock, say: Callable[[str], None]
                    ) -> tuple[GapProblem, Fit]:
    """The noise as it is in each record, from the baseline's residual (:func:`noise_of`), and the baseline fitted
    again under it along the level (:meth:`GapProblem.fit_along_the_level`).  The first noise model, before the
    force's sign is taken, is :func:`diagnosis.baseline.polarity.check_polarity`'s."""
    problem = noise_of(problem, problem.simulate(baseline.beta, until="all"), clock, say)
    with clock.stage("noise model"):
        baseline = problem.fit_along_the_level(baseline.beta)
    return problem, baseline
