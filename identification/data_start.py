"""A start read from the records: the basin of the global answer, whatever the config's nominal values.

Output-error fits of lightly damped records have a narrow valley along the stiffness-to-mass ratio (every
resonance moves with it, a fraction of a half-power bandwidth decides) and a long, flat one along the level (a
common scale of EI, ρA, c and N leaves every frequency where it is and scales the outputs): a GA started from
a config's nominal values and a local polish find the first but crawl along the second, and stop far from the
answer.  The records themselves fix both, before any search:

1. **Frequencies.**  The records' modes (:mod:`identification.record_poles`: averaged FRFs, a stabilised pole
   estimator and its stability chart — not the peaks of a noisy spectrum) are matched to the model's modes
   (:mod:`identification.start_modes`): the frequency scale ``k = √((EI/ρA)/(EI₀/ρA₀))`` and N that place them,
   and — where the model has parts a common scale leaves alone (a declared mass, a spring) — the level their
   pattern asks for, or where the pattern cannot say it (an unmodelled part zigzags the modes), the level at which
   the model's FRF magnitude meets the records'.
2. **Refinement in time.**  Around each, the output error is scanned along the frequency scale (and N, when it
   is unknown) with the damping lowered stage by stage (:data:`STAGES`: each stage's window is the previous
   one's resolution; a heavily damped model's cost is smooth where a lightly damped one's is a comb), and the
   level projected out in closed form: with EI, ρA, c and N scaled by ``s`` together the outputs scale by
   ``1/s`` exactly, so the best level of every trial is one inner product.
3. **Level.**  The best trial's level gives ρA (and EI, c, N with it) — unless step 1 gave it: then the
   amplitude would move the modes off the frequency scale found, and it is the less accurate of the two on a
   config's numerics.  A level outside the bounds is kept as a note that the run prints only where
   its final fit bears it out (:class:`DataStart`); the start's sign is no claim (an undeclared delay turns it
   as readily as a reversed force).

The GA's first population carries the start (:func:`identification.optimise.optimise`), and the polish runs from
it as well as from the GA's knee (:func:`identification.run.identify`).  The model evaluations run through the
identification's runner (worker processes or Dask), counted in ``DataStart.n_evaluations``
(``data_start`` in ``pareto.json``), apart from the search's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Sequence

import numpy as np

from ebb_model.acquisition.channel_delay import effective_delays
from ebb_model.errors import EbbError

from .polish import residual_scale
from .record_poles import frequency_response_estimate, record_modes
from .runners import Runner, SerialRunner
from .start_modes import (MATCH_TOLERANCE, Directions, alignments, family, pattern_level, scale_moves_modes,
                          spectrum_level)

__all__ = ["DataStart", "STAGES", "data_start"]

#: (relative half-window of the frequency scale, damping ratio at the lowest matched mode) per stage.
STAGES = ((0.06, 0.05), (0.015, 0.015), (0.004, 0.004), (0.001, 0.001))
#: Factors of the last stage's damping ratio tried at the end (the level's accuracy is the damping's).
DAMPING_FACTORS = 2.0 ** np.linspace(-1.5, 1.5, 13)
#: Trials per stage along the frequency scale.
TRIALS = 13
#: Samples per experiment the time-domain refinement uses (the record's start: it begins at rest).
MAX_SAMPLES = 1 << 15


@dataclass(frozen=True)
class DataStart:
    """What the records say, as a start for the search.

    Attributes
    ----------
    x
        The start (physical units, order of the unknowns), inside the bounds.
    modes_hz
        The records' modes [Hz] (:func:`identification.record_poles.record_modes`).
    level
        The records' level against the model at the frequency scale found (1: the model's own level; the
        outputs are ``level ×`` the model's at unit scale), NaN when the level is not free (EI or ρA known).
    level_note
        The records' level outside the bounds, in one sentence (``None`` when inside): a claim made at the start,
        which the run prints only where its final fit bears it out (:func:`identification.fit_hints.fit_hints`)
        and writes nowhere else.  Measured on the hint family (``tests/hint_family.py``: 64 broadband records,
        correct, with a withheld effect, an undeclared delay or filter): the start made it of 5 records whose
        units were right, the final fit bore it out on none.  The start makes no claim of a sign: a negative
        level here follows an undeclared delay as readily as a reversed force (measured: 3 records of the same
        family, each delayed), and the final fit's gains say a reversed sign where it holds.
    n_evaluations
        Model evaluations used.
    """

    x: np.ndarray
    modes_hz: np.ndarray
    level: float
    level_note: str | None = None
    n_evaluations: int = 0

    def to_dict(self, names: Sequence[str]) -> dict[str, Any]:
        """JSON-ready values."""
        return {"parameters": {n: float(v) for n, v in zip(names, self.x)},
                "modes_hz": [float(v) for v in self.modes_hz],
                "level": None if math.isnan(self.level) else float(self.level),
                "n_evaluations": int(self.n_evaluations)}


@dataclass(frozen=True, eq=False)
class ProjectedCost:
    """Output error of candidates with the level projected out (picklable; runs through any runner).

    ``evaluate(X)`` gives per candidate ``(cost, level)``: the sum over sensors of the squared error normalised
    by each sensor's spread, at the best common level ``a`` of the simulated outputs (``a = 1`` when the level
    is not free), and ``a``.  Refused candidates cost ``inf``.
    """

    evaluator: Any
    project: bool

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        out = np.empty((len(X), 2))
        exps = self.evaluator.experiments
        w = 1.0 / residual_scale(exps) ** 2        # the polish's normalisation of each sensor
        yy = float(sum(np.sum(e.outputs ** 2 * w) for e in exps))
        for j, x in enumerate(np.atleast_2d(X)):
            try:
                sim = self.evaluator.simulate(np.asarray(x, float))
            except (EbbError, ValueError, np.linalg.LinAlgError):
                out[j] = (np.inf, np.nan)
                continue
            if not sim.stable or not sim.outputs:
                out[j] = (np.inf, np.nan)
                continue
            sy = float(sum(np.sum(s * e.outputs * w) for s, e in zip(sim.outputs, exps)))
            ss = float(sum(np.sum(s * s * w) for s in sim.outputs))
            if not (np.isfinite(ss) and np.isfinite(sy)) or ss <= 0:
                out[j] = (np.inf, np.nan)
                continue
            a = sy / ss if self.project else 1.0
            out[j] = (yy - 2 * a * sy + a * a * ss, a)
        return out


def _head(evaluator: Any) -> Any:
    """``evaluator`` on the first :data:`MAX_SAMPLES` samples of every experiment."""
    exps = tuple(replace(e, inputs=e.inputs[:MAX_SAMPLES], outputs=e.outputs[:MAX_SAMPLES])
                 for e in evaluator.experiments)
    return replace(evaluator, experiments=exps)


def data_start(evaluator: Any, runner: Runner | None = None) -> DataStart | None:
    """The start the records give (module docstring); ``None`` when neither the frequency scale nor the damping
    is among the unknowns (nothing to read).

    Parameters
    ----------
    evaluator
        The native evaluator of the identification (its config, unknowns and experiments).
    runner
        Where batches of trials are evaluated (default: this process).
    """
    run = runner or SerialRunner()
    sp, cfg = evaluator.space, evaluator.config
    names = tuple(sp.names)
    fixed = {k: float(cfg.parameters[k].value) for k in ("EI", "rhoA", "c", "eta", "N") if k in cfg.parameters}
    if not any(n in names for n in ("EI", "rhoA", "c", "eta")):
        return None
    d0 = Directions(names, sp.lower, sp.upper, sp.nominal, fixed, 1.0)
    modes_at = family(evaluator, d0)
    if not modes_at:
        return None
    exps = evaluator.experiments
    dt = float(cfg.time.dt)
    recorded = record_modes([e.inputs for e in exps], [e.outputs for e in exps], dt, effective_delays(cfg))
    peaks = recorded.frequencies_hz
    k_lo, k_hi = d0.k_range()
    nyquist = 0.5 / dt
    if peaks.size:
        starts = alignments(peaks, recorded.support, modes_at, k_lo, k_hi, nyquist)
    else:
        starts = []
    nominal_n = modes_at[len(modes_at) // 2][0]
    if not starts:
        starts = [(min(max(1.0, k_lo), k_hi), nominal_n)]
    # the damping's reference: the lowest mode the peaks show (else the model's first)
    head = _head(evaluator)
    cost_ev = ProjectedCost(head, d0.level_free)
    record_frf: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    count = 0

    def trial_costs(trials: list[tuple[float, float, float | None]], d: Directions) -> np.ndarray:
        nonlocal count
        X = np.array([d.candidate(k, z, nv) for k, z, nv in trials])
        count += len(X)
        return np.asarray(run(cost_ev, X), float)

    def refine(k: float, nv: float | None, d: Directions) -> tuple[float, float, float, float | None, float]:
        """Steps 2 of the module docstring from ``(k, nv)``: ``(cost, k, ζ, N, level)``."""
        zeta = STAGES[0][1]
        cost, level = math.inf, math.nan
        for window, z_stage in STAGES:
            zs = sorted({zeta, z_stage}) if (d.has("c") or d.has("eta")) else [zeta]
            ks = k * (1.0 + window * np.linspace(-1.0, 1.0, TRIALS))
            ks = ks[(ks >= k_lo * (1 - 1e-12)) & (ks <= k_hi * (1 + 1e-12))]
            trials = [(float(kk), float(z), nv) for kk in ks for z in zs]
            if not trials:
                break
            res = trial_costs(trials, d)
            j = int(np.argmin(res[:, 0]))
            if res[j, 0] < cost or not math.isfinite(cost):
                k, zeta, _ = trials[j]
                cost, level = float(res[j, 0]), float(res[j, 1])
            if d.has("N") and nv is not None:
                i = names.index("N")
                span = (d.upper[i] - d.lower[i]) * window * 4.0
                nvs = np.clip(nv + span * np.linspace(-1.0, 1.0, 9), d.lower[i], d.upper[i])
                trials = [(k, zeta, float(v)) for v in nvs]
                res = trial_costs(trials, d)
                j = int(np.argmin(res[:, 0]))
                if res[j, 0] < cost:
                    nv = trials[j][2]
                    cost, level = float(res[j, 0]), float(res[j, 1])
        if d.has("c") or d.has("eta"):
            # the damping on a finer grid at the end: the level projected out depends on it (a peak's height is
            # ∝ 1/ζ), and the stages' values are a factor of 4 apart
            trials = [(k, float(z), nv) for z in zeta * DAMPING_FACTORS]
            res = trial_costs(trials, d)
            j = int(np.argmin(res[:, 0]))
            if res[j, 0] < cost:
                zeta, cost, level = trials[j][1], float(res[j, 0]), float(res[j, 1])
        return cost, k, zeta, nv, level

    best: tuple[float, float, float, float | None, float, Directions, bool] | None = None
    for k0, nv0 in starts:
        f_model = dict(modes_at)[nv0]
        f_model = f_model[f_model > 0]
        seen = f_model[np.min(np.abs(np.log(k0 * f_model[:, None] / peaks[None, :])), axis=1) < MATCH_TOLERANCE] \
            if peaks.size else f_model[:1]
        d = Directions(names, sp.lower, sp.upper, sp.nominal, fixed,
                        2 * math.pi * float(seen[0] if seen.size else f_model[0]))
        pattern = pattern_level(evaluator, d, k0, nv0, recorded, (k_lo, k_hi)) if d.level_free else None
        if pattern is None and d.level_free and scale_moves_modes(evaluator, d.candidate(k0, 0.0, nv0, clip=False)):
            # the pattern undecided where the level moves the modes: the spectrum's magnitude gives it
            if record_frf is None:
                record_frf = frequency_response_estimate([e.inputs for e in head.experiments],
                                                         [e.outputs for e in head.experiments], dt)
            zeta0 = float(np.median(recorded.damping)) if peaks.size else STAGES[-1][1]
            level0, used = spectrum_level(head, d, k0, nv0, zeta0, record_frf)
            count += used
            pattern = None if level0 is None else (k0, level0, nv0)
        if pattern is not None:
            k0, level0, nv0 = pattern
            d = d.rebased(level0)
            nv0 = None if nv0 is None else nv0 * level0
        trial = refine(k0, nv0, d)
        if best is None or trial[0] < best[0]:
            best = (*trial, d, pattern is not None)
    assert best is not None
    # the level found moves the modes where the model has parts the common scale leaves alone (a declared point
    # mass, a spring, a fixed axial force): the frequency scale is searched again at that level, and again
    cost, k, zeta, nv, level, d, from_pattern = best
    note: str | None = None
    if from_pattern:
        # the level is the modes' pattern's (or the spectrum's): the amplitude's would move the modes off the
        # frequency scale found, and on a config's numerics it is the less accurate (the strip with a tip mass on
        # 80 nodes and the cubic: the pattern's ρA 0.6 % low, the amplitude's 4.4 % high; with an unmodelled 10 g
        # mass besides, the spectrum's 11.7 % high, the amplitude's 2.45 times the truth)
        x = d.candidate(k, zeta, nv)
    elif d.level_free and math.isfinite(level):
        scale = 1.0 / abs(level) if level != 0 else 1.0
        raw = d.candidate(k, zeta, nv)
        i, j = names.index("EI"), names.index("rhoA")
        # the scales EI and rhoA both allow (c and N follow; clipped on their own, they move no frequency)
        lo = max(d.lower[i] / raw[i], d.lower[j] / raw[j])
        hi = min(d.upper[i] / raw[i], d.upper[j] / raw[j])
        reach = min(max(scale, lo), hi) if lo <= hi else scale
        x = d.candidate(k, zeta, nv, reach)
        if reach != scale:
            note = (f"the records' level asks for EI {raw[i] * scale:.4g} and rhoA {raw[j] * scale:.4g}, outside "
                    f"their bounds ({d.lower[i]:.4g}–{d.upper[i]:.4g}, {d.lower[j]:.4g}–{d.upper[j]:.4g}): the "
                    f"records are {reach / scale:.3g} times what the bounds allow — check the records' units and "
                    "calibration, or widen the bounds")
    else:
        x = d.candidate(k, zeta, nv)
        level = math.nan
    return DataStart(x, peaks, level, note, count)
