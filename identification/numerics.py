"""The numerics the records ask for: a finer grid and the band-limited force between samples, when they close a gap.

A config's grid (``[beam] nodes``) and its force between samples (``[time] input``) are numerics, not physics:
a newcomer takes the examples' grid and the default cubic, and on the record labs make most — a shaker fed
broadband noise, read by an accelerometer — both leave a gap the parameters then compensate (the strip of the
broadband family, 80 nodes and the cubic: 409 noise variances and EI 4 % low; the band-limited force: 1.9 and
1.1 % low; and 323 nodes: the noise floor).  After the polish, the refinements that can close a gap made by
numerics are tried at the identified point, in turn — at the noise floor too, where the parameters may have taken
up the numerics' error (a cantilever's accelerometer near the clamp under noise to 0.2 fs, 80 nodes and the cubic:
1.13 noise variances with EI and ρA 1.26 % high, six Cramér–Rao deviations; the refinements were not tried there).
Above the floor they are tried in turn:

* the band-limited force between samples (:mod:`ebb_model.acquisition.bandlimited`), when the records' force reaches
  :data:`~ebb_model.acquisition.bandlimited.BROADBAND_EDGE` of the sampling rate and the config takes the cubic;
* the grid the numerical adequacy compares with (:func:`ebb_model.space.adequacy.adequacy_grid`: four times the
  intervals for the exact scheme, so that its Richardson pair is a finer pair too, or the grid advice's).

A refinement that changes the identified point's χ² by more than :data:`REFINEMENT_GAIN` noise variances per
sample (either way: at that point the parameters compensate the coarser numerics' error) is polished on, and kept
(:func:`keeps`) when the polished fit is lower by more than that, or at the noise floor and not higher by more
than that (a model's own record, made with its grid and cubic, fits those better and keeps them); the next
refinement is judged from there.  At the floor each alone can look no better — the parameters have compensated
their joint error (that cantilever: the band-limited force alone 1.2, the finer grid alone 1.18) — so every
refinement is tried at once — polished on when it changes χ² at the point by more than :data:`FLOOR_EVIDENCE`
(:func:`records_tell_apart`) — and kept when its polished fit is decisively better (:data:`FLOOR_EVIDENCE`; that
cantilever: 0.98, EI within its Cramér–Rao deviation).
Records the model made itself (its own cubic, its own grid) fit worse on other numerics, so they keep theirs:
the records choose, not a rule about the force's band.  The FMU backend keeps the config's numerics (an FMU takes
the force sample by sample; :func:`ebb_model.acquisition.bandlimited.hold_hint` then says what would model the records).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ebb_model.space.adequacy import (DECISIVE_EVIDENCE, GRID_SHIFT, NOISE_FLOOR_EXCESS, NumericalAdequacy,
                                     adequacy_grid, excited_band, numerical_adequacy)
from ebb_model.space.grid_advice import GridAdvice, grid_advice
from ebb_model.acquisition.bandlimited import hold_hint
from ebb_model.config import BeamConfig

from .modal_data import ModalData, modal_data
from .native import NativeEvaluator
from .noise_model import NoiseModel
from .grid_shift import on_the_grid_of, shift_between
from .polish import PolishResult, ResidualEvaluator, polish
from .prior import Prior
from .runners import Runner

__all__ = ["FLOOR_EVIDENCE", "REFINEMENT_GAIN", "REFINEMENT_SHARE", "SHIFT_NODES", "NumericsChoice", "all_at_once",
           "keeps", "moves_the_answer", "numerics_for_records", "records_keep", "refine_numerics", "refinements"]

#: A refinement is judged (polished on) when it changes the identified point's χ² by more than this many noise
#: variances per sample, and kept (:func:`keeps`) when it lowers the fit by more than that: the noise floor's own
#: allowance (:data:`~ebb_model.space.adequacy.NOISE_FLOOR_EXCESS`), so that a change the noise could make never moves
#: the numerics.
REFINEMENT_GAIN = NOISE_FLOOR_EXCESS
#: ... and by this share of the excess over the floor: the share of a gap from which the numerics are named in it
#: (:attr:`diagnosis.settings.Thresholds.grid_caution`, the same 10 %).
REFINEMENT_SHARE = 0.1
#: The largest grid a refinement is tried on because it moves the answer (:func:`moves_the_answer`): a new parameter
#: set costs 0.04–0.2 s on 323 nodes and 0.45 s on 1,295 (the pinned–clamped beam of
#: :mod:`ebb_model.space.adequacy`), and the adequacy check of an answer on 1,295 nodes simulates 5,183 (minutes).
SHIFT_NODES = 400
#: At the noise floor the finest numerics are kept when their polished χ² is lower by more than this: decisive odds
#: of 100 to 1 between two models of the same unknowns (2 ln 100).  A model's own record, made with its grid and
#: cubic, fits those better and keeps them.
FLOOR_EVIDENCE = DECISIVE_EVIDENCE


@dataclass(frozen=True)
class NumericsChoice:
    """The numerics kept and the fit on them.

    Attributes
    ----------
    evaluator
        The evaluator on the numerics kept (the one given when none was refined).
    polished
        The polish on the refined numerics (``None`` when nothing was refined).
    note
        One line saying what was refined and what it did to the fit (``None`` when nothing was).
    """

    evaluator: NativeEvaluator
    polished: PolishResult | None
    note: str | None


def keeps(before: float, after: float, n: int) -> bool:
    """Whether the records keep a refinement whose fit went from χ² ``before`` to ``after`` over ``n`` residuals:
    when it fits better by more than :data:`REFINEMENT_GAIN` per residual and by :data:`REFINEMENT_SHARE` of the
    excess over the floor, or reaches the noise floor without
    fitting worse by more than that — finer numerics are the same beam nearer the continuum, with no parameter
    more (at the floor on both, the coarser one's parameters compensate its error: the compressed pinned beam's EI
    0.23 % low on 80 nodes, 74 Cramér–Rao deviations).  A fit far above the floor on both is the physics' gap, not
    the numerics': it keeps the config's (an effect's blind record refitted on four times the grid, 3.89e3 noise
    variances less 0.2 %, moved that diagnosis' verdict)."""
    gain = before - after
    if gain > REFINEMENT_GAIN * n and gain > REFINEMENT_SHARE * (before - n):
        return True
    return after / n <= 1.0 + NOISE_FLOOR_EXCESS and after <= before + REFINEMENT_GAIN * n


def records_tell_apart(level: float, trial: float, n: int, at_floor: bool) -> bool:
    """Whether the records tell a refinement's numerics from the current ones at the same point (χ² ``level`` and
    ``trial``, ``n`` residuals), so that a fit on them is worth making: at the noise floor by the floor's own
    evidence, :data:`FLOOR_EVIDENCE` (what :func:`records_keep` then asks of the fit), above it by
    :data:`REFINEMENT_GAIN` per residual.  Asking 0.25 per residual at the floor too let a change of 346 pass
    unseen: the hint family's correct pinned–pinned record under white noise to the Nyquist frequency, one
    displacement sensor, 1,400 residuals, 1.26 noise variances per residual on the cubic between samples at the
    truth and 1.01 on the band-limited force; the diagnosis kept the cubic, its baseline within 0.2 % of the truth
    held out 1.5 and the verdict was ``unexplained``."""
    return abs(trial - level) > (FLOOR_EVIDENCE if at_floor else REFINEMENT_GAIN * n)


def records_keep(before: float, after: float, n: int, at_floor: bool) -> bool:
    """Whether the records keep a refinement tried from a fit at the noise floor (``at_floor``: every refinement at
    once, kept when lower by :data:`FLOOR_EVIDENCE`) or above it (:func:`keeps`) — the rule of
    :func:`numerics_for_records` and of the diagnosis' baseline."""
    return before - after > FLOOR_EVIDENCE if at_floor else keeps(before, after, n)


def moves_the_answer(space: Any, x: np.ndarray, here: Callable[[np.ndarray], np.ndarray],
                     there: Callable[[np.ndarray], np.ndarray], nodes: int, trial_nodes: int) -> bool:
    """Whether a fit on a refinement's numerics would move the answer ``x`` (of the unknowns ``space``) by more than
    :data:`~ebb_model.space.adequacy.GRID_SHIFT` Cramér–Rao deviations (:mod:`identification.grid_shift`; ``here``
    and ``there``: whitened residuals on the current numerics and on the refinement's, grids of ``nodes`` and
    ``trial_nodes``): the records then tell the numerics apart at the parameters' level though their χ² at ``x``
    changes by less than :func:`records_tell_apart` asks (the demo's beam under white noise, two displacement sensors,
    10 s: on 80 nodes with the band-limited force 0.21 noise variances per sample from the grid four times finer, and
    N 12 deviations off it).  Whether the numerics are kept stays :func:`records_keep`'s decision, on the polished
    fit — the rule of ``identify`` and of the diagnosis' baseline.  Grids above :data:`SHIFT_NODES` are not tried
    for it."""
    if trial_nodes > SHIFT_NODES:
        return False
    shift = shift_between(space, x, here, there, nodes, trial_nodes)
    return shift is not None and shift.largest > GRID_SHIFT


def refinements(config: BeamConfig, params: Mapping[str, float], inputs: Sequence[np.ndarray], band_hz: float
                 ) -> list[tuple[str, Callable[[BeamConfig], BeamConfig]]]:
    """The refinements to try, in order, each as ``(what it is, config → refined config)``; ``params`` are the
    physical parameters at the identified point (the grid advice's)."""
    out: list[tuple[str, Callable[[BeamConfig], BeamConfig]]] = []
    if config.time.scheme != "exact":
        return out        # the seed's θ-scheme is asked for by name: its grid is the user's, the grid advice says how
    if hold_hint(config, inputs) is not None:
        out.append(("the band-limited force between samples",
                    lambda c: replace(c, time=replace(c.time, input_hold="bandlimited"))))
    out.append(("a finer grid", lambda c: adequacy_grid(c, params, band_hz)))
    return out


def all_at_once(steps: Sequence[tuple[str, Callable[[BeamConfig], BeamConfig]]]
                ) -> list[tuple[str, Callable[[BeamConfig], BeamConfig]]]:
    """:func:`refinements`' ``steps`` as one step, every refinement at once (none: none) — what is tried at the noise
    floor, where each alone can look no better (module docstring)."""
    if not steps:
        return []
    each = tuple(steps)

    def finest(c: BeamConfig) -> BeamConfig:
        for _, refine in each:
            c = refine(c)
        return c

    return [(" and ".join(w for w, _ in each), finest)]


def numerics_for_records(evaluator: NativeEvaluator, candidates: Sequence[np.ndarray], runner: Runner, *,
                         budget: int, band_hz: float, noise: NoiseModel | None = None, prior: Prior | None = None,
                         modes: ModalData | None = None,
                         evaluator_for: Callable[[BeamConfig], NativeEvaluator]) -> NumericsChoice:
    """The numerics the records ask for, judged at the identified point (module docstring).

    Parameters
    ----------
    evaluator
        The identification's native evaluator (the config's numerics).
    candidates
        The polished points, the identified one first: the numerics are judged at the first; once refined,
        every candidate is polished on them and the lowest χ² is the answer (on coarse numerics the parameters'
        compensation can rank the basins wrongly: the clamped beam in tension under white noise to the Nyquist
        frequency, the cubic and 80 nodes, ranked a basin 7 % off ρA first).
    runner
        Where the polish's batches run.
    budget
        The polish's residual evaluations.
    band_hz
        Top of the records' excited band [Hz] (the grid advice's band).
    noise, prior, modes
        As the identification's polish (:func:`identification.polish.polish`).
    evaluator_for
        The evaluator of the same records and unknowns on another config.
    """
    def chi2(ev: NativeEvaluator, at: np.ndarray) -> float:
        r = np.asarray(runner(ResidualEvaluator(ev, noise, prior, modes), at[None, :]), dtype=float)[0]
        return float(r @ r) if np.all(np.isfinite(r)) else np.inf

    def polished(ev: NativeEvaluator, at: np.ndarray) -> PolishResult:
        return polish(ev, at, runner=runner, max_evaluations=budget, noise=noise, prior=prior, modes=modes)

    x = np.asarray(candidates[0], dtype=float)
    samples = sum(e.outputs.size for e in evaluator.experiments)
    first = chi2(evaluator, x)
    if not np.isfinite(first):
        return NumericsChoice(evaluator, None, None)
    cfg = evaluator.config
    at_x, params = evaluator.space.apply(cfg, x)
    current, level, fit, kept = evaluator, first, None, []
    steps = refinements(at_x, params, [e.inputs for e in evaluator.experiments], band_hz)
    if first / samples <= 1.0 + NOISE_FLOOR_EXCESS:
        # at the floor every refinement at once, kept only when the records decisively prefer it (module docstring)
        steps = all_at_once(steps)
    at_floor = first / samples <= 1.0 + NOISE_FLOOR_EXCESS
    for what, refine in steps:
        trial = evaluator_for(refine(current.config))
        if not records_tell_apart(level, chi2(trial, x), samples, at_floor) and (noise is None or not moves_the_answer(
                current.space, x, ResidualEvaluator(current, noise, prior, modes).residuals,
                ResidualEvaluator(trial, noise, prior, modes).residuals, current.config.beam.nodes,
                trial.config.beam.nodes)):
            continue                  # the records cannot tell the two numerics apart here
        # a change either way is judged after a polish: at ``x`` the parameters compensate the coarser numerics'
        # error (the strip's band-limited fit on 80 nodes: 2.0 noise variances there, 4.9 on 323 nodes at the same
        # point — and 1.0 once polished on them)
        step = polished(trial, x)
        if records_keep(level, step.cost, samples, at_floor):
            current, level, fit, x = trial, step.cost, step, step.x
            kept.append(what)
    if fit is None:
        return NumericsChoice(evaluator, None, None)
    for other in candidates[1:]:
        step = polished(current, np.asarray(other, dtype=float))
        if step.cost < fit.cost:
            fit = step
    grid = current.config.beam.nodes
    said = " and ".join(kept).replace("a finer grid", f"a finer grid ({grid} nodes, from {cfg.beam.nodes})")
    note = (f"the records ask for finer numerics: with {said} the fit goes from {first / samples:.3g} to "
            f"{fit.cost / samples:.3g} noise variances per sample; the identified model is polished on them (the "
            "config's numerics left a gap the parameters would compensate)")
    return NumericsChoice(current, fit, note)


#: One polished point as the identification keeps it: ``(from_index, x, F, evaluations, polish result)``.
Polished = tuple[int, np.ndarray, np.ndarray, int, Any]


def refine_numerics(evaluator: NativeEvaluator, polished: list[Polished], runner: Runner, budget: int,
                    noise: NoiseModel | None, evaluator_for: Callable[[BeamConfig], NativeEvaluator]
                    ) -> tuple[NativeEvaluator, list[Polished], str | None]:
    """:func:`numerics_for_records` on an identification's polished points: the evaluator on the numerics kept, the
    best polish on them in place of the first polished point (its objectives evaluated), and the line saying so
    (``None`` when the config's numerics stay)."""
    cfg = evaluator.config
    band_hz = excited_band([e.inputs for e in evaluator.experiments], cfg.time.dt)[1]
    choice = numerics_for_records(evaluator, [p[1] for p in polished], runner, budget=budget, band_hz=band_hz,
                                  noise=noise, prior=Prior.of(cfg, evaluator.space.names), modes=modal_data(cfg),
                                  evaluator_for=evaluator_for)
    if choice.polished is None:
        return evaluator, polished, None
    r = choice.polished
    f = np.asarray(runner(choice.evaluator, r.x[None, :]))[0]
    return choice.evaluator, [(polished[0][0], r.x, f, r.n_evaluations + 1, r), *polished[1:]], choice.note


def grid_adequacy(evaluator: NativeEvaluator, x: np.ndarray, noise: NoiseModel, stable: bool = True
                  ) -> tuple[GridAdvice, NumericalAdequacy]:
    """What ``identify`` says of the grid at its answer ``x`` (:func:`ebb_model.space.adequacy.grid_line` of the
    two): the grid advice for the records' band, and the numerical adequacy at the noise's white level with — for
    a ``stable`` model — the refined grid's shift of the answer (:func:`shift_between`, the residuals whitened by
    ``noise`` with the config's priors and measured modes).  The same advice ``diagnose`` gives at its baseline."""
    cfg, space, exps = evaluator.config, evaluator.space, evaluator.experiments
    band_hz = excited_band([e.inputs for e in exps], cfg.time.dt)[1]
    at = space.apply(cfg, x)
    advice = grid_advice(*at, band_hz=band_hz)
    adequacy = numerical_adequacy(*at, [(e.inputs, e.outputs) for e in exps], np.median(noise.std, axis=0),
                                  band_hz=band_hz, advice=advice)
    if not stable:
        return advice, adequacy
    fine = on_the_grid_of(cfg, adequacy_grid(*at, band_hz, advice))
    on_fine = NativeEvaluator(fine, space, exps, per=evaluator.per, stabilising=evaluator.stabilising)
    prior, modes = Prior.of(cfg, space.names), modal_data(cfg)
    shift = shift_between(space, x, ResidualEvaluator(evaluator, noise, prior, modes).residuals,
                          ResidualEvaluator(on_fine, noise, prior, modes).residuals, cfg.beam.nodes, fine.beam.nodes)
    return advice, replace(adequacy, shift=shift)
