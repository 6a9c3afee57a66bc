"""The diagnosis' baseline stage: where the baseline fit starts, the fit from the config's values (or an
identification's result) and from the records' own start, and which of them is the baseline."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ebb_model.space.adequacy import NOISE_FLOOR_EXCESS, modes_top
from ebb_model.acquisition.channel_delay import effective_delays
from ebb_model.errors import ConfigError
from ebb_model.modal.modal import discrete_frequencies
from identification.start_modes import alignment_miss
from identification.record_poles import record_modes
from identification.result import IdentificationResult

from ..problem.fitting import Fit, GapProblem
from ..problem.records import records_start
from .numerics import numerics_from_the_records

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
    """The baseline fit: a short global search seeded with ``beta0`` (the identification result or the nominal
    values), then the fit from its best basin.  Returns the problem with the other basins kept as starts for the
    refits (the baseline may sit where it only compensates an effect) and the fit from the records' own start
    (:func:`diagnosis.problem.records.records_start`, where ``identify`` starts) as its
    :attr:`~diagnosis.problem.fitting.GapProblem.rival`, and the fit."""
    basins = problem.baseline_basins(beta0, n_basins=3)
    others = tuple(problem.fit(b, max_evaluations=60).beta for b in basins[1:])
    x = records_start(problem)
    return replace(problem, other_starts=others, rival=None if x is None else problem.fit(x)), problem.fit(basins[0])


def floor_from_the_records(problem: GapProblem, baseline: Fit, band_hz: float, say: Callable[[str], None]
                           ) -> tuple[GapProblem, Fit]:
    """The problem on the numerics the records ask for (:func:`diagnosis.baseline.numerics.numerics_from_the_records`)
    and its baseline: the baseline given, or — when that leaves a gap and the fit from the records' own start
    (the problem's :attr:`~diagnosis.problem.fitting.GapProblem.rival`, fitted again under the problem's noise
    model) explains the records to the noise floor, on the config's numerics or on those the records ask for —
    that fit: then there is no gap to diagnose, the fit from the config's values stopped in another basin (a
    lightly damped record's level valley).

    A fit from the records' start that is better without reaching the floor is not the baseline the search starts
    from — measured on the blind family: a spring at a pinned end compensated by the axial load (N 29.6 for 20,
    3.6 noise variances), where a soft segment next to that end then closed the rest and was named — but the first
    of the problem's other starts, from which every shortlisted effect is refitted when the baseline's basin leaves
    the gap, and stays the problem's :attr:`~diagnosis.problem.fitting.GapProblem.rival` (the measured modes are
    scanned from its modes, the modal patterns matched from it too); once the search is done it is the baseline
    reported, every refit weighed against it (:func:`diagnosis.search.rebase.against_the_best_baseline`).  A fit
    from the records' start that is worse in time stays the rival when its
    modes place the records' own better than the baseline's (:func:`_places_more`); otherwise the problem has no
    rival."""
    floor = 1.0 + NOISE_FLOOR_EXCESS
    rival, problem = problem.rival, replace(problem, rival=None)
    if baseline.rss / baseline.n <= floor or rival is None:
        return numerics_from_the_records(problem, baseline, band_hz, say)
    fit = problem.fit(rival.beta)
    if fit.rss / fit.n <= floor:
        _say_floor(say, baseline, fit, "")
        return numerics_from_the_records(problem, fit, band_hz, say)    # at the floor too: they may still be asked
    lines: list[str] = []
    refined, fit_refined = numerics_from_the_records(problem, fit, band_hz, lines.append)
    if fit_refined.rss / fit_refined.n <= floor:
        for line in lines:
            say(line)
        _say_floor(say, baseline, fit_refined, " on the numerics the records ask for")
        return refined, fit_refined
    if fit.rss < baseline.rss:
        problem = replace(problem, other_starts=(np.asarray(fit.beta, dtype=float), *problem.other_starts),
                          rival=fit)
    elif _places_more(problem, fit, baseline, band_hz):
        # worse in time, it can still hold the records' modes where the baseline does not (a 10 g mass mid-span
        # on the broadband strip: the baseline's modes at 0.67 of the records', the records' start's within 1.2 %,
        # its level misplaced by modes the mass moved unevenly): the modal stages work from it too
        problem = replace(problem, rival=fit)
    return numerics_from_the_records(problem, baseline, band_hz, say)


def _places_more(problem: GapProblem, fit: Fit, baseline: Fit, band_hz: float) -> bool:
    """Whether ``fit``'s modes place the records' own modes (:func:`identification.record_poles.record_modes` of
    the fit windows) better than ``baseline``'s (:func:`identification.start_modes.alignment_miss`), counting the
    modes a record of the excited band's top ``band_hz`` shows (:func:`ebb_model.space.adequacy.modes_top`)."""
    records = [r for r in problem.records if r.has_fit]
    dt = problem.config.time.dt
    recorded = record_modes([r.inputs[:r.fit_end] for r in records], [r.outputs[:r.fit_end] for r in records], dt,
                            effective_delays(problem.config))
    if recorded.frequencies_hz.size == 0:
        return False
    top = modes_top(band_hz, dt)

    def miss(f: Fit) -> float:
        freqs, _ = discrete_frequencies(*problem.space.apply(problem.config, f.beta))
        return alignment_miss(recorded.frequencies_hz, recorded.support, freqs[freqs <= top])

    return miss(fit) < miss(baseline)


def _say_floor(say: Callable[[str], None], baseline: Fit, fit: Fit, numerics: str) -> None:
    say(f"the baseline from the start given stopped at {baseline.rss / baseline.n:.3g} noise variances; from the "
        f"records' own start it reaches the noise floor{numerics} ({fit.rss / fit.n:.3g}): that fit is the baseline")
