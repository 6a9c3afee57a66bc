"""Where a modal pattern fit starts, and how it leaves a wrong basin (:mod:`diagnosis.search.modal_pattern`).

A pattern fit's cost is sharp in an effect's place and flat along the scale the modes cannot see (every
force-like constant times one ratio leaves the modes alone); a baseline that compensated an effect can hold its
unknowns where no local step from the effect's grid reaches the effect's basin.  These are the fit's ways out:

* :func:`profiled` — the baseline unknowns re-adjusted at a start of the effect's grid (Gauss–Newton steps with
  the baseline's :func:`jacobian`);
* :func:`room` — the unseen scale moved so that EI, or the held ρA, is off its bound;
* :func:`within` — a scale kept inside every variable's bounds at once;
* :func:`aligned` — the modes' common scale aligned to the measured ones before a start is polished;
* :func:`best_per_place` — the best start at every place of the effect's grid, not only the best few overall;
* :func:`place_profiled` — the place profiled on a fine grid around the polished match's when that match is not
  at the records' scatter (the other variables re-fitted at each place, :func:`fixed_place_fits`), its other
  minima polished;
* :func:`amplitude_scale` — the unseen scale, read from the records' amplitudes.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy.optimize import OptimizeResult

from ebb_model.errors import EbbError

from ..effects import Effect
from ..problem.fitting import GapProblem

__all__ = ["ALIGNED", "ALIGN_STEPS", "ON_BOUND", "PROFILE_BUDGET", "PROFILE_MINIMA", "PROFILE_POINTS", "aligned",
           "amplitude_scale", "at_nominal_density", "best_per_place", "fixed_place_fits",
           "jacobian", "place_profiled", "profiled", "room", "within"]

#: Starts of a pattern fit from the effect's grid with the modes' common scale aligned (:func:`aligned`), and
#: the scales tried between EI's bounds (log-spaced: 400 steps over a ×16 range are 0.35 % in frequency, within
#: a few measured standard errors of a light mode's; the polish does the rest).
ALIGNED = 2
ALIGN_STEPS = 400
#: EI within this factor of a bound is on it (:func:`room`).
ON_BOUND = 1.01
#: Places tried by :func:`place_profiled` over one step of the effect's grid either side of the match's place
#: (17 over two of the point mass's 13 grid steps: 0.7 % of the beam apart), and the evaluations each fixed
#: place's re-fit gets (measured: 5–9 used; the profile of a 0.25 kg mass on a 1.1 m beam took 1.1 s).
PROFILE_POINTS = 17
PROFILE_BUDGET = 30
#: Minima of the profile other than the match's own place that are polished.
PROFILE_MINIMA = 2

Residual = Callable[[np.ndarray], np.ndarray]
Modes = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
#: A bounded least-squares polish: residual, start, lower and upper bounds, evaluations.
Polish = Callable[[Residual, np.ndarray, np.ndarray, np.ndarray, int], OptimizeResult]


def jacobian(res: Callable[[np.ndarray], np.ndarray], x: np.ndarray, k: int, span: np.ndarray) -> np.ndarray:
    """Forward-difference Jacobian of ``res`` w.r.t. the first ``k`` variables at ``x``."""
    r0 = res(x)
    cols = []
    for j in range(k):
        dx = 1e-6 * span[j]
        x1 = x.copy()
        x1[j] += dx
        cols.append((res(x1) - r0) / dx)
    return np.column_stack(cols)


def profiled(res: Callable[[np.ndarray], np.ndarray], x: np.ndarray, J: np.ndarray, lo: np.ndarray,
              hi: np.ndarray, steps: int = 2) -> tuple[np.ndarray, float]:
    """``x`` with its first ``J.shape[1]`` (baseline) variables moved by Gauss–Newton steps of fixed ``J``,
    kept while the cost falls; the point and its cost."""
    k = J.shape[1]
    r = res(x)
    cost = float(r @ r)
    for _ in range(steps):
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        x1 = x.copy()
        x1[:k] = np.clip(x[:k] + step, lo[:k], hi[:k])
        r1 = res(x1)
        c1 = float(r1 @ r1)
        if not c1 < cost:
            break
        x, r, cost = x1, r1, c1
    return x, cost


def best_per_place(trials: list[np.ndarray], grid: list[tuple[np.ndarray, float]]) -> list[np.ndarray]:
    """The re-adjusted start of least cost at each value of an effect's second variable (a place) on its grid:
    the pattern's cost is sharp in the place, and the best few starts of the whole grid can all lie at wrong
    places (measured: a 0.22 kg mass at 0.62 L on a beam in tension, its baseline's N at 0.36 of the value the
    held ρA asks for: the four best starts at other places, χ² 2.9e5; the best start of the nearest place on the
    grid, 0.66 L, reaches 21 for 9 modes — the truth's own values polish to the same — for 10 % more time)."""
    best: dict[float, tuple[np.ndarray, float]] = {}
    for s, g in zip(trials, grid):
        if float(s[1]) not in best or g[1] < best[float(s[1])][1]:
            best[float(s[1])] = g
    return [g[0] for g in best.values()]


def aligned(modes: Modes, cost: Callable[[np.ndarray, np.ndarray], np.ndarray], z: np.ndarray, ei: int,
            lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float]:
    """``z`` with EI (index ``ei``) scaled so that the model's modes ``modes(z)``, all multiplied by
    ``√(EI'/EI)``, best match the measured ones by ``cost`` (of a stack of the model's frequency sets, one per
    row, and its damping ratios: a value per row; exact without an axial load, a start otherwise), and that
    match's cost; ``z`` and ``inf`` if the model cannot be evaluated at ``z``."""
    try:
        f, zeta = modes(z)
    except (EbbError, ValueError, np.linalg.LinAlgError):
        return z, math.inf
    if not (z[ei] > 0.0 and lo[ei] > 0.0):
        return z, math.inf
    ratios = np.geomspace(lo[ei] / z[ei], hi[ei] / z[ei], ALIGN_STEPS)
    costs = cost(f[None, :] * np.sqrt(ratios)[:, None], zeta)      # every scale at once
    k = int(np.argmin(costs))
    out = z.copy()
    out[ei] = z[ei] * ratios[k]
    return out, float(costs[k])


def room(problem: GapProblem, beta: np.ndarray, free: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``beta`` with every force-like constant multiplied by one ratio (the same modes: see
    :func:`diagnosis.search.modal_pattern.pattern_fit`'s amplitude scale) so that EI sits at the geometric centre
    of its bounds, as far as the other unknowns' bounds allow — when ρA is held and EI lies on a bound (within
    :data:`ON_BOUND`), else ``beta`` as it is: the modes see only the ratio, and a baseline that compensated
    an effect can hold ρA where the ratio the records ask for puts EI beyond its bound (measured: a withheld tip
    mass on a broadband strip record, EI on its bound ×4 the nominal, every match stuck at χ² 3.6e10; at the
    centre the transducer's mass matched at 1.6).  When EI is inside its bounds but the held ρA lies on one, ρA
    goes to its centre instead (measured: a compressed clamped–pinned beam with a withheld 0.25 kg mass, ρA on its
    upper bound ×5.6 the truth, EI at 0.36 of it: the ratio the modes ask for put EI at twice its upper bound, the
    mass's match stuck at χ² 1.5e4 while a short soft segment at the mass's place matched at 25).  The scale is set
    afterwards from the amplitudes."""
    names = list(problem.space.names)
    if np.all(free) or "EI" not in names:
        return beta

    def on_bound(k: int) -> bool:
        return beta[k] > 0.0 and not lo[k] * ON_BOUND < beta[k] < hi[k] / ON_BOUND

    # EI on a bound: EI to its centre; else the held ρA on a bound: ρA to its centre (EI, free, then reaches
    # every ratio the boxes allow on either side)
    held = [k for k in range(len(names)) if not free[k] and names[k] == "rhoA"]
    i = names.index("EI") if on_bound(names.index("EI")) else held[0] if held and on_bound(held[0]) else None
    if i is None or not lo[i] > 0.0:
        return beta
    return beta * within(math.sqrt(lo[i] * hi[i]) / beta[i], beta, lo, hi)


def at_nominal_density(problem: GapProblem, beta: np.ndarray, free: np.ndarray, lo: np.ndarray, hi: np.ndarray
                       ) -> np.ndarray | None:
    """``beta`` with every force-like constant multiplied by one ratio (the same modes, as in :func:`room`) that
    brings the held ρA to the config's value, as far as the unknowns' bounds allow; ``None`` when ρA is not held
    or no ratio moves it by more than 1 %.  The config's ρA is the user's value: holding it keeps the ratios the
    records' modes ask for near the centre of the box the config's bounds were drawn around."""
    names = list(problem.space.names)
    held = [k for k in range(len(names)) if not free[k] and names[k] == "rhoA"]
    if not held or not beta[held[0]] > 0.0:
        return None
    k = held[0]
    lam = within(float(problem.space.nominal[k]) / beta[k], beta, lo, hi)
    return None if abs(lam - 1.0) <= 0.01 else beta * lam


def within(lam: float, values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """``lam`` clipped to the ratios that keep every one of ``values`` multiplied by it inside ``[lo, hi]``; 1 if
    no ratio does.  (A scale clipped at a bound variable by variable changes the modes: measured, a pattern χ² of
    3.5e5 went to 1.1e8 when the amplitudes asked for ×16 and EI stopped at its bound while ρA did not.)"""
    pos, neg = values > 0.0, values < 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        top = np.min(np.concatenate([hi[pos] / values[pos], lo[neg] / values[neg]]), initial=np.inf)
        bottom = np.max(np.concatenate([lo[pos] / values[pos], hi[neg] / values[neg]]), initial=0.0)
    return min(max(lam, bottom), top) if bottom <= top else 1.0


def fixed_place_fits(res: Residual, x: np.ndarray, j: int, places: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                     polish: Polish) -> tuple[list[np.ndarray], list[float]]:
    """``x`` with its variable ``j`` (a place) at each of ``places`` and every other variable re-fitted from ``x``
    (``polish`` for :data:`PROFILE_BUDGET` evaluations, inside ``[lo, hi]``): those points and their costs
    ``res·res``."""
    others = np.arange(x.size) != j
    points, costs = [], []
    for v in places:
        z = x.copy()
        z[j] = v

        def held(y: np.ndarray, z: np.ndarray = z) -> np.ndarray:
            w = z.copy()
            w[others] = y
            return res(w)

        sol = polish(held, z[others], lo[others], hi[others], PROFILE_BUDGET)
        z[others] = sol.x
        points.append(z)
        costs.append(2.0 * float(sol.cost))
    return points, costs


def place_profiled(res: Residual, x: np.ndarray, j: int, step: float, lo: np.ndarray, hi: np.ndarray,
                   polish: Polish) -> list[np.ndarray]:
    """The local minima of the profile of ``res``'s cost over its variable ``j`` (a place), best first, at most
    :data:`PROFILE_MINIMA`: at :data:`PROFILE_POINTS` places within ``step`` either side of ``x[j]``
    (:func:`fixed_place_fits`); ``x``'s own place is not one of them.

    A polished match at a wrong place can be a basin of its own: the other unknowns compensate the place, and a
    free polish does not leave it (measured: a compressed clamped–pinned beam with a withheld 0.25 kg mass at
    0.523 L, the mass's match at 0.498 L — 0.3 of a grid step off — with N on its upper bound in tension, χ²
    1.5e4; the profile's other minimum, at 0.518 L, re-fitted to 2.0e4 with N in compression, and polished free
    from there to 9.0 for 12 modes, N and EI within 3 % of the truth's ratio to the held ρA)."""
    places = np.unique(np.clip(np.linspace(x[j] - step, x[j] + step, PROFILE_POINTS), lo[j], hi[j]))
    points, costs = fixed_place_fits(res, x, j, places, lo, hi, polish)
    own = int(np.argmin(np.abs(places - x[j])))
    minima = [i for i in range(len(places)) if i != own
              and costs[i] < min(costs[i - 1] if i > 0 else np.inf, costs[i + 1] if i + 1 < len(places) else np.inf)]
    return [points[i] for i in sorted(minima, key=lambda i: costs[i])[:PROFILE_MINIMA]]


def amplitude_scale(problem: GapProblem, effect: Effect | None, z: np.ndarray) -> float | None:
    """``λ`` with measured ≈ simulated / λ on the fit windows (least squares) at the baseline unknowns and effect
    variables ``z``, ``None`` if it cannot be had: multiplying every force-like constant by ``λ`` divides the
    response by ``λ`` and leaves the modes alone."""
    p = problem.space.dim
    try:
        sims = problem.simulate(z[:p], effect, z[p:] if effect is not None else None)
    except (EbbError, ValueError, np.linalg.LinAlgError):
        return None
    num = den = 0.0
    with np.errstate(over="ignore", invalid="ignore"):   # a diverging candidate: rejected below
        for y, r in zip(sims, problem.records):
            if y is not None:
                a, b = y / problem.noise_std, r.outputs[:r.fit_end] / problem.noise_std
                num, den = num + float(np.sum(a * b)), den + float(np.sum(a * a))
    if not (num > 0 and den > 0 and np.isfinite(num / den)):
        return None
    return den / num
