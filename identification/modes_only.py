"""Identification from measured natural frequencies alone: no time record, no force.

A free decay, an ambient record or another lab's modal test gives a beam's natural frequencies
(:mod:`identification.output_modes`, a spectrum file, ``[identification.modes]``) but no force, so no scale:
multiplying every mass and every stiffness of a beam by one factor leaves its frequencies where they were.  The
frequencies fix ``√(EI/ρA)``, the axial load per unit mass and the ratios of the rest; the common scale needs a
prior (``[identification.geometry]`` or a ``prior_std``) or a record with its force.  This module fits the
config's unknowns to the measured frequencies and the priors (least squares of ``(f_model − f)/σ`` and the
priors' residuals, :class:`identification.prior.Prior`) and says what each result rests on:

- a direction of the unknowns along which neither the frequencies nor a prior move the fit — the common scale
  of masses and stiffnesses, say — is **refused** with one line naming it (:class:`ModesOnlyError`), never
  guessed;
- an unknown the frequencies barely depend on (the damping, a sensor's position: its conditional standard
  deviation wider than its bounds, :data:`HELD_WIDTH`) and without a prior is **held** at its nominal value and
  listed;
- every other unknown gets its value, its posterior standard deviation (Gauss–Newton: the whitened Jacobian's
  information plus the prior's) and what moved it (:meth:`identification.prior.Prior.judge`: data, prior or a
  conflict), and the model's frequencies are compared with the measured ones (χ² against its 99.9 % point).

The fit starts from the nominal values and from a scrambled Sobol set over the bounds (log-spaced for
positive bounds), polished by a trust-region least-squares solver; the best is kept.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import qmc

from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError, EbbError
from ebb_model.space.adequacy import refined_grid

from .config_file import load_identification_config
from .modal_data import ModalData, modal_data
from .modes_result import ModalIdentification
from .parameters import ParameterSpace, parameter_space
from .prior import Prior

__all__ = ["HELD_WIDTH", "Extension", "ModesFit", "ModesOnlyError", "fit_modes",
           "identify_from_modes", "modes_input", "with_grid_error"]

#: An unknown whose conditional standard deviation from the frequencies alone exceeds this share of its bounds'
#: width is held at its nominal value (the frequencies cannot place it within its bounds).
HELD_WIDTH = 1.0
#: A direction of the unknowns (relative units) along which the frequencies and priors leave a standard deviation
#: above this is free: they do not place it within its own size (the common scale's: infinite but for round-off).
FREE_STD = 1.0
#: Starts of the search besides the nominal values.
STARTS = 16
#: The config's unknowns the common scale of masses and stiffnesses multiplies: the beam's frequencies are the
#: same when every one of them (and every point mass and spring, ``k_``/``m_`` unknowns among them) is multiplied
#: by one factor.
SCALE_LIKE = ("EI", "rhoA", "c", "N", "rhoI", "kf")
#: Starts polished when an extension joins the fit (the best of its grid's).
POLISHED = 4
#: Iterations each start's polish gets before only the best one continues to convergence.
RACE = 6
#: Polishes to convergence of the race's best at most (each restarts the trust region).
RESTARTS = 3
#: Relative step of the Jacobian's central differences (the eigen-solver resolves a frequency to ~1e-9
#: relative: a step of 1e-6 left derivatives 1e-3 off, enough to make the common scale look seen).
JACOBIAN_STEP = 1e-4
#: Relative step of the least-squares polish's forward differences.
STEP = 1e-6
#: Ways to take one member of each doublet (:meth:`identification.modal_data.ModalData.choices`) fitted each at
#: most; with more, the member nearest the model's mode decides at every evaluation.
CHOICES = 16


class ModesOnlyError(ConfigError):
    """The measured frequencies and the priors leave a direction of the unknowns free (no scale without a prior
    or a force record), or there are no measured frequencies."""


def _jacobian(f: Any, x: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Central differences of ``f`` in the relative units ``x / scale`` (:data:`JACOBIAN_STEP`: forward ones at
    1e-6 made the common scale, along which the frequencies are the same to round-off, look fixed by them)."""
    cols = []
    for j in range(x.size):
        h = JACOBIAN_STEP * scale[j]
        up, down = x.copy(), x.copy()
        up[j] += h
        down[j] -= h
        cols.append((f(up) - f(down)) / (2 * JACOBIAN_STEP))
    return np.column_stack(cols)


def _starts(space: ParameterSpace, free: np.ndarray, seed: int) -> np.ndarray:
    """The nominal values and :data:`STARTS` scrambled Sobol points over the free unknowns' bounds."""
    lo, hi = space.lower[free], space.upper[free]
    u = qmc.Sobol(int(free.sum()), scramble=True, seed=seed).random(STARTS)
    logs = (lo > 0) & (hi > 0)
    pts = lo + u * (hi - lo)
    pts[:, logs] = np.exp(np.log(lo[logs]) + u[:, logs] * (np.log(hi[logs]) - np.log(lo[logs])))
    x = np.tile(space.nominal, (STARTS + 1, 1))
    x[1:, free] = pts
    return x


def _own_size(problem: "_Problem") -> np.ndarray:
    """Each unknown's own size, the unit a free direction is measured in: its nominal value, or its bounds' width
    when that is 0 (an axial load a newcomer starts at 0 has no size of its own: 300 N of uncertainty leaves a
    tension of kilonewtons placed, not free)."""
    return np.where(problem.nominal != 0.0, problem.scale, problem.upper - problem.lower)


def _free_direction(J: np.ndarray, names: list[str]) -> tuple[list[str], str] | None:
    """The direction (in the unknowns' own sizes, :func:`_own_size`) the whitened Jacobian leaves free: its
    unknowns and its name in words; ``None`` if there is none."""
    _, sv, vt = np.linalg.svd(J, full_matrices=False)
    if sv.size == J.shape[1] and sv[-1] * FREE_STD > 1.0:
        return None
    v = vt[-1] / vt[-1][np.argmax(np.abs(vt[-1]))]
    on = [(n, float(c)) for n, c in zip(names, v) if abs(c) > 0.05]
    if all(abs(c - 1.0) < 0.05 for _, c in on):
        words = (f"the common scale of {', '.join(n for n, _ in on)}" if len(on) > 1 else on[0][0])
    else:
        words = "the combination " + " ".join(f"{c:+.2g}·{n}" for n, c in on) + " (relative changes)"
    return [n for n, _ in on], words


@dataclass(frozen=True)
class Extension:
    """Unknowns beside the config's that a model of the modes carries (a diagnosis' candidate effect): their names,
    bounds, values at which they leave the beam as it is, the grid the fit starts from, and the map of
    ``(config, params, values)`` to the beam they make."""

    label: str
    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    off: np.ndarray
    grid: tuple[np.ndarray, ...]
    apply: Callable[[BeamConfig, Mapping[str, float], np.ndarray], tuple[BeamConfig, Mapping[str, float]]]
    #: which of ``names`` are a mass or a stiffness in fixed units (the common scale multiplies them)
    scaled: tuple[int, ...] = ()


@dataclass(frozen=True)
class ModesFit:
    """A least-squares fit of measured frequencies: the unknowns (config's, then an extension's), the free mask,
    χ² of the frequencies alone and with the priors, the covariance (absolute units; held unknowns: 0), the
    model's frequencies' agreement, evaluations."""

    names: tuple[str, ...]
    x: np.ndarray
    free: np.ndarray
    chi2: float
    chi2_total: float
    cov: np.ndarray
    agreement: dict[str, Any]
    n_evaluations: int
    #: the frequencies as compared: the measured ones, each uncertainty combined with the model grid's own error
    #: of the mode at the fit (:func:`with_grid_error`)
    compared: ModalData | None = None
    #: how many directions of the free unknowns the frequencies alone place within their own size (the rank of
    #: their whitened Jacobian at the fit, :data:`FREE_STD`): a fit with as many as there are frequencies
    #: reproduces them whatever they are, so it is no test of its model
    rank: int = 0

    @property
    def overdetermined(self) -> bool:
        """Whether the frequencies outnumber what the fit's unknowns can set: only then is reproducing them a test."""
        return int(self.agreement["modes"]) > self.rank


class _Problem:
    """The residuals of one model of the modes: frequencies ``(f_model − f)/σ``, then the priors'."""

    def __init__(self, cfg: BeamConfig, space: ParameterSpace, modes: ModalData, prior: Prior,
                 extension: Extension | None):
        self.cfg, self.space, self.modes, self.prior, self.ext = cfg, space, modes, prior, extension
        p = space.dim
        e = extension
        self.lower = np.concatenate([space.lower, [] if e is None else e.lower])
        self.upper = np.concatenate([space.upper, [] if e is None else e.upper])
        self.nominal = np.concatenate([space.nominal, [] if e is None else e.off])
        self.names = tuple(space.names) + (() if e is None else e.names)
        self.scale = np.maximum(np.abs(self.nominal), 1e-3 * (self.upper - self.lower))
        self.p = p
        #: the unknowns the common scale of masses and stiffnesses multiplies (the frequencies do not see it)
        self.scale_like = np.array([n in SCALE_LIKE or space.is_size(n) for n in space.names]
                                   + [k in (() if e is None else e.scaled) for k in range(len(self.names) - p)])
        self.calls = 0

    def model(self, x: np.ndarray) -> tuple[BeamConfig, Mapping[str, float]]:
        cfg, params = self.space.apply(self.cfg, x[:self.p])
        return (cfg, params) if self.ext is None else self.ext.apply(cfg, params, x[self.p:])

    def __call__(self, x: np.ndarray) -> np.ndarray:
        self.calls += 1
        try:
            r = self.modes.residuals(*self.model(x))
        except (EbbError, ValueError, np.linalg.LinAlgError):
            r = np.full(self.modes.count, 1e6)
        return np.concatenate([r, self.prior.residuals(x[:self.p])])


def _along_the_common_scale(problem: _Problem, x: np.ndarray) -> np.ndarray:
    """``x`` moved along the common scale of every mass- and stiffness-like unknown to where the priors are best
    (the frequencies are the same all along it, so the priors' residuals — linear in ``x`` — decide the step
    exactly); ``x`` itself when no prior sees the scale.  A trust region polishing frequencies a million times
    stiffer than the priors crawls along this direction: a spring's fit ended with EI 12 % above the truth where
    the priors put it within 1 %."""
    d = np.where(problem.scale_like, x, 0.0)
    r0 = problem.prior.residuals(x[:problem.p])
    a = problem.prior.residuals((x + d)[:problem.p]) - r0
    if r0.size == 0 or float(a @ a) == 0.0:
        return x
    return np.clip(x - float(a @ r0) / float(a @ a) * d, problem.lower, problem.upper)


def _solve(problem: _Problem, free: np.ndarray, starts: np.ndarray, polished: int) -> ModesFit:
    """Polish the ``polished`` best of ``starts`` (each costed first) over the ``free`` unknowns; the best fit
    with its covariance."""
    scale = problem.scale
    held = starts[0].copy()                        # (the unknowns not free are the same in every start)

    def polish(x0: np.ndarray, budget: int | None) -> tuple[float, np.ndarray, int]:
        """Bounded least squares from ``x0`` in units of each unknown's size there (an effect's size far from
        its "off" scale made the common scale of the beam and the effect a direction the trust region crawled
        along: a spring's fit ended with its priors' residual at 5 where 0.2 was reachable)."""
        s0 = np.maximum(np.abs(x0[free]), scale[free])
        lo, hi = problem.lower[free] / s0, problem.upper[free] / s0

        def sub(z: np.ndarray) -> np.ndarray:
            x = held.copy()
            x[free] = z * s0
            return problem(x)

        r = least_squares(sub, np.clip(x0[free] / s0, lo, hi), bounds=(lo, hi), method="trf", x_scale=1.0,
                          diff_step=STEP, max_nfev=budget)
        x = held.copy()
        x[free] = r.x * s0
        return float(r.cost), x, int(r.status)

    costs = [float(np.sum(problem(x0) ** 2)) for x0 in starts]
    raced = [polish(starts[k], RACE) for k in np.argsort(costs)[:polished]]
    cost, x, _ = min(raced, key=lambda r: r[0])
    # the race's best to convergence, the trust region restarted while it pays (a polish ending on its step
    # tolerance along the common scale stops short)
    for _ in range(RESTARTS):
        again, x_again, _ = polish(x, None)
        improved = again < cost * (1.0 - 1e-6)
        if again <= cost:
            cost, x = again, x_again
        if not improved:
            break
    for _ in range(RESTARTS):     # then along what only the priors see, the frequencies polished again there
        moved = _along_the_common_scale(problem, x)
        if np.array_equal(moved, x):
            break
        again, x_again, _ = polish(moved, None)
        if not again < cost * (1.0 - 1e-6):
            break
        cost, x = again, x_again
    # the covariance in units of each unknown's size at the fit (an effect's size far from its "off" scale made
    # the steps round-off: the common scale of EI, ρA and a spring looked fixed by the frequencies to 6e-5)
    scale = np.maximum(np.abs(x), scale)
    J = _jacobian(problem, x, scale)[:, free]
    m = problem.modes.count
    n = len(problem.names)
    info = np.zeros((n, n))
    info[np.ix_(free, free)] = J[:m].T @ J[:m]     # the frequencies' information; the prior's is added below
    prior_info = np.zeros((n, n))
    prior_info[:problem.p, :problem.p] = problem.prior.information(scale[:problem.p])
    total = info + prior_info
    cov = np.zeros((n, n))
    cov[np.ix_(free, free)] = np.linalg.pinv(total[np.ix_(free, free)]) * np.outer(scale[free], scale[free])
    r = problem(x)
    sv = np.linalg.svd(J[:m], compute_uv=False)
    return ModesFit(problem.names, x, free, float(r[:m] @ r[:m]), float(r @ r), cov,
                    problem.modes.agreement(*problem.model(x)), problem.calls, problem.modes,
                    int(np.sum(sv * FREE_STD > 1.0)))


def with_grid_error(cfg: BeamConfig, params: Mapping[str, float], measured: ModalData) -> ModalData:
    """``measured`` with each uncertainty combined with the model grid's own error of the mode of ``cfg`` at
    ``params``: the change of its frequency on the refined grid (:func:`ebb_model.space.adequacy.refined_grid`), so
    that a model is not asked to be nearer the measured frequencies than its discretisation is to its own
    continuum; ``measured`` itself when the model cannot be evaluated."""
    m = measured.count
    try:
        f = measured.model_frequencies(cfg, params)
        fine = measured.model_frequencies(refined_grid(cfg), params)
    except (EbbError, ValueError, np.linalg.LinAlgError):
        return measured
    if f.size < m or fine.size < m:
        return measured
    return measured.widened(fine - f)


def _aligned(problem: _Problem, x: np.ndarray, free: np.ndarray) -> np.ndarray:
    """``x`` with EI scaled so that the model's frequencies best match the measured ones in common scale (a start
    whose baseline compensated another effect can sit far from the scale the effect needs); ``x`` when EI is not a
    free unknown or the model cannot be evaluated."""
    if "EI" not in problem.names or not free[problem.names.index("EI")]:
        return x
    modes = problem.modes
    try:
        f = modes.model_frequencies(*problem.model(x))
    except (EbbError, ValueError, np.linalg.LinAlgError):
        return x
    if f.size < modes.count:
        return x
    k = modes.compared_with(f)
    w = 1.0 / modes.std_hz[k] ** 2
    alpha = float(np.sum(w * modes.frequencies_hz[k] * f) / np.sum(w * f * f))
    out = x.copy()
    i = problem.names.index("EI")
    out[i] = float(np.clip(x[i] * alpha ** 2, problem.lower[i], problem.upper[i]))
    return out


def fit_modes(cfg: BeamConfig, modes: ModalData, *, extension: Extension | None = None,
              baseline: ModesFit | None = None, seed: int = 0) -> ModesFit:
    """The config's unknowns (and an ``extension``'s) fitted to ``modes`` and the config's priors.

    Without an extension: the checks of the module docstring (a free direction refused, unknowns the frequencies
    barely move held), then the nominal values and :data:`STARTS` Sobol starts; the fit is polished again with
    each frequency's uncertainty combined with the model grid's own error of the mode there (:func:`with_grid_error`).
    With one: ``baseline``'s fit (required) with each value of the extension's grid, its common scale aligned to
    the measured frequencies, the :data:`POLISHED` best polished against the baseline's compared frequencies; the
    baseline's held unknowns stay held; its χ² is then taken against the uncertainties with its own grid error.
    ``modes``: the measured frequencies.

    Raises
    ------
    ModesOnlyError
        A direction of the unknowns the frequencies and priors leave free (named), or nothing the frequencies fix.
    """
    space = parameter_space(cfg)
    prior = Prior.of(cfg, space.names)
    if extension is not None:
        assert baseline is not None and baseline.compared is not None
        problem = _Problem(cfg, space, baseline.compared, prior, extension)
        free = np.concatenate([baseline.free, np.ones(len(extension.names), dtype=bool)])
        starts = np.array([_aligned(problem, np.concatenate([baseline.x, g]), free) for g in extension.grid])
        fit = _solve(problem, free, starts, POLISHED)
        own = with_grid_error(*problem.model(fit.x), modes)
        r = own.residuals(*problem.model(fit.x))
        return replace(fit, chi2=float(r @ r), chi2_total=float(r @ r) + fit.chi2_total - fit.chi2,
                       agreement=own.agreement(*problem.model(fit.x)), compared=own)
    problem = _Problem(cfg, space, modes, prior, extension)
    names = list(space.names)
    scale = problem.scale
    J0 = _jacobian(problem, space.nominal.copy(), scale)
    conditional = 1.0 / np.maximum(np.linalg.norm(J0, axis=0), 1e-300)        # relative units
    free = np.array([prior.given[j] or conditional[j] * scale[j] <= HELD_WIDTH * (space.upper[j] - space.lower[j])
                     for j in range(len(names))])
    if not free.any():
        raise ModesOnlyError("the measured frequencies fix none of the unknowns " + ", ".join(names))
    loose = _free_direction((J0 * _own_size(problem) / scale)[:, free], [n for n, f in zip(names, free) if f])
    if loose is not None:
        raise ModesOnlyError(f"the measured frequencies and the priors leave {loose[1]} free (frequencies fix ratios, "
                             f"not the common scale of masses and stiffnesses): give [identification.geometry], a "
                             f"prior_std, or a record with its force")
    # a doublet's members (``modes.groups``): each way to take one of each fitted from the starts, the best kept —
    # the member nearest the model's mode at every evaluation let a start far off (a newcomer's 50 %) settle on
    # the wrong member for good; up to :data:`CHOICES` ways, beyond that the nearest member decides alone
    options = modes.choices()
    options = options if len(options) <= CHOICES else [modes]
    first = min((_solve(_Problem(cfg, space, m, prior, None), free, _starts(space, free, seed), STARTS + 1)
                 for m in options), key=lambda fit: fit.chi2_total)
    compared = with_grid_error(*problem.model(first.x), modes)
    fit = _solve(_Problem(cfg, space, compared, prior, None), free, first.x[None, :], 1)
    return replace(fit, n_evaluations=fit.n_evaluations + first.n_evaluations, compared=compared)


def modes_input(config: BeamConfig | str | Path, modes: ModalData | None, out_dir: str | Path | None
                ) -> tuple[BeamConfig, ModalData, Path | None]:
    """The config (loaded and checked), the measured frequencies (default its ``[identification.modes]``) and the
    output directory of a run from the modes alone, checked before any work.

    Raises
    ------
    ModesOnlyError
        No measured frequencies.
    ConfigError
        An invalid config, or an output directory that exists and is not empty.
    """
    cfg = config if isinstance(config, BeamConfig) else load_identification_config(config)
    modes = modes if modes is not None else modal_data(cfg)
    if modes is None:
        raise ModesOnlyError("no measured natural frequencies: give [identification.modes], --modes FILE or a record")
    out = None if out_dir is None else Path(out_dir)
    if out is not None and out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(f"{out}: the output directory must not exist or be empty")
    return cfg, modes, out


def identify_from_modes(config: BeamConfig | str | Path, out_dir: str | Path | None = None, *,
                        modes: ModalData | None = None, seed: int = 0) -> ModalIdentification:
    """Fit the config's unknowns to measured natural frequencies and the config's priors (module docstring).

    Parameters
    ----------
    config
        Identification config (path or value) with its unknowns, their bounds and priors.
    out_dir
        Directory for ``identified.json`` (must not exist or be empty); ``None`` writes nothing.
    modes
        The measured frequencies; default the config's ``[identification.modes]``.
    seed
        Seed of the search's scrambled starts.

    Raises
    ------
    ModesOnlyError
        No measured frequencies, or a direction of the unknowns the frequencies and priors leave free (named).
    ConfigError
        An invalid config.
    """
    cfg, modes, out = modes_input(config, modes, out_dir)
    fit = fit_modes(cfg, modes, seed=seed)
    names, x, free, cov = list(fit.names), fit.x, fit.free, fit.cov
    held = {n: "the measured frequencies barely depend on it and it has no prior" for n, f in zip(names, free)
            if not f}
    space = parameter_space(cfg)
    prior = Prior.of(cfg, space.names)
    problem = _Problem(cfg, space, fit.compared or modes, prior, None)
    Jm = (_jacobian(problem, x, problem.scale) * _own_size(problem) / problem.scale)[:modes.count][:, free]
    scaled = _free_direction(Jm, [n for n, f in zip(names, free) if f])   # the frequencies alone: the priors' part
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    root = None
    if "EI" in names and "rhoA" in names and free[names.index("EI")] and free[names.index("rhoA")]:
        i, j = names.index("EI"), names.index("rhoA")
        g = np.zeros(len(names))
        g[i], g[j] = 0.5 / x[i], -0.5 / x[j]                # d ln √(EI/ρA)
        value = math.sqrt(x[i] / x[j])
        root = (value, value * math.sqrt(float(g @ cov @ g)))
    result = ModalIdentification(space.to_dict(x), {n: (float(s) if f else math.nan) for n, s, f in
                                                    zip(names, std, free)}, held,
                                 tuple(prior.judge(x, np.where(free, std, np.inf))), fit.agreement,
                                 fit.n_evaluations, tuple(scaled[0]) if scaled is not None else (), root, out)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "identified.json").write_text(json.dumps(result.to_dict(), indent=2) + "\n", encoding="utf-8")
    return result
