"""The diagnosis' baseline on the numerics the records ask for: the identification's rule
(:mod:`identification.numerics`), so that a gap the config's grid or its force between samples makes is not left for
an effect to explain (nor for the grid's verdict to name when the records already tell the finer numerics apart)."""
from __future__ import annotations

from dataclasses import replace
from typing import Callable

from ebb_model.adequacy import NOISE_FLOOR_EXCESS
from identification.numerics import REFINEMENT_GAIN, keeps, refinements

from ..problem.fitting import Fit, GapProblem

__all__ = ["numerics_from_the_records"]


def numerics_from_the_records(problem: GapProblem, baseline: Fit, band_hz: float, say: Callable[[str], None]
                              ) -> tuple[GapProblem, Fit]:
    """The problem on the numerics the records ask for and the baseline refitted on them (the problem and baseline
    given when the baseline is at the noise floor, or no refinement is kept).

    A refinement (:func:`identification.numerics.refinements`) that changes the baseline's χ² by more than
    :data:`~identification.numerics.REFINEMENT_GAIN` per residual is fitted on, and kept by the identification's
    rule (:func:`identification.numerics.keeps`).
    """
    if baseline.rss / baseline.n <= 1.0 + NOISE_FLOOR_EXCESS:
        return problem, baseline
    cfg = problem.config
    at, params = problem.space.apply(cfg, baseline.beta)
    first, kept = baseline.rss, []
    for what, refine in refinements(at, params, [r.inputs for r in problem.records], band_hz):
        trial = replace(problem, config=refine(problem.config))
        r = trial.residuals(baseline.beta)
        if not abs(float(r @ r) - baseline.rss) > REFINEMENT_GAIN * baseline.n:
            continue
        fit = trial.fit_along_the_level(baseline.beta)
        if keeps(baseline.rss, fit.rss, baseline.n):
            problem, baseline = trial, fit
            kept.append(what + (f" ({trial.config.beam.nodes} nodes, from {cfg.beam.nodes})"
                                if trial.config.beam.nodes != cfg.beam.nodes else ""))
    if kept:
        say(f"the records ask for finer numerics: with {' and '.join(kept)} the baseline goes from "
            f"{first / baseline.n:.3g} to {baseline.rss / baseline.n:.3g} noise variances per residual; the diagnosis "
            "runs on them")
    return problem, baseline
