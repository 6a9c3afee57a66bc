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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import qmc

from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError, EbbError

from .config_file import load_identification_config
from .modal_data import ModalData, modal_data
from .parameters import ParameterSpace, parameter_space
from .prior import Prior, PriorCheck

__all__ = ["HELD_WIDTH", "ModesOnlyError", "ModalIdentification", "identify_from_modes"]

#: An unknown whose conditional standard deviation from the frequencies alone exceeds this share of its bounds'
#: width is held at its nominal value (the frequencies cannot place it within its bounds).
HELD_WIDTH = 1.0
#: A direction of the unknowns (relative units: each unknown over its nominal magnitude) along which the
#: frequencies and priors leave a standard deviation above this is free: they do not place it within its own size.
#: The common scale's is infinite but for round-off and the damping's second-order share of a damped frequency
#: (``√(1 − ζ²)``: 1e-5 of a frequency's sensitivity at ζ 0.4 %).
FREE_STD = 1.0
#: Starts of the search besides the nominal values.
STARTS = 16
#: Relative step of the forward differences of the Jacobian (the eigen-solver's round-off ~1e-13 relative).
STEP = 1e-6


class ModesOnlyError(ConfigError):
    """The measured frequencies and the priors leave a direction of the unknowns free (no scale without a prior
    or a force record), or there are no measured frequencies."""


@dataclass(frozen=True)
class ModalIdentification:
    """What :func:`identify_from_modes` found.

    Attributes
    ----------
    parameters, std
        Every unknown's value and posterior standard deviation (a held unknown: its nominal value, std ``nan``).
    held
        The unknowns held at their nominal values, each with why.
    from_priors
        The unknowns whose common scale the frequencies leave free, so that it rests on their priors (EI and ρA
        of a free beam, say); empty when the frequencies fix every free unknown.
    root_ratio
        ``√(EI/ρA)`` and its standard deviation, when both are unknowns: what the frequencies fix.
    priors
        Each prior's check at the result (:class:`identification.prior.PriorCheck`).
    agreement
        The model's frequencies against the measured ones (:meth:`identification.modal_data.ModalData.agreement`).
    n_evaluations
        Frequency evaluations of the search.
    out_dir
        Where ``identified.json`` was written (``None``: nothing written).
    """

    parameters: dict[str, float]
    std: dict[str, float]
    held: dict[str, str]
    priors: tuple[PriorCheck, ...]
    agreement: dict[str, Any]
    n_evaluations: int
    from_priors: tuple[str, ...] = ()
    root_ratio: tuple[float, float] | None = None
    out_dir: Path | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (``identified.json``)."""
        return {"evidence": "measured natural frequencies only (no time record)",
                "parameters": self.parameters,
                "std": {n: (None if n in self.held else s) for n, s in self.std.items()}, "held": self.held,
                "scale_from_priors": list(self.from_priors),
                "root_EI_over_rhoA": None if self.root_ratio is None else {"value": self.root_ratio[0],
                                                                           "std": self.root_ratio[1]},
                "priors": [p.to_dict() for p in self.priors], "modes": self.agreement,
                "n_evaluations": self.n_evaluations}

    def lines(self) -> list[str]:
        """What a user reads: each unknown with its uncertainty, what was held and why, the priors, the modes."""
        out = []
        for n, v in self.parameters.items():
            s = self.std[n]
            out.append(f"{n} = {v:.6g}" + (f" (held: {self.held[n]})" if n in self.held else f" ± {s:.2g} (1σ)"))
        if self.root_ratio is not None:
            v, sd = self.root_ratio
            out.append(f"√(EI/ρA) = {v:.6g} ± {sd:.2g} (1σ, {100 * sd / v:.2g} %): what the frequencies fix")
        if self.from_priors:
            out.append(f"the common scale of {', '.join(self.from_priors)} rests on their priors: the frequencies fix "
                       f"their ratios only (a record with its force would fix it)")
        for p in self.priors:
            if p.name in self.from_priors and p.status != "conflict":     # not the data's alone: say whose it is
                head = p.line().rsplit("): ", 1)[0]
                out.append(f"{head}): its ratio to {', '.join(n for n in self.from_priors if n != p.name)} from the "
                           f"frequencies, its scale from the prior")
            else:
                out.append(p.line())
        a = self.agreement
        out.append(f"measured modes {np.round(a['measured_hz'], 4).tolist()} Hz, the model's "
                   f"{np.round(a['model_hz'], 4).tolist()} Hz: chi2 {a['chi2']:.3g} for {a['modes']} modes "
                   + ("(agree)" if a["agrees"] else f"(beyond its 99.9 % point {a['chi2_limit']:.3g}: the model "
                                                    f"does not reproduce them)"))
        return out


def _residuals(cfg: BeamConfig, space: ParameterSpace, modes: ModalData, prior: Prior, x: np.ndarray) -> np.ndarray:
    try:
        r = modes.residuals(*space.apply(cfg, x))
    except (EbbError, ValueError):
        r = np.full(modes.count, 1e6)
    return np.concatenate([r, prior.residuals(x)])


def _jacobian(f: Any, x: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Forward differences of ``f`` in the relative units ``x / scale``."""
    r0 = f(x)
    cols = []
    for j in range(x.size):
        h = STEP * scale[j]
        xj = x.copy()
        xj[j] += h
        cols.append((f(xj) - r0) / STEP)
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


def _free_direction(J: np.ndarray, names: list[str]) -> tuple[list[str], str] | None:
    """The direction (relative units) the whitened Jacobian leaves free: its unknowns and its name in words;
    ``None`` if there is none."""
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
    cfg = config if isinstance(config, BeamConfig) else load_identification_config(config)
    modes = modes if modes is not None else modal_data(cfg)
    if modes is None:
        raise ModesOnlyError("no measured natural frequencies: give [identification.modes], --modes FILE or a record")
    out = None if out_dir is None else Path(out_dir)
    if out is not None and out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(f"{out}: the output directory must not exist or be empty")
    space = parameter_space(cfg)
    prior = Prior.of(cfg, space.names)
    names = list(space.names)
    scale = np.maximum(np.abs(space.nominal), 1e-3 * (space.upper - space.lower))
    calls = [0]

    def f(x: np.ndarray) -> np.ndarray:
        calls[0] += 1
        return _residuals(cfg, space, modes, prior, x)

    J0 = _jacobian(f, space.nominal.copy(), scale)
    conditional = 1.0 / np.maximum(np.linalg.norm(J0, axis=0), 1e-300)        # relative units
    held = {n: "the measured frequencies barely depend on it and it has no prior"
            for j, n in enumerate(names)
            if not prior.given[j] and conditional[j] * scale[j] > HELD_WIDTH * (space.upper[j] - space.lower[j])}
    free = np.array([n not in held for n in names])
    if not free.any():
        raise ModesOnlyError("the measured frequencies fix none of the unknowns " + ", ".join(names))
    free_names = [n for n in names if n not in held]
    loose = _free_direction(J0[:, free], free_names)
    if loose is not None:
        raise ModesOnlyError(f"the measured frequencies and the priors leave {loose[1]} free (frequencies fix ratios, "
                             f"not the common scale of masses and stiffnesses): give [identification.geometry], a "
                             f"prior_std, or a record with its force")
    scaled = _free_direction(J0[:modes.count][:, free], free_names)   # the frequencies alone: what the priors fix

    def sub(z: np.ndarray) -> np.ndarray:
        x = space.nominal.copy()
        x[free] = z * scale[free]
        return f(x)

    best = None
    for x0 in _starts(space, free, seed):
        r = least_squares(sub, x0[free] / scale[free], bounds=(space.lower[free] / scale[free],
                                                               space.upper[free] / scale[free]),
                          method="trf", x_scale=1.0, diff_step=STEP)
        if best is None or r.cost < best.cost:
            best = r
    assert best is not None
    x = space.nominal.copy()
    x[free] = best.x * scale[free]
    J = _jacobian(f, x, scale)[:, free]
    Jm = J[:modes.count]                          # the frequencies' information; the prior's is added by the prior
    info = np.zeros((len(names), len(names)))
    info[np.ix_(free, free)] = Jm.T @ Jm
    info[~free, ~free] = 1.0                      # (held: no row; a unit placeholder keeps the matrix invertible)
    cov = np.linalg.inv(info + prior.information(scale)) * np.outer(scale, scale)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    root = None
    if "EI" in free_names and "rhoA" in free_names:
        i, j = names.index("EI"), names.index("rhoA")
        g = np.zeros(len(names))
        g[i], g[j] = 0.5 / x[i], -0.5 / x[j]                # d ln √(EI/ρA)
        value = math.sqrt(x[i] / x[j])
        root = (value, value * math.sqrt(float(g @ cov @ g)))
    cfg_x, params = space.apply(cfg, x)
    result = ModalIdentification(space.to_dict(x), {n: (float(s) if f else math.nan) for n, s, f in
                                                    zip(names, std, free)}, held,
                                 tuple(prior.judge(x, np.where(free, std, np.inf))), modes.agreement(cfg_x, params),
                                 calls[0], tuple(scaled[0]) if scaled is not None else (), root, out)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "identified.json").write_text(json.dumps(result.to_dict(), indent=2) + "\n", encoding="utf-8")
    return result
