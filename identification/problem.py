"""The identification as a pymoo ``Problem``: unknowns, bounds, objectives, population evaluation.

Following pymoo's roles (Problem / Algorithm / Result kept apart): the problem
declares the parameter names, bounds and objective names and evaluates a whole
population at once (``F`` of shape (n, n_obj)) through an injected runner.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from pymoo.core.problem import Problem

from .runners import Runner, SerialRunner

__all__ = ["Constrained", "IdentificationProblem"]


class Constrained:
    """An evaluator as the runners see it for the GA: ``evaluate(X)`` gives the objectives and the stability
    constraint side by side (:meth:`~identification.objectives.ObjectiveFunction.evaluate_constrained`);
    ``close`` reaches the evaluator's own (an FMU's instances)."""

    def __init__(self, evaluator: Any):
        self.evaluator = evaluator

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        """``[F | G]`` of a population ``X``."""
        return self.evaluator.evaluate_constrained(X)

    def close(self) -> None:
        """Close the evaluator when it holds resources."""
        close = getattr(self.evaluator, "close", None)
        if callable(close):
            close()


class IdentificationProblem(Problem):
    """Multi-objective output-error identification, the finite beam's stability as its constraint.

    Parameters
    ----------
    evaluator
        Picklable evaluator (``evaluate(X) -> F``) with ``space`` and ``n_obj``.
    objective_names
        Names of the objectives, in order.
    runner
        Parallel runner; not pickled with the problem (re-attach after loading
        a checkpoint with :meth:`attach`).
    """

    def __init__(self, evaluator: Any, objective_names: tuple[str, ...], runner: Runner | None = None):
        space = evaluator.space
        super().__init__(n_var=space.dim, n_obj=len(objective_names), n_ieq_constr=1, xl=np.asarray(space.lower),
                         xu=np.asarray(space.upper))
        self.evaluator = evaluator
        self.constrained = Constrained(evaluator)
        self.parameter_names = tuple(space.names)
        self.objective_names = tuple(objective_names)
        self.runner: Runner = runner or SerialRunner()
        self.n_evaluations = 0

    def attach(self, runner: Runner) -> None:
        """Use ``runner`` from now on."""
        self.runner = runner

    def _evaluate(self, X: np.ndarray, out: dict, *args: Any, **kwargs: Any) -> None:
        FG = self.runner(self.constrained, np.asarray(X, dtype=float))
        self.n_evaluations += len(X)
        out["F"] = FG[:, :-1]
        out["G"] = FG[:, -1:]

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["runner"] = None
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        if self.runner is None:
            self.runner = SerialRunner()
