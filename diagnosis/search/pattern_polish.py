r"""How a modal pattern fit's starts are polished (:mod:`diagnosis.search.modal_pattern`): bounded least squares,
raced in heats.

A match has 8–23 starts (the effect's grid re-adjusted, aligned, from two baselines:
:mod:`diagnosis.search.pattern_starts`), and polishing each to convergence was most of a diagnosis' time.  The
starts race instead (:func:`raced`): every start is polished for a few iterations (a *heat*), the best few for
more, the best one to convergence.

The heats' difference Jacobians are three quarters of their residuals (a heat of 10 steps over 4–6 unknowns takes
39).  A secant Jacobian in the heats (Broyden's update after one difference Jacobian) halved that and ran the
two-set-up shaker bench's diagnosis in 108 s instead of 189 s, every match's χ² within the polish's ``ftol`` on it
and on three hint records — and changed two verdicts of the suite's broadband families (a stiffness loss on the
strip named a point mass with a sensor lag; a point mass on a compressed clamped–pinned beam, hint record 53,
``unexplained``): a heat's ranking decides which basin the match ends in, and a secant ranking is not the same
ranking.  The heats keep difference Jacobians.
"""
from __future__ import annotations

from typing import Callable, Iterable

import numpy as np
from scipy import optimize

__all__ = ["DIFF_STEP", "FINALISTS", "FTOL", "HEAT", "RACE", "least_squares_polish", "raced"]

Residual = Callable[[np.ndarray], np.ndarray]

#: Relative step of the polish's difference Jacobian.  The modes carry round-off of ~1e-13 relative (eigen
#: solvers, the Richardson difference), which the standard step (√eps ≈ 1.5e-8) turns into ~1e-5 errors of
#: derivatives that the uncertainties scale by up to 1e5: the polish then stalled in the valley where EI, N
#: and a clamp's compliance trade off (χ² 7.8e3 where 0.89 is reachable).  At 1e-6 the truncation error is
#: ~1e-6 and the round-off's share ~1e-7.
DIFF_STEP = 1e-6
#: Relative decrease of χ² per iteration below which a polish stops (``least_squares``' ``ftol``; its default
#: ``1e-8`` let the polishes crawl along the valleys where the baseline and an effect trade off: on the rig
#: family's pair, 400 evaluations of the final polish moved χ² from 1.0905 to 1.0863).  What is decided from a
#: match is by margins of the BIC margin (10, :attr:`~diagnosis.settings.Thresholds.bic_margin`) and factors of
#: 10 in χ², and its optimum is only a start of the time-domain refit; measured on that record's 14 fits: χ²
#: within 0.015 of the default's, the same order of the matches, the same basins, 64 → 18 s.
FTOL = 1e-3
#: Function evaluations (about as many iterations) each start's heat gets.  The starts' polishes ran 40
#: evaluations (median) to their race's end; measured on a two-set-up shaker bench and a broadband strip (64
#: matches, 8–23 starts each), ordered by their cost after 20 residuals (some four iterations), a start whose race
#: ended in the best basin (within 1e-3 of the best cost) was first in every match whose best is within 1e6 of
#: the records' scatter, and at most twelfth in matches of χ² 6e7 and more.
HEAT = 10
#: How many of a match's starts continue after their heat (the best by cost).
FINALISTS = 4
#: Function evaluations each finalist's polish gets before only the best one continues to convergence.
RACE = 60


def least_squares_polish(res: Residual, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, budget: int
                         ) -> optimize.OptimizeResult:
    """Bounded least squares of ``res`` from ``x0`` (clipped into ``[lo, hi]``) for at most ``budget`` function
    evaluations (difference Jacobians, :data:`DIFF_STEP`; :data:`FTOL`)."""
    return optimize.least_squares(res, np.clip(x0, lo, hi), bounds=(lo, hi), x_scale=hi - lo, diff_step=DIFF_STEP,
                                  ftol=FTOL, max_nfev=budget)


def raced(res: Residual, starts: Iterable[np.ndarray], lo: np.ndarray, hi: np.ndarray, budget: int
          ) -> optimize.OptimizeResult:
    """The best polish of ``res`` from ``starts``: every start a heat (:data:`HEAT` evaluations), the best
    :data:`FINALISTS` polished for :data:`RACE` more, the best of them to convergence (at most ``budget``
    evaluations each; a heat that converged is not polished again: its polish would start where it stopped)."""
    heats = sorted((least_squares_polish(res, x0, lo, hi, min(HEAT, budget)) for x0 in starts),
                   key=lambda sol: sol.cost)
    best = min((least_squares_polish(res, h.x, lo, hi, min(RACE, budget)) if h.status == 0 else h
                for h in heats[:FINALISTS]), key=lambda sol: sol.cost)
    if best.status == 0:       # stopped by the budget, not converged
        best = least_squares_polish(res, best.x, lo, hi, budget)
    return best
