r"""A tracked record's segments fitted together: what they share once, what changes in each segment per segment.

One segment of a tracked record (:mod:`identification.tracking`) gives a few frequencies; fitted alone, each
segment's modes are matched exactly by the unknowns they share with every other segment — the beam's
√(EI/ρA) absorbs in one dwell what a roller's place or a missing mass does in another (DROPBEAR's dwells: EI from
178 to 361 N m² per dwell under one geometry prior).  The segments are one beam: its unknowns are fitted once to
every segment's frequencies, and only the unknowns ``varying`` (a support's place ``x_roller``, an axial load
``N``) take a value per segment:

.. math::  \chi^2 = \sum_i \Big\lVert \frac{f(\theta, v_i) - \hat f_i}{\sigma_i} \Big\rVert^2 + \chi^2_{prior}(\theta)

(``θ`` shared, ``v_i`` segment ``i``'s own; ``σ_i`` each frequency's standard error combined with the model grid's
own error of the mode at the start).  Then ``χ²`` against its degrees of freedom says whether one beam explains
every segment — where the segments alone each agree trivially.  Started from the segments' own fits (the shared
unknowns at their median, the varying ones as each segment had them), from the config's nominal values with a
single varying unknown scanned over its bounds in each segment, from the nominal values alone, and — when the
config makes a spring's stiffness or a point mass an unknown — from the fit without them; the
Jacobian's columns of different segments are differenced together (each segment's frequencies depend on its own
varying unknowns only).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Sequence

import numpy as np
from scipy import optimize, sparse, stats

from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError, EbbError

from .modal_data import ModalData
from .modes_only import with_grid_error
from .parameters import parameter_space
from .prior import Prior
from .settings import SECTION

__all__ = ["JointFit", "fit_together"]

#: Relative step of the polish's forward differences (as :data:`identification.modes_only.STEP`).
STEP = 1e-6
#: Values of a single varying unknown scanned over its bounds per segment for a start.
SCAN = 49


@dataclass(frozen=True)
class JointFit:
    """The segments' joint fit: the shared unknowns with their standard deviations, each segment's varying
    unknowns with theirs, χ² (frequencies only, and with the priors) against the frequencies' count less the
    unknowns the frequencies fix, and per segment its χ², the model's frequencies and the measured ones compared
    with them (a doublet's nearer member, :class:`identification.modal_data.ModalData`)."""

    shared: dict[str, float]
    shared_std: dict[str, float]
    varying: list[dict[str, float]]
    varying_std: list[dict[str, float]]
    chi2: float
    chi2_total: float
    dof: int
    segment_chi2: list[float]
    model_hz: list[list[float]]
    measured_hz: list[list[float]]

    @property
    def chi2_limit(self) -> float:
        """The 99.9 % point of χ² with :attr:`dof` degrees of freedom (at least one)."""
        return float(stats.chi2.ppf(0.999, max(self.dof, 1)))

    @property
    def agrees(self) -> bool:
        """Whether one beam reproduces every segment's frequencies (χ² within its 99.9 % point)."""
        return self.chi2 <= self.chi2_limit

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (``tracked.json``'s ``together``)."""
        return {"shared": self.shared, "shared_std": self.shared_std, "varying": self.varying,
                "varying_std": self.varying_std, "chi2": self.chi2, "chi2_with_priors": self.chi2_total,
                "dof": self.dof, "chi2_limit": self.chi2_limit, "agrees": self.agrees,
                "segment_chi2": self.segment_chi2, "model_hz": self.model_hz, "measured_hz": self.measured_hz}


def fit_together(config: BeamConfig, modes: Sequence[ModalData], varying: Sequence[str],
                 starts: Sequence[np.ndarray] = (), *, search: bool = True) -> JointFit:
    """The config's unknowns fitted to every segment's ``modes`` at once, the unknowns ``varying`` one value per
    segment (module docstring); ``starts``: each segment's own fit of every unknown (in the config's order), when
    there are; ``search=False`` polishes from ``starts`` alone (a fit of fewer segments started at a fit of
    all, :mod:`identification.hold_out`).

    Raises
    ------
    ConfigError
        A ``varying`` name that is not one of the config's unknowns, or nothing left to share.
    """
    space = parameter_space(config)
    names = list(space.names)
    bad = [v for v in varying if v not in names]
    if bad:
        raise ConfigError(f"--varies {', '.join(bad)}: not among the config's unknowns ({', '.join(names)})")
    vary = np.array([n in varying for n in names])
    if vary.all():
        raise ConfigError("every unknown varies between segments: nothing for them to share")
    n_seg, n_sh, n_v = len(modes), int(np.count_nonzero(~vary)), int(np.count_nonzero(vary))
    prior = Prior.of(config, space.names)
    scale = np.maximum(np.abs(space.nominal), 1e-3 * (space.upper - space.lower))

    def point(z: np.ndarray, i: int) -> np.ndarray:
        x = np.empty(len(names))
        x[~vary] = z[:n_sh]
        x[vary] = z[n_sh + i * n_v:n_sh + (i + 1) * n_v]
        return x

    def residuals(z: np.ndarray, data: Sequence[ModalData]) -> np.ndarray:
        parts = []
        for i, m in enumerate(data):
            x = point(z * zscale, i)
            try:
                cfg, params = space.apply(config, x)
            except (EbbError, ValueError):
                parts.append(np.full(m.count, 1e6))
                continue
            parts.append(m.residuals(cfg, params))
        x0 = point(z * zscale, 0)
        return np.concatenate(parts + [prior.residuals(x0)])

    lo = np.concatenate([space.lower[~vary]] + [space.lower[vary]] * n_seg)
    hi = np.concatenate([space.upper[~vary]] + [space.upper[vary]] * n_seg)
    zscale = np.concatenate([scale[~vary]] + [scale[vary]] * n_seg)
    rows = [m.count for m in modes]
    pattern = sparse.lil_matrix((sum(rows) + prior.count, lo.size), dtype=int)
    r0 = 0
    for i, c in enumerate(rows):
        pattern[r0:r0 + c, :n_sh] = 1
        pattern[r0:r0 + c, n_sh + i * n_v:n_sh + (i + 1) * n_v] = 1
        r0 += c
    pattern[r0:, :n_sh] = 1
    if prior.count and np.any(prior.given[vary]):
        pattern[r0:, n_sh:] = 1

    def as_z(x_each: Sequence[np.ndarray]) -> np.ndarray:
        shared = np.median(np.array([x[~vary] for x in x_each]), axis=0)
        return np.concatenate([shared] + [x[vary] for x in x_each])

    candidates = [as_z([space.nominal] * n_seg)] if search or len(starts) != n_seg else []
    if n_v == 1 and search:       # each segment's own value scanned over its bounds at the shared nominal values
        k = int(np.flatnonzero(vary)[0])
        grid = np.linspace(space.lower[k], space.upper[k], SCAN)
        scanned = []
        for m in modes:
            costs = []
            for g in grid:
                x = space.nominal.copy()
                x[k] = g
                try:
                    r = m.residuals(*space.apply(config, x))
                except (EbbError, ValueError):
                    r = np.full(m.count, 1e6)
                costs.append(float(r @ r))
            x = space.nominal.copy()
            x[k] = grid[int(np.argmin(costs))]
            scanned.append(x)
        candidates.insert(0, as_z(scanned))
    if len(starts) == n_seg:
        candidates.insert(0, as_z(list(starts)))
    simpler = _without_sizes(config) if search else None
    if simpler is not None:     # the fit without the points' sizes first, then every unknown from it
        inner = parameter_space(simpler).names
        nested = fit_together(simpler, modes, varying,
                              [np.array([s[names.index(n)] for n in inner]) for s in starts])
        candidates.insert(0, as_z([np.array([v.get(n, nested.shared.get(n, space.nominal[k]))
                                             for k, n in enumerate(names)]) for v in nested.varying]))

    def solve(z0: np.ndarray, data: Sequence[ModalData]) -> optimize.OptimizeResult:
        return optimize.least_squares(residuals, np.clip(z0, lo, hi) / zscale, args=(data,), bounds=(lo / zscale,
                                      hi / zscale), jac_sparsity=pattern, diff_step=STEP, x_scale=1.0)

    best = min((solve(z, modes) for z in candidates), key=lambda s: s.cost)
    compared = [with_grid_error(*space.apply(config, point(best.x * zscale, i)), m) for i, m in enumerate(modes)]
    best = solve(best.x * zscale, compared)
    z = best.x * zscale
    J = best.jac.toarray() if sparse.issparse(best.jac) else np.asarray(best.jac)
    cov = np.linalg.pinv(J.T @ J) * np.outer(zscale, zscale)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    m_rows = sum(rows)
    r = best.fun
    seg_chi2, model_hz, measured_hz = [], [], []
    r0 = 0
    for i, m in enumerate(compared):
        seg_chi2.append(float(r[r0:r0 + m.count] @ r[r0:r0 + m.count]))
        r0 += m.count
        x = point(z, i)
        try:
            f = m.model_frequencies(*space.apply(config, x))
        except (EbbError, ValueError, np.linalg.LinAlgError):
            f = None
        model_hz.append([] if f is None else [float(v) for v in f])
        measured_hz.append(m.frequencies_hz[m.compared_with(f) if f is not None and f.size == m.count
                                            else np.arange(m.frequencies_hz.size)].tolist())
    sh_names = [n for n, v in zip(names, vary) if not v]
    v_names = [n for n, v in zip(names, vary) if v]
    fixed = int(np.sum(np.linalg.svd(J[:m_rows], compute_uv=False) > 1e-6 * np.linalg.norm(J[:m_rows])))
    return JointFit(dict(zip(sh_names, map(float, z[:n_sh]))), dict(zip(sh_names, map(float, sd[:n_sh]))),
                    [dict(zip(v_names, map(float, z[n_sh + i * n_v:n_sh + (i + 1) * n_v]))) for i in range(n_seg)],
                    [dict(zip(v_names, map(float, sd[n_sh + i * n_v:n_sh + (i + 1) * n_v]))) for i in range(n_seg)],
                    float(r[:m_rows] @ r[:m_rows]), float(r @ r), m_rows - fixed, seg_chi2, model_hz, measured_hz)


def _without_sizes(config: BeamConfig) -> BeamConfig | None:
    """``config`` without ``[identification] sizes`` (its springs and masses at their values), ``None`` when it has
    none: a joint fit with a support's stiffness or a mass among the shared unknowns starts from the fit without
    them (DROPBEAR's first run, a compliant roller and a tip mass, from the nominal values and the dwells' own fits:
    χ² 4.6e8, the mass on its bound; from the fit without sizes: 3.3e4, about that fit's own 3.1e4)."""
    ident = config.extra.get(SECTION)
    if not isinstance(ident, Mapping) or not ident.get("sizes"):
        return None
    return replace(config, extra={**config.extra, SECTION: {k: v for k, v in ident.items() if k != "sizes"}})
