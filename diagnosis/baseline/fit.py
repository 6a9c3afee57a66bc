"""The diagnosis' baseline stage: where the baseline fit starts, the fit, and the records' own start when the fit
from the config's values (or an identification's result) leaves a gap the records' start does not."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ebb_model.adequacy import NOISE_FLOOR_EXCESS
from ebb_model.errors import ConfigError
from identification.result import IdentificationResult

from ..problem.fitting import Fit, GapProblem
from ..problem.records import records_start

__all__ = ["baseline_fit", "floor_from_the_records", "start_from_result"]


def start_from_result(result: IdentificationResult | str | Path, names: Sequence[str]) -> np.ndarray:
    """The identified model's values (:attr:`IdentificationResult.best`) of the unknowns ``names``."""
    if not isinstance(result, IdentificationResult):
        try:
            result = IdentificationResult.read(result)
        except ConfigError as exc:
            raise ConfigError(f"`result` {exc}") from None
    best = result.best
    missing = [n for n in names if n not in best]
    if missing:
        raise ConfigError(f"`result` {result.out_dir}: the identification has no values of {', '.join(missing)}; "
                          f"expected the parameters {', '.join(names)}")
    return np.array([float(best[n]) for n in names])


def baseline_fit(problem: GapProblem, beta0: np.ndarray) -> tuple[GapProblem, Fit]:
    """The baseline fit: a short global search first, seeded with ``beta0`` (the identification result or the
    nominal values), then the fit from its best basin.  Returns the problem with the other basins kept as
    starts for the refits (the baseline may sit where it only compensates an effect), and the fit."""
    basins = problem.baseline_basins(beta0, n_basins=3)
    problem = replace(problem, other_starts=tuple(problem.fit(b, max_evaluations=60).beta for b in basins[1:]))
    return problem, problem.fit(basins[0])


def floor_from_the_records(problem: GapProblem, baseline: Fit, say: Callable[[str], None]) -> Fit:
    """The baseline, or — when it leaves a gap and the records' own start
    (:func:`diagnosis.problem.records.records_start`)
    explains the records to the noise floor — the fit from that start: then there is no gap to diagnose, the fit
    from the config's values stopped in another basin (a lightly damped record's level valley)."""
    floor = 1.0 + NOISE_FLOOR_EXCESS
    if baseline.rss / baseline.n <= floor:
        return baseline
    x = records_start(problem)
    if x is None:
        return baseline
    fit = problem.fit(x)
    if fit.rss / fit.n > floor:
        return baseline
    say(f"the baseline from the start given stopped at {baseline.rss / baseline.n:.3g} noise variances; from the "
        f"records' own start it reaches the noise floor ({fit.rss / fit.n:.3g}): that fit is the baseline")
    return fit
