"""A prior on EI and ρA from what the drawings and data sheets say: material and section with their tolerances.

A user rarely knows EI and ρA; they know the strip — its width and thickness from a calliper or two documents that
disagree, the steel's E and ρ from a data sheet.  The config says so once::

    [identification.geometry]            # a solid rectangular section: EI = E w t³/12, ρA = ρ w t
    E = { value = 200e9, std = 4e9 }               # Pa
    density = { value = 7850.0, std = 40.0 }       # kg/m³
    width = { value = 0.05066, std = 0.0002 }      # m
    thickness = { value = 4.665e-3, std = 0.475e-3 }   # m

and the prior on (EI, ρA) follows by the law of propagation of uncertainty (GUM, JCGM 100:2008, §5.1) — to first
order, in relative terms::

    var(EI)/EI² = u_E² + u_w² + 9 u_t²,   var(ρA)/ρA² = u_ρ² + u_w² + u_t²,   cov/(EI ρA) = u_w² + 3 u_t²

(``u``: each quantity's relative standard uncertainty).  The two are correlated through the section: a thicker
strip is both stiffer and heavier, and their ratio — which sets the natural frequencies — is known better
(``u_E² + u_ρ² + 4 u_t²``) than either.  The linearisation is the GUM's first order; for a thickness known to
±10 % the third power's curvature moves EI's mean by 3 % of its value (a tenth of its standard deviation).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TypeGuard

import numpy as np

from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError

from .settings import identification_table

__all__ = ["QUANTITIES", "SectionPrior", "geometry_prior"]

#: The section's quantities and their units.
QUANTITIES = {"E": "Pa", "density": "kg/m3", "width": "m", "thickness": "m"}
#: Exponents of (E, density, width, thickness) in EI (with 1/12) and in ρA.
_EXPONENTS = {"EI": np.array([1.0, 0.0, 1.0, 3.0]), "rhoA": np.array([0.0, 1.0, 1.0, 1.0])}


@dataclass(frozen=True, eq=False)
class SectionPrior:
    """The Gaussian prior on ``("EI", "rhoA")`` a section's geometry and material give: ``mean`` and ``cov``."""

    mean: np.ndarray
    cov: np.ndarray
    source: str

    names = ("EI", "rhoA")


def geometry_prior(config: BeamConfig) -> SectionPrior | None:
    """The prior of ``[identification.geometry]`` (module docstring); ``None`` when the config has none.

    Raises
    ------
    ConfigError
        Not a table, a quantity missing or unknown, a value or uncertainty not a finite number > 0 (an uncertainty
        may be 0), EI or ρA with a ``prior_std`` of its own as well (a prior is stated once) — every problem at once.
    """
    table = identification_table(config, "geometry", f"of {', '.join(QUANTITIES)}, each {{ value = ..., std = ... }}")
    if table is None:
        return None
    where = "identification.geometry"
    bad = [f"{where}.{k}: unknown quantity; allowed: {', '.join(QUANTITIES)}" for k in table if k not in QUANTITIES]
    bad += [f"{where}.{k}: missing ({u}, {{ value = ..., std = ... }})" for k, u in QUANTITIES.items()
            if k not in table]
    value, rel = np.ones(4), np.zeros(4)
    for i, (k, unit) in enumerate(QUANTITIES.items()):
        spec = table.get(k)
        if spec is None:
            continue
        v, s = (spec.get("value"), spec.get("std")) if isinstance(spec, Mapping) else (None, None)
        extra = [key for key in spec if key not in ("value", "std")] if isinstance(spec, Mapping) else []
        if not (_number(v) and v > 0 and _number(s) and s >= 0) or extra:
            bad.append(f"{where}.{k}: must be {{ value = <number > 0> {unit}, std = <number >= 0> }}, got {spec!r}")
            continue
        value[i], rel[i] = v, s / v
    bad += [f"{where}: parameters.{n} has a prior_std of its own; state its prior once (drop one of the two)"
            for n in SectionPrior.names if n in config.parameters and config.parameters[n].prior_std is not None]
    if bad:
        raise ConfigError(bad)
    mean = np.array([np.prod(value ** _EXPONENTS[n]) for n in SectionPrior.names]) * np.array([1.0 / 12.0, 1.0])
    A = np.stack([_EXPONENTS[n] for n in SectionPrior.names])
    cov = np.outer(mean, mean) * (A @ np.diag(rel ** 2) @ A.T)
    sd = np.sqrt(np.diag(cov))
    if not np.all(sd > 0) or abs(cov[0, 1]) / (sd[0] * sd[1]) > 0.999:
        raise ConfigError(f"{where}: with these uncertainties EI or rhoA, or their ratio, would be known exactly; "
                          f"give every tolerance that applies (the material's E and density too)")
    return SectionPrior(mean, cov, "geometry")


def _number(v: object) -> TypeGuard[float]:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
