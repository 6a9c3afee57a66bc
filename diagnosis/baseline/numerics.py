"""The diagnosis' baseline on the numerics the records ask for: the identification's rule
(:mod:`identification.numerics`), so that a gap the config's grid or its force between samples makes is not left for
an effect to explain (nor for the grid's verdict to name when the records already tell the finer numerics apart)."""
from __future__ import annotations

from dataclasses import replace
from typing import Callable

from ebb_model.space.adequacy import NOISE_FLOOR_EXCESS
from identification.numerics import all_at_once, moves_the_answer, records_keep, records_tell_apart, refinements

from ..effects import Effect
from ..problem.fitting import Fit, GapProblem

__all__ = ["numerics_at_the_refit", "numerics_from_the_records"]


def numerics_from_the_records(problem: GapProblem, baseline: Fit, band_hz: float, say: Callable[[str], None]
                              ) -> tuple[GapProblem, Fit]:
    """The problem on the numerics the records ask for and the baseline refitted on them (the problem and baseline
    given when no refinement is kept).

    The identification's rule (:func:`identification.numerics.numerics_for_records`): a refinement
    (:func:`identification.numerics.refinements`) that changes the baseline's χ² so that the records tell it apart
    (:func:`identification.numerics.records_tell_apart`) is fitted on, and kept by
    :func:`identification.numerics.keeps`; at the noise floor every refinement at once, kept when its fit is lower
    by :data:`~identification.numerics.FLOOR_EVIDENCE` — there the parameters have taken up the coarser numerics'
    error, which the held-out window then shows as a gap (measured: the hint family's correct cantilever record 48,
    an accelerometer under noise to 0.2 fs, 80 nodes and the cubic: fit 1.1 noise variances, held out 1.44, the
    verdict ``unexplained``; at the truth 323 nodes and the band-limited force leave 1.02 and 0.99).
    """
    first = baseline.rss
    problem, baseline, kept = _refined(problem, baseline, band_hz)
    if kept:
        say(f"the records ask for finer numerics: with {' and '.join(kept)} the baseline goes from "
            f"{first / baseline.n:.3g} to {baseline.rss / baseline.n:.3g} noise variances per residual; the diagnosis "
            "runs on them")
    return problem, baseline


def numerics_at_the_refit(problem: GapProblem, refit: Fit, effect: Effect, band_hz: float,
                          say: Callable[[str], None]) -> tuple[GapProblem, Fit] | None:
    """The problem on the numerics the leading refit asks for and the refit on them, or ``None`` when it asks for
    none.

    The baseline's numerics are judged where the model lacks the effect, and when the records' effect keeps the
    baseline far from them, the comparison says little about the numerics: the steel strip under a broadband force
    to 0.39 fs with a withheld crack next to the clamp, its baseline 2,800 noise variances per residual, kept the
    cubic between samples; its crack's refit (position, length and factor right) left 110 on the cubic and 0.83 on
    the band-limited force and 323 nodes (fitted along the level: :meth:`GapProblem.fit_along_the_level
    <diagnosis.problem.fitting.GapProblem.fit_along_the_level>`), a 30 g tip mass's 48.6 and 2.4.  The same rule
    as the baseline's (:func:`numerics_from_the_records`) at the leading refit (``effect`` at ``refit``): the
    search then runs again on the numerics kept (there: the crack and the transducer's mass named, each at the
    floor; before, the crack's gap left 1.4e3 noise variances and the mass was paired with a spurious term).
    """
    if refit.rss / refit.n <= 1.0 + NOISE_FLOOR_EXCESS:
        return None
    first = refit.rss
    refined, fit, kept = _refined(problem, refit, band_hz, effect)
    if not kept:
        return None
    say(f"the leading refit ({effect.label}) asks for finer numerics: with {' and '.join(kept)} it goes from "
        f"{first / fit.n:.3g} to {fit.rss / fit.n:.3g} noise variances per residual; the search runs again on them")
    return refined, fit


def _refined(problem: GapProblem, fit: Fit, band_hz: float, effect: Effect | None = None
             ) -> tuple[GapProblem, Fit, list[str]]:
    """Each refinement that changes ``fit``'s χ² (of ``effect`` at ``fit.s`` when given) by more than
    :data:`~identification.numerics.REFINEMENT_GAIN` per residual, or that moves the baseline (``effect`` ``None``)
    by more than a Cramér–Rao deviation (:func:`~identification.numerics.moves_the_answer`), fitted on and kept by
    :func:`~identification.numerics.keeps` (at the noise floor all at once, kept by
    :data:`~identification.numerics.FLOOR_EVIDENCE`): the problem and fit on the numerics kept, and what was kept."""
    cfg = problem.config
    at, params = problem.space.apply(cfg, fit.beta)
    kept: list[str] = []
    steps = refinements(at, params, [r.inputs for r in problem.records], band_hz)
    at_floor = fit.rss / fit.n <= 1.0 + NOISE_FLOOR_EXCESS
    for what, refine in all_at_once(steps) if at_floor else steps:
        trial = replace(problem, config=refine(problem.config))
        r = trial.residuals(fit.beta, effect, fit.s if effect is not None else None)
        if not records_tell_apart(fit.rss, float(r @ r), fit.n, at_floor) and (effect is not None or not (
                moves_the_answer(problem.space, fit.beta, problem.residuals, trial.residuals, problem.config.beam.nodes,
                                 trial.config.beam.nodes))):
            continue
        new = trial.fit_along_the_level(fit.beta, effect, fit.s if effect is not None else None)
        if records_keep(fit.rss, new.rss, fit.n, at_floor):
            problem, fit = trial, new
            kept.append(what + (f" ({trial.config.beam.nodes} nodes, from {cfg.beam.nodes})"
                                if trial.config.beam.nodes != cfg.beam.nodes else ""))
    return problem, fit, kept
