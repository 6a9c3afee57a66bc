"""The polished basins of an identification: the knee's, the records' start's and the front's best fit, each
refined by the local polish (:mod:`identification.polish`), the lowest χ² first.

The GA's knee, the records' own start (:mod:`identification.data_start`) and the front's best-fitting point can
lie in different basins of a lightly damped record's output error; polishing each and taking the lowest makes the
identified model the best of local fits, never a silent local optimum of one.
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from .data_start import DataStart
from .modal_data import ModalData
from .native import NativeEvaluator
from .noise_model import NoiseModel, estimate_noise_model
from .optimise import ParetoSet, knee_order
from .polish import ResidualEvaluator, polish as polish_point, settle
from .prior import Prior
from .progress import Progress
from .runners import Runner

__all__ = ["FROM_START", "better_of", "noise_at", "polish_basins"]


def noise_at(evaluator: NativeEvaluator, x: np.ndarray) -> NoiseModel | None:
    """The noise model of every experiment from the residual of candidate ``x`` (the GA's knee: its residual's
    part coherent with the inputs, where a model error lies, does not enter the estimate), ``None`` when the
    candidate is unstable."""
    exps = evaluator.experiments
    sim = evaluator.simulate(x)
    if not sim.stable:
        return None
    return estimate_noise_model([e.inputs for e in exps], [e.outputs - y for e, y in zip(exps, sim.outputs)],
                                evaluator.config.time.dt)


def better_of(evaluator: NativeEvaluator, x: np.ndarray, start: DataStart | None) -> np.ndarray:
    """``x`` or the records' start, whichever fits the records better (the polish's sum of squared output errors,
    each sensor normalised by its spread, whatever the objectives are)."""
    if start is None:
        return x
    r = ResidualEvaluator(evaluator).evaluate(np.vstack([x, start.x]))
    return start.x if float(r[1] @ r[1]) < float(r[0] @ r[0]) else x


#: ``from_index`` of the polished point that started from the records' start (not a Pareto point).
FROM_START = -1


def polish_basins(pareto: ParetoSet, evaluator: Any, runner: Runner, k: int, budget: int,
                  on_progress: Callable[[Progress], None] | None, noise: NoiseModel | None = None,
                  prior: Prior | None = None, modes: ModalData | None = None, start: DataStart | None = None
                  ) -> list[tuple[int, np.ndarray, np.ndarray, int, Any]]:
    """Polish the ``k`` points nearest the knee (knee first), their residuals whitened by ``noise`` when given
    and the ``prior`` and measured ``modes`` added (the posterior's mode): ``(from_index, x, F, evaluations,
    result)``.

    With ``k >= 1`` the records' ``start`` is polished too (``from_index`` :data:`FROM_START`), and so is the
    front's point that fits the records best (by the polish's own χ²) when it is not among the ``k``: whichever
    polished point reaches the lowest χ² comes first.  The identified model is the best of local fits from
    different basins, never a silent local optimum of one — and what a longer search finds is polished, so more
    effort cannot give a worse answer than the default's stages do.  The best is polished again until it settles
    (:func:`identification.polish.settle`)."""
    out: list[tuple[int, np.ndarray, np.ndarray, int, Any]] = []
    n_done = pareto.n_evaluations
    todo = [(int(i), pareto.X[i]) for i in knee_order(pareto.F, pareto.objective_names)[:k]]
    if k >= 1 and pareto.X.shape[0] > 1:
        rv = np.asarray(runner(ResidualEvaluator(evaluator, noise, prior, modes), pareto.X), dtype=float)
        chi2 = np.where(np.all(np.isfinite(rv), axis=1), np.sum(rv * rv, axis=1), np.inf)
        n_done += pareto.X.shape[0]
        best = int(np.argmin(chi2))
        if np.isfinite(chi2[best]) and best not in [i for i, _ in todo]:
            todo.append((best, pareto.X[best]))
    if k >= 1 and start is not None:
        todo.insert(1, (FROM_START, start.x))
    for step, (i, x0) in enumerate(todo):
        r = polish_point(evaluator, x0, runner=runner, max_evaluations=budget, noise=noise, prior=prior,
                         modes=modes)
        f = np.asarray(runner(evaluator, r.x[None, :]))[0]
        n_ev = r.n_evaluations + 1
        n_done += n_ev
        out.append((i, r.x, f, n_ev, r))
        if on_progress is not None:
            on_progress(Progress("polish", step, n_done, r.x[None, :], f[None, :], 0))
    if len(out) >= 2:
        first = int(np.argmin([o[4].cost for o in out]))
        out.insert(0, out.pop(first))
    if out:
        # the identified point is where the polish settles (identification.polish.settle)
        i, _x, _f, n_ev, r = out[0]
        r = settle(evaluator, r, runner=runner, max_evaluations=budget, noise=noise, prior=prior, modes=modes)
        f = np.asarray(runner(evaluator, r.x[None, :]))[0]
        out[0] = (i, r.x, f, r.n_evaluations + 1 + n_ev - out[0][4].n_evaluations, r)
    return out
