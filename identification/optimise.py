"""Running the multi-objective GA with a checkpoint every generation and resume.

NSGA-II by default (NSGA-III selectable, with Das–Dennis reference directions).
After every generation the whole algorithm state (population, archive and its
``numpy.random.Generator``) is pickled atomically to ``checkpoint.pkl`` in the
output directory, so a run killed at any moment resumes from the last finished
generation and a seeded run gives the identical front whether or not it was
interrupted.
"""
from __future__ import annotations

import os
import pickle
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from pymoo.algorithms.moo.nsga2 import NSGA2
from pymoo.algorithms.moo.nsga3 import NSGA3
from pymoo.operators.sampling.rnd import FloatRandomSampling
from pymoo.util.ref_dirs import get_reference_directions

from ebb_model.io.output import atomic_path
from ebb_model.errors import ConfigError

from .problem import IdentificationProblem
from .runners import Runner

__all__ = ["ALGORITHMS", "ParetoSet", "check_settings", "knee_index", "knee_order", "optimise", "CHECKPOINT"]

ALGORITHMS = ("nsga2", "nsga3")
CHECKPOINT = "checkpoint.pkl"


@dataclass(frozen=True, eq=False)
class ParetoSet:
    """Non-dominated candidates of a run.

    Attributes
    ----------
    X
        Parameter values (n, dim), in the order of ``parameter_names``.
    F
        Objective values (n, n_obj), in the order of ``objective_names``.
    knee
        Index of the knee point (closest to the ideal point in objectives
        normalised to [0, 1] over the front).
    n_evaluations
        Model evaluations used by the GA.
    generations
        Generations run.
    history
        The search's convergence, one row per generation: the model evaluations so far, then the best value of
        each objective in that generation's non-dominated set (for one objective: the best so far); shape
        (generations, 1 + n_obj), empty for a result read back from an older file.
    """

    X: np.ndarray
    F: np.ndarray
    parameter_names: tuple[str, ...]
    objective_names: tuple[str, ...]
    knee: int
    n_evaluations: int
    generations: int
    history: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))


#: Name of the stabilising objective (the θ-scheme's largest growth factor), see :mod:`identification.objectives`.
GROWTH = "growth_factor"


def _knee_space(F: np.ndarray, names: Sequence[str] | None) -> tuple[np.ndarray, np.ndarray]:
    """Fit objectives normalised to [0, 1] over the eligible points, and which points are eligible.

    With a stabilising objective among ``names`` the knee is a compromise of the *fit* objectives among the
    strictly stable candidates (growth factor below 1; else the stable ones, else all): the growth factor is
    a constraint, not a term of the compromise — a nearly constant objective would otherwise pick the point.
    """
    F = np.asarray(F, dtype=float)
    eligible = np.ones(F.shape[0], dtype=bool)
    cols = np.arange(F.shape[1])
    if names is not None and GROWTH in names and F.shape[1] > 1:
        g = F[:, list(names).index(GROWTH)]
        for limit in (1.0 - 1e-12, 1.0 + 1e-12):
            if np.any(g <= limit):
                eligible = g <= limit
                break
        cols = np.array([j for j, n in enumerate(names) if n != GROWTH])
    Fe = F[:, cols]
    lo, hi = Fe[eligible].min(axis=0), Fe[eligible].max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    return (Fe - lo) / span, eligible


def knee_index(F: np.ndarray, names: Sequence[str] | None = None) -> int:
    """Knee of a front: the point nearest the ideal point after normalising each objective to [0, 1]
    (with ``names``: of the fit objectives, among strictly stable points, see :func:`_knee_space`)."""
    G, eligible = _knee_space(F, names)
    d = np.linalg.norm(G, axis=1)
    d[~eligible] = np.inf
    return int(np.argmin(d))


def knee_order(F: np.ndarray, names: Sequence[str] | None = None) -> np.ndarray:
    """Indices of a front ordered by distance to its knee (knee first), in the normalisation of :func:`knee_index`;
    points that are not eligible come last."""
    G, eligible = _knee_space(F, names)
    k = knee_index(F, names)
    d = np.linalg.norm(G - G[k], axis=1)
    d[~eligible] += 1e6
    d[k] = -1.0  # the knee first, also when another point coincides with it
    return np.argsort(d, kind="stable")


#: Key of the convergence history in the pymoo algorithm's ``data`` (pickled with the checkpoint).
HISTORY = "ebb_history"

#: ``callback(generation, n_evaluations, X, F)`` after every generation (current non-dominated set).
GenerationCallback = Callable[[int, int, np.ndarray, np.ndarray], None]


def check_settings(pop: int, generations: int, algorithm: str) -> None:
    """Check the GA's settings (what :func:`optimise` needs), so a caller can do it before writing anything.

    Raises
    ------
    ConfigError
        ``pop`` below 4, ``generations`` below 1 (or not whole numbers), or an unknown ``algorithm``.
    """
    for key, value, low in (("pop", pop, 4), ("generations", generations, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise ConfigError(f"`{key}` must be an integer >= {low}, got {value!r}")
    if algorithm not in ALGORITHMS:
        raise ConfigError(f"`algorithm`: unknown {algorithm!r}; allowed: {', '.join(ALGORITHMS)}")


class _Seeded(FloatRandomSampling):
    """pymoo's random first population with its first rows replaced by given candidates."""

    def __init__(self, initial: np.ndarray):
        super().__init__()
        self.initial = np.atleast_2d(np.asarray(initial, dtype=float))

    def _do(self, problem, n_samples: int, *args, random_state=None, **kwargs):  # type: ignore[override]
        X = super()._do(problem, n_samples, *args, random_state=random_state, **kwargs)
        k = min(len(self.initial), len(X))
        X[:k] = np.clip(self.initial[:k], *problem.bounds())
        return X


def _algorithm(name: str, pop: int, n_obj: int, initial: np.ndarray | None = None):
    sampling = FloatRandomSampling() if initial is None else _Seeded(initial)
    if name == "nsga2":
        return NSGA2(pop_size=pop, sampling=sampling)
    if name == "nsga3":
        parts = max(1, {1: pop, 2: pop - 1, 3: 12, 4: 6}.get(n_obj, 4))
        ref = get_reference_directions("das-dennis", n_obj, n_partitions=parts)
        return NSGA3(ref_dirs=ref, pop_size=max(pop, len(ref)), sampling=sampling)
    raise ConfigError(f"algorithm: unknown {name!r}; allowed: {', '.join(ALGORITHMS)}")


def _save_atomic(obj: object, path: Path) -> None:
    with atomic_path(path) as tmp, tmp.open("wb") as fh:
        pickle.dump(obj, fh, protocol=pickle.HIGHEST_PROTOCOL)
        fh.flush()
        os.fsync(fh.fileno())


def optimise(problem: IdentificationProblem, *, pop: int = 40, generations: int = 30, seed: int = 1,
             algorithm: str = "nsga2", out_dir: str | Path | None = None, resume: bool = False,
             runner: Runner | None = None, progress: bool = True,
             callback: GenerationCallback | None = None, initial: np.ndarray | None = None) -> ParetoSet:
    """Run the GA; checkpoint into ``out_dir`` each generation; resume from it on request.

    ``initial`` (rows of candidates, e.g. the records' start of :mod:`identification.data_start`) replaces the
    first members of the random first population (a resumed run keeps its own population).

    ``callback(generation, n_evaluations, X, F)`` is called after every
    generation with the current non-dominated candidates (e.g. to monitor
    convergence); it must not modify the arrays.

    Raises
    ------
    ConfigError
        Bad settings, or ``resume`` without a checkpoint in ``out_dir``.
    """
    check_settings(pop, generations, algorithm)
    ckpt = Path(out_dir) / CHECKPOINT if out_dir is not None else None
    if resume:
        if ckpt is None or not ckpt.exists():
            raise ConfigError(f"`resume`: no checkpoint {ckpt} to resume from")
        with ckpt.open("rb") as fh:
            algo = pickle.load(fh)
        problem = algo.problem
    else:
        algo = _algorithm(algorithm, pop, problem.n_obj, initial)
        algo.setup(problem, termination=("n_gen", generations), seed=seed, verbose=False)
    if runner is not None:
        problem.attach(runner)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=generations, initial=algo.n_gen - 1 if algo.n_gen else 0, unit="gen",
                   desc="identify", leave=False)
    try:
        while algo.has_next():
            algo.next()
            # kept in the algorithm's own data, so that the checkpoint carries it across a resume
            algo.data.setdefault(HISTORY, []).append(
                [float(problem.n_evaluations), *np.atleast_2d(algo.opt.get("F")).min(axis=0).tolist()])
            if ckpt is not None:
                _save_atomic(algo, ckpt)
            if bar is not None:
                bar.update(1)
            if callback is not None:
                opt = algo.opt
                callback(int(algo.n_gen - 1), int(problem.n_evaluations), np.atleast_2d(opt.get("X")),
                         np.atleast_2d(opt.get("F")))
    finally:
        if bar is not None:
            bar.close()
    res = algo.result()
    # no feasible (stable) candidate at all: the least infeasible ones, as pymoo keeps them
    best = algo.opt if res.X is None else res
    X = np.atleast_2d(best.X if best is res else best.get("X"))
    F = np.atleast_2d(best.F if best is res else best.get("F"))
    order = np.lexsort(F.T[::-1])
    X, F = X[order], F[order]
    knee = knee_index(F, problem.objective_names)
    history = np.array(algo.data.get(HISTORY, []), dtype=float).reshape(-1, 1 + F.shape[1])
    return ParetoSet(X, F, problem.parameter_names, problem.objective_names, knee,
                     problem.n_evaluations, int(algo.n_gen - 1), history)
