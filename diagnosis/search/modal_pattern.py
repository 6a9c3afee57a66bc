r"""Which effect, by its modal pattern: how each candidate moves the frequencies and damping ratios of the modes.

Effects that act through the mass and stiffness distribution all shift the
modes, and a baseline fit absorbs part of every shift into EI, ρA and N; what
tells them apart is *how the shift depends on the mode* — a foundation adds the
same amount to every ω², rotary inertia grows with the wavenumber squared, a
point mass follows the mode shape squared at its position, a compliant clamp
moves the low modes most, Kelvin–Voigt damping ratios grow with ω.

For every structural effect of the catalogue (and for the baseline alone) the
measured modes (:mod:`diagnosis.search.modal_estimate`) are fitted by the model's
own discrete modes, :func:`ebb_model.modal.modal.discrete_frequencies`, over the
baseline unknowns *and* the effect together — the baseline is profiled out
globally, not linearised at the point where it compensated the effect:

.. math::  \chi^2_E = \min_{\beta, s} \sum_i
           \Big(\frac{f_i(\beta, s) - \hat f_i}{\sigma_{f,i}}\Big)^2
         + \Big(\frac{\zeta_i(\beta, s) - \hat\zeta_i}{\sigma_{\zeta,i}}\Big)^2
         + \Big\lVert\frac{\beta - \hat\beta}{\beta_{hi} - \beta_{lo}}\Big\rVert^2 .

Measured mode :math:`i` is compared with the model mode :math:`j(i)` it matches: the increasing assignment of
least cost (:mod:`diagnosis.search.mode_match`), which may pass over up to :data:`SKIPPED` of the model's modes
(one weakly excited or at a sensor's node is not among the measured ones); :math:`f_i` above stands for
:math:`f_{j(i)}`.

The uncertainties are the estimate's standard errors combined with the
model's own discretisation error of each mode (the change of its frequency and
damping on the refined grid of :func:`ebb_model.space.adequacy.refined_grid`: the
grid's pattern is thus part of every comparison, and an effect must explain
more than it).  The last term only settles the directions the modes cannot see
(EI and ρA move the frequencies only through their ratio).  The fit starts
from the best of a coarse grid of the effect, with the baseline unknowns at the
baseline's values and at the config's nominal ones
(:func:`diagnosis.candidates.score.trial_values`; the starts raced in heats,
:func:`diagnosis.search.pattern_polish.raced`; only the compared modes are
computed, :func:`ebb_model.modal.modal.discrete_frequencies` with ``n_modes``).  Its
optimum is a start of the effect's time-domain refit that lies in the right
basin even when the baseline had compensated the effect — a one-sided score
test then sees nothing, the modal pattern still does.  Signal-level effects
(lags, drift, stretching) do not move the linear modes and have no pattern of
their own.
"""
from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np
from scipy import optimize

from scipy import stats

from ebb_model.space.adequacy import refined_grid
from ebb_model.errors import EbbError
from ebb_model.modal.modal import discrete_frequencies

from ..effects import Catalogue, Effect, variables_for
from ..problem.fitting import GapProblem
from .modal_estimate import MeasuredModes
from .mode_match import ModalEvidence, compared, mode_cost
from ..candidates.score import MASS_GRID, trial_values
from .pattern_polish import least_squares_polish, raced
from .pattern_starts import (ALIGNED, aligned, amplitude_scale, at_nominal_density, best_per_place,
                             fixed_place_fits, jacobian, place_profiled, profiled, room, within)
from .workers import side_by_side

__all__ = ["PatternFit", "amplitude_screened", "modal_evidence", "moves_modes", "pattern_fit",
           "pattern_fits", "time_invariant"]

#: Relative floor of the damping ratios' uncertainty (the estimate of a damping ratio carries what the
#: oscillator model leaves out, e.g. the small phase of a lag).
DAMPING_FLOOR = 0.005
#: How many of the grid's best starts are polished when the effect has a position (the pattern's cost is
#: sharp: a point mass 4 cm off its position on the grid's best start can end in another basin); two otherwise.
STARTS = 4
#: Value of χ² for a model that cannot be evaluated.
FAILED = 1e12
#: Model modes beyond the measured ones that a match may pass over (:func:`matched`): a mode weakly excited or
#: at a sensor's node is not among the measured ones, and the measured modes are then the model's with a gap
#: (measured: a clamped–pinned beam with a withheld spring near the fourth mode's node, its 45 Hz mode absent
#: from the estimate; matched index to index, every effect's pattern was off by one mode from the fourth on, χ²
#: 8e6 for the best, the spring itself 1e9).
SKIPPED = 2
#: Probability below which a match's χ² is beyond the records' scatter (its upper quantile for twice the modes'
#: number of terms): a match of a place's effect beyond it has its place profiled
#: (:func:`diagnosis.search.pattern_starts.place_profiled`).  The right effect's matches measured 9–21 for 8–12
#: modes (the quantile: 42–51), a wrong basin's 1e3 and more.
SCATTER = 1e-3
#: Share of an unknown's span within which a pattern fit's value counts as on its bound: a match beyond the
#: scatter is made again at the config's ρA (:func:`pattern_fit`) only when a baseline unknown ended there — the
#: sign that the box, not the records, stopped it (measured: every wrong effect's match is beyond the scatter, and
#: retrying them all doubled a two-set-up diagnosis' time, 208 → 394 s, with no verdict changed).
ON_BOUND = 1e-3


@dataclass(frozen=True)
class PatternFit:
    """Best match of the measured modes by one effect (or the baseline alone, ``label == "baseline"``)."""

    label: str
    chi2: float
    beta: np.ndarray
    s: np.ndarray
    freq_hz: np.ndarray
    damping: np.ndarray
    #: the same effect's matches from the other baselines that are within the records' scatter too (the modes
    #: cannot choose between them: the time-domain refit starts from each, :func:`pattern_fits`)
    others: tuple["PatternFit", ...] = ()


def _modes(problem: GapProblem, beta: np.ndarray, effect: Effect | None, s: np.ndarray | None, m: int,
           *, refined: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The model's lowest modes, up to ``m + SKIPPED`` of them (at least ``m``): frequencies [Hz], damping."""
    model = problem.model(beta, effect, s)
    cfg = refined_grid(model.config) if refined else model.config
    f, z = discrete_frequencies(cfg, model.params, m + SKIPPED)
    if f.size < m:
        raise EbbError(f"the model has {f.size} modes, {m} measured")
    return f[:m + SKIPPED], z[:m + SKIPPED]


def modal_evidence(problem: GapProblem, beta: np.ndarray, measured: MeasuredModes) -> ModalEvidence:
    """The measured modes with their comparison uncertainty: standard error and the model grid's own error
    of each mode at ``beta`` (module docstring; the grid's error of the model mode nearest in frequency)."""
    m = measured.freq_hz.size
    f, z = _modes(problem, beta, None, None, m)
    f_fine, z_fine = _modes(problem, beta, None, None, m, refined=True)
    k = min(f.size, f_fine.size)
    near = np.argmin(np.abs(f[None, :k] - measured.freq_hz[:, None]), axis=1)
    sf = np.hypot(measured.freq_std, np.abs(f_fine[:k] - f[:k])[near])
    sz = np.sqrt(measured.damping_std ** 2 + ((z_fine[:k] - z[:k]) ** 2)[near]
                 + (DAMPING_FLOOR * measured.damping) ** 2)
    return ModalEvidence(measured, np.maximum(sf, 1e-9 * measured.freq_hz), np.maximum(sz, 1e-12))


def moves_modes(problem: GapProblem, beta: np.ndarray, effect: Effect) -> bool:
    """Whether ``effect`` changes the linear beam (a structural effect) rather than a signal or the axial force."""
    s = np.asarray(trial_values(effect.lower, effect.upper, effect.off)[-1])
    cfg, params = problem.space.apply(problem.config, np.asarray(beta, dtype=float))
    moved = effect.apply(cfg, params, s)
    return moved.config is not cfg or moved.params != params


def time_invariant(problem: GapProblem, beta: np.ndarray, effect: Effect) -> bool:
    """Whether ``effect`` keeps the model linear and time-invariant (everything but a drifting axial load and
    stretching): then the measured modes' oscillators can represent what it does to the records."""
    s = np.asarray(trial_values(effect.lower, effect.upper, effect.off)[-1])
    moved = problem.model(beta, effect, s)
    return moved.time_invariant


class _ModesAt:
    """The model's compared modes at a point ``z`` (baseline unknowns, then the effect's), each point computed
    once: a fit's starts, its profiled grid, its polishes' first points and its final modes revisit points
    already evaluated (measured: 13 % of a point-mass diagnosis's evaluations).  A point the model cannot be
    evaluated at raises the same error each time."""

    def __init__(self, problem: GapProblem, effect: Effect | None, p: int, m: int):
        self._problem, self._effect, self._p, self._m = problem, effect, p, m
        self._seen: dict[bytes, tuple[np.ndarray, np.ndarray] | Exception] = {}

    def __call__(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = z.tobytes()
        if key not in self._seen:
            p = self._p
            try:
                self._seen[key] = _modes(self._problem, z[:p], self._effect,
                                         z[p:] if self._effect is not None else None, self._m)
            except (EbbError, ValueError, np.linalg.LinAlgError) as exc:
                self._seen[key] = exc
        found = self._seen[key]
        if isinstance(found, Exception):
            raise found
        return found[0].copy(), found[1].copy()


def _residual(ev: ModalEvidence, beta0: np.ndarray, span: np.ndarray, modes: _ModesAt, z: np.ndarray
              ) -> np.ndarray:
    p = beta0.size
    prior = (z[:p] - beta0) / span
    try:
        f, zeta = modes(z)
    except (EbbError, ValueError, np.linalg.LinAlgError):
        return np.concatenate([np.full(2 * ev.n_modes, np.sqrt(FAILED / (2 * ev.n_modes))), prior])
    f, zeta = compared(ev, f, zeta)
    return np.concatenate([(f - ev.measured.freq_hz) / ev.freq_sigma,
                           (zeta - ev.measured.damping) / ev.damping_sigma, prior])


def _free(problem: GapProblem, effect: Effect | None) -> np.ndarray:
    """Which variables the pattern fit moves: all but ρA when EI is an unknown too and the modes see only their
    ratio (the time-domain refit then sets the scale from the amplitudes) — all where a common scale of the beam's
    unknowns moves the modes (:attr:`GapProblem.level_seen`: a declared mass or spring).  Held at the baseline's
    value there, ρA would make the pattern fit move an effect to make up for it: the strip with a declared 45 g
    accelerometer and a withheld 10 g mass at 0.3 m, its baseline's ρA 5 % high — the mass's match landed at
    0.319 m and the refits from it left 60 noise variances."""
    names = list(problem.space.names)
    hold = "EI" in names and "rhoA" in names and not problem.level_seen
    free = np.array([not (n == "rhoA" and hold) for n in names])
    return np.concatenate([free, np.ones(0 if effect is None else effect.dim, dtype=bool)])


def _place(effect: Effect | None, free: np.ndarray, p: int) -> int | None:
    """Index among the free variables (``free``, ``p`` baseline unknowns first) of ``effect``'s place ``x``."""
    if effect is None or "x" not in effect.variables:
        return None
    k = p + effect.variables.index("x")
    return int(np.count_nonzero(free[:k])) if free[k] else None


def pattern_fit(problem: GapProblem, evidence: ModalEvidence, beta0: np.ndarray, effect: Effect | None = None,
                *, max_evaluations: int = 200, start: PatternFit | None = None) -> PatternFit:
    """Least-squares match of the measured modes by the baseline unknowns and ``effect`` (module docstring),
    from ``beta0`` and the best :data:`STARTS` values of the effect's coarse grid — or, with ``start`` (the
    same effect's match from another baseline), from that match alone, the unknowns the fit holds (ρA) as the
    match had them (with the baseline's ρA, a match of χ² 25 was polished from a start of χ² 2.5e6).

    An effect's match beyond the records' scatter (:data:`SCATTER`) with a baseline unknown on its bound
    (:data:`ON_BOUND`) is made again with the held ρA at the
    config's value (``beta0``'s force-like constants scaled to it: the same modes,
    :func:`~diagnosis.search.pattern_starts.at_nominal_density`) and the better match kept: the box bounds EI
    and N, not their ratios to ρA, and a baseline that compensated the effect can hold ρA where the ratios the
    effect's pattern asks for lie outside it (measured: a compressed clamped–clamped beam with a withheld 0.25 kg
    mass read by one accelerometer, the baseline's ρA 2.8× the truth with N on its upper bound in tension — the
    mass's pattern needed EI and N beyond their bounds and matched at χ² 1.9e5; at the config's ρA, 15 for 11
    modes, the mass 0.5 % heavy and 0.04 mm off)."""
    p = np.asarray(beta0).size
    free = _free(problem, effect)
    box = problem.box(effect)
    fit = _match(problem, evidence, np.asarray(beta0, dtype=float), effect, max_evaluations, start)
    lo, hi = np.asarray(box.lower, dtype=float)[:p], np.asarray(box.upper, dtype=float)[:p]
    if effect is None or start is not None or np.all(free[:p]) \
            or not fit.chi2 > stats.chi2.isf(SCATTER, 2 * evidence.n_modes) \
            or not _on_bound(fit.beta[free[:p]], lo[free[:p]], hi[free[:p]]):
        return fit
    other = at_nominal_density(problem, np.asarray(beta0, dtype=float), free[:p], lo, hi)
    if other is None:
        return fit
    again = _match(problem, evidence, other, effect, max_evaluations, None)
    return again if again.chi2 < fit.chi2 else fit


def _on_bound(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Whether any of ``x`` lies on its bound (within :data:`ON_BOUND` of its span)."""
    tol = ON_BOUND * (hi - lo)
    return bool(np.any((x <= lo + tol) | (x >= hi - tol)))


def _match(problem: GapProblem, evidence: ModalEvidence, beta0: np.ndarray, effect: Effect | None,
           max_evaluations: int, start: PatternFit | None) -> PatternFit:
    """:func:`pattern_fit` with the held unknowns (ρA) as ``beta0`` (after
    :func:`~diagnosis.search.pattern_starts.room`) or ``start`` has them."""
    box = problem.box(effect)
    lo, hi = np.asarray(box.lower, dtype=float), np.asarray(box.upper, dtype=float)
    p = np.asarray(beta0).size
    span = hi[:p] - lo[:p]
    free = _free(problem, effect)
    beta0 = room(problem, np.asarray(beta0, dtype=float), free[:p], lo[:p], hi[:p])
    held = np.concatenate([beta0, np.asarray(effect.off if effect is not None else [], dtype=float)])
    if start is not None:     # the unknowns the fit holds (ρA) as the match had them: its modes are the match's
        held = np.clip(np.concatenate([start.beta, start.s]), lo, hi)

    def full(x: np.ndarray) -> np.ndarray:
        z = held.copy()
        z[free] = x
        return z

    modes = _ModesAt(problem, effect, p, evidence.n_modes)

    def res(x: np.ndarray) -> np.ndarray:
        return _residual(evidence, beta0, span, modes, full(x))

    def cost(f: np.ndarray, zeta: np.ndarray) -> np.ndarray:     # χ² of each of a stack of frequency sets
        return np.asarray(mode_cost(evidence, f, zeta))

    ei = list(problem.space.names).index("EI") if "EI" in problem.space.names else None
    if ei is not None and not free[ei]:
        ei = None
    if effect is None:
        # as it is, and with the modes' common scale aligned to the measured ones
        # (:func:`~diagnosis.search.pattern_starts.aligned`)
        starts = [held[free]] + ([aligned(modes, cost, held, ei, lo, hi)[0][free]] if ei is not None else [])
    elif start is not None:
        # the measured modes are the same: the match found from another baseline lies in the effect's basin
        starts = [held[free]]
    else:
        # every value of the effect's grid with the baseline re-adjusted (two Gauss–Newton steps with the
        # baseline's Jacobian at the start): the baseline may sit where it compensated the effect
        nb = int(np.sum(free[:p]))
        x_off = held[free]
        J = jacobian(res, x_off, nb, (hi - lo)[free][:nb])
        trials = trial_values(effect.lower, effect.upper, effect.off)
        starts = []
        # from the baseline, and from the config's nominal values: a baseline that compensated the effect can sit
        # in a valley the effect's basin is not reached from (measured: a stiff translational spring at a pinned
        # end, absorbed by N at its lower bound and EI +20 %: every start from the baseline ended at χ² 1.4e5,
        # the nominal's at 0.1 — EI, N and the compliance within 0.5 % of the truth)
        nominal = np.clip(np.asarray(problem.space.nominal, dtype=float), lo[:p], hi[:p])
        for base, k_profiled, k_raw in ((beta0, STARTS if effect.dim > 1 else 2, 2), (nominal, 1, 1)):
            raw = [np.concatenate([base, s])[free] for s in trials]
            grid = [profiled(res, x, J, lo[free], hi[free]) for x in raw]
            # the best re-adjusted values, and the best as they were (a re-adjustment can also mislead)
            starts += [g[0] for g in sorted(grid, key=lambda g: g[1])[:k_profiled]]
            starts += [raw[i] for i in np.argsort([float(r @ r) for r in map(res, raw)])[:k_raw]]
            if base is beta0 and effect.dim > 1:
                starts += best_per_place(trials, grid)
        # every value of the grid with the modes' common scale aligned to the measured ones: a baseline that
        # compensated the effect can hold EI where no re-adjustment reaches the effect's basin
        if ei is not None:
            at_scale = [aligned(modes, cost, np.concatenate([beta0, s]), ei, lo, hi) for s in trials]
            starts += [a[0][free] for a in sorted(at_scale, key=lambda a: a[1])[:ALIGNED]]

    def polish(x0: np.ndarray, budget: int = max_evaluations) -> optimize.OptimizeResult:
        return least_squares_polish(res, x0, lo[free], hi[free], budget)

    best = raced(res, starts, lo[free], hi[free], max_evaluations)
    place = _place(effect, free, p)
    if place is not None and start is None and 2.0 * best.cost > stats.chi2.isf(SCATTER, 2 * evidence.n_modes):
        # a match beyond the records' scatter at a place can be a basin of the place: profiled over one grid
        # step either side, then polished from the profile's other minima (a match polished from ``start`` was
        # profiled where it was found)
        for x1 in place_profiled(res, best.x, place, (hi - lo)[free][place] / (MASS_GRID - 1), lo[free], hi[free],
                                 least_squares_polish):
            other = polish(x1)
            best = other if other.cost < best.cost else best
    if not np.all(free[:p]):
        # the scale the modes cannot see, from the amplitudes: multiplying every force-like constant by λ
        # divides the response by λ and leaves the modes alone
        lam = amplitude_scale(problem, effect, full(best.x))
        if lam is not None:
            z0 = full(best.x)
            scaled = np.zeros(z0.size, dtype=bool)
            scaled[:p] = True
            scaled[[p + i for i in (effect.scaled if effect is not None else ())]] = True   # a mass, a stiffness:
            lam = within(lam, z0[scaled], lo[scaled], hi[scaled])        # the same ratio to the beam, the same modes
            before = (held.copy(), best)
            held[:p][~free[:p]] = held[:p][~free[:p]] * lam
            z0[scaled] *= lam
            best = polish(z0[free])
            # the same modes, a prior term that moved by at most 1 per baseline unknown (each within its box)
            if best.cost > before[1].cost + 0.5 * p:
                held, best = before
    z = full(best.x)
    s = z[p:]
    try:
        f, zeta = compared(evidence, *modes(z))
    except (EbbError, ValueError, np.linalg.LinAlgError):
        f = zeta = np.full(evidence.n_modes, np.nan)
    return PatternFit("baseline" if effect is None else effect.label, float(2 * best.cost), z[:p], s, f, zeta)


def amplitude_screened(problem: GapProblem, evidence: ModalEvidence, effect: Effect, match: PatternFit
                       ) -> PatternFit:
    """``match`` (``effect``'s pattern fit), or the match of the measured modes with the effect at another place
    of its grid (:data:`~diagnosis.candidates.score.MASS_GRID` places, every other variable re-fitted,
    :func:`~diagnosis.search.pattern_starts.fixed_place_fits`) that fits the records' amplitudes better — when
    ``match`` is within the records' scatter (:data:`SCATTER`): then the modes may not tell the places apart,
    and the time-domain refit's start is the one of the places the modes allow whose residual on the fit windows
    is least, each at its amplitudes' scale (measured: a clamped–pinned beam in strong tension with a stiff
    spring at 0.505 L withheld, three modes measured: every place from 0.42 to 0.70 L matched them at χ² 0.10;
    the match at 0.61 L leaves 1.57 noise variances on the records, the grid's place 0.50 L 0.92, and the
    refit from there lands 0.7 mm from the truth, held out 0.93–1.00).  Without a place, or beyond the scatter,
    ``match``."""
    p = match.beta.size
    limit = stats.chi2.isf(SCATTER, 2 * evidence.n_modes)
    free = _free(problem, effect)
    place = _place(effect, free, p)
    if place is None or not match.chi2 <= limit:
        return match
    box = problem.box(effect)
    lo, hi = np.asarray(box.lower, dtype=float), np.asarray(box.upper, dtype=float)
    held = np.concatenate([match.beta, match.s])
    modes = _ModesAt(problem, effect, p, evidence.n_modes)

    def res(x: np.ndarray) -> np.ndarray:
        z = held.copy()
        z[free] = x
        return _residual(evidence, match.beta, hi[:p] - lo[:p], modes, z)

    scaled = np.zeros(held.size, dtype=bool)
    scaled[:p] = True
    scaled[[p + i for i in effect.scaled]] = True
    k = p + effect.variables.index("x")
    points, costs = fixed_place_fits(res, held[free], place, np.linspace(lo[k], hi[k], MASS_GRID), lo[free],
                                     hi[free], least_squares_polish)
    best, best_rss, best_chi2 = held, _records_rss(problem, effect, match), match.chi2
    for x, chi2 in zip(points, costs):
        if chi2 <= limit:
            z = held.copy()
            z[free] = x
            lam = amplitude_scale(problem, effect, z)
            if lam is not None:
                z[scaled] *= within(lam, z[scaled], lo[scaled], hi[scaled])
            r = _records_rss(problem, effect, replace(match, beta=z[:p], s=z[p:]))
            if r < best_rss:
                best, best_rss, best_chi2 = z, r, chi2
    if best is held:
        return match
    f, zeta = compared(evidence, *modes(best))        # the same modes at any scale
    return PatternFit(match.label, best_chi2, best[:p], best[p:], f, zeta)


def _records_rss(problem: GapProblem, effect: Effect, match: PatternFit) -> float:
    """The residual sum of squares of ``match`` (at its amplitudes' scale) on the records' fit windows."""
    r = problem.residuals(match.beta, effect, match.s)
    return float(r @ r) if np.all(np.isfinite(r)) else np.inf


def _pattern_task(problem: GapProblem, evidence: ModalEvidence, beta: np.ndarray, catalogue: Catalogue,
                  label: str | None, start: PatternFit | None = None) -> PatternFit:
    """One pattern fit, in this or a worker process (effects are rebuilt from their label: they do not pickle)."""
    return pattern_fit(problem, evidence, beta, None if label is None else catalogue.effect(label), start=start)


def pattern_fits(problem: GapProblem, evidence: ModalEvidence, beta: np.ndarray, catalogue: Catalogue,
                 executor: Executor | None = None, *, margin: float = 0.0,
                 previous: Mapping[str, PatternFit] | None = None) -> dict[str, PatternFit]:
    """The baseline's (key ``"baseline"``) and every structural effect's pattern fit from the baseline
    unknowns ``beta``, on ``executor``'s processes when given.

    The baseline's fit comes first; when its χ² is at most ``margin`` the effects' fits are not made (the
    baseline alone is returned): a χ² is a sum of squares, so no effect could match better by more than the
    margin.  (Measured on the displacement actuator-lag record of the blind family, whose baseline matches its
    five modes with χ² 1.6: 33 of its 48 s were these fits.)  An effect with a match in ``previous`` (the same
    records' modes matched from another baseline, in an earlier ranking or on other numerics: :func:`carried`) is
    polished from it once, about the baseline whose own match is best, instead of searched again from every
    baseline (:func:`pattern_fit`'s ``start``; the other baselines' matches within the scatter it carried are kept
    with it): the grid's starts were tried once, and a new baseline moves only the weak prior's centre.
    (Measured on the rig family's pair, spring and actuator lag, ranked twice: the second ranking's 30 s of
    pattern fits; on the hint family's record 45, a 0.25 kg mass withheld on a compressed clamped–pinned beam and
    ranked four times, the rival baseline's search repeated by every later ranking to the same matches, 20 s each:
    0.7 s each now, the same verdict, size and place.)

    With a rival baseline (:attr:`GapProblem.rival`: the fit from the records' own start, better than the baseline
    without reaching the floor) every fit is made from it too and the better match kept — the baseline's and
    each effect's: a compensating baseline can hold ρA (which the modes do not see) on a bound where the records'
    frequency scale lies beyond EI's (measured: a withheld tip mass on a broadband strip record, the baseline's
    matches all at χ² 5.6e10, the records' start 4.4e7 before any fit).  When both matches of an effect are
    within the records' scatter (:data:`SCATTER`) the modes cannot choose: the other one is kept with the better
    (:attr:`PatternFit.others`), and the time-domain refit starts from both (measured: three modes of a beam in
    strong tension with a stiff spring withheld, matched at χ² 0.140 by a spring near its place and 0.139 by a
    rigid support 0.25 L away in another beam, which alone refitted to 840 noise variances held out).
    """
    betas = [np.asarray(beta, dtype=float)]
    if problem.rival is not None:
        betas.append(np.asarray(problem.rival.beta, dtype=float))
    bases = [pattern_fit(problem, evidence, b) for b in betas]
    k = int(np.argmin([f.chi2 for f in bases]))
    base = bases[k]
    if base.chi2 <= margin:
        return {"baseline": base}
    previous = previous or {}
    moving = sorted((e for e in catalogue.effects() if moves_modes(problem, beta, e)), key=lambda e: -e.dim)
    # the costliest first; an effect matched before is polished from its match once, about the baseline that
    # matches best
    args = [(problem, evidence, b, catalogue, e.label, previous.get(e.label))
            for e in moving for b in (betas[k:k + 1] if e.label in previous else betas)]
    best: dict[str, PatternFit] = {}
    limit = stats.chi2.isf(SCATTER, 2 * evidence.n_modes)
    for f in side_by_side(executor, _pattern_task, args):
        g = best.get(f.label)
        if f.label in previous:    # the other baselines' matches within the scatter, as they were found
            best[f.label] = replace(f, others=previous[f.label].others)
        elif g is None:
            best[f.label] = f
        else:
            won, lost = (f, g) if f.chi2 < g.chi2 else (g, f)
            best[f.label] = replace(won, others=won.others + (lost,)) if lost.chi2 <= limit else won
    return {"baseline": base} | best


def carried(matches: Mapping[str, PatternFit], made_with: Mapping[str, Effect], catalogue: Catalogue
            ) -> dict[str, PatternFit]:
    """``matches`` — pattern fits of the effects ``made_with`` (by label), in another catalogue of the same records:
    sized from another baseline, on other numerics — as matches of ``catalogue``'s effects of the same labels, by
    their physical values (:func:`~diagnosis.effects.variables_for`); one without such a point is left out."""
    out = {}
    for e in catalogue.effects():
        pf, old = matches.get(e.label), made_with.get(e.label)
        if pf is None or old is None:
            continue
        moved = [(m, variables_for(e, old.physical(m.s), m.s)) for m in (pf, *pf.others)]
        if moved[0][1] is not None:
            out[e.label] = replace(pf, s=moved[0][1], others=tuple(replace(m, s=s) for m, s in moved[1:]
                                                                   if s is not None))
    return out
