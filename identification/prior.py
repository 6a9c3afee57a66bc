"""What the user knows before the data: a Gaussian prior per identified parameter, and what the data did to it.

A parameter of the config's ``[parameters]`` table may carry ``prior_std``: the standard deviation of a Gaussian
prior about its ``value`` (the nominal value from drawings, a data sheet, the geometry)::

    EI = { value = 88.0, bounds = [50.0, 160.0], identify = true, prior_std = 27.0 }   # N.m2

The bounds stay the hard limits; the prior says how far from the nominal value the user expects the truth.  Fits
then minimise the negative log posterior — the whitened residuals' squares plus ``((x - μ)/σ_p)²`` per prior —
and every result says, per parameter, what moved it (:meth:`Prior.judge`):

- the **data**, when the posterior standard deviation is well below the prior's (the record decides it);
- the **prior**, when it is nearly the prior's (the record says little; the value is the user's);
- a **conflict**, when the estimate lies more than :data:`CONFLICT_SIGMA` prior standard deviations from the
  nominal value ("EI −47 %: 5.2 σ from the prior") — the data and the user's knowledge disagree, and one of them,
  or the model, is wrong.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ebb_model.config import BeamConfig

__all__ = ["CONFLICT_SIGMA", "Prior", "PriorCheck"]

#: Distance from the prior's mean, in prior standard deviations, beyond which a result is a prior conflict (a
#: Gaussian's two-sided tail beyond 3σ holds 0.27 %).
CONFLICT_SIGMA = 3.0
#: Posterior / prior standard deviation below which the data, not the prior, determined a parameter.
DATA_DECIDED = 0.5
#: ... and above which the prior held it (the data barely narrowed it).
PRIOR_HELD = 0.9


@dataclass(frozen=True)
class PriorCheck:
    """One parameter's estimate against its prior."""

    name: str
    mean: float
    std: float
    value: float
    posterior_std: float

    @property
    def z(self) -> float:
        """Distance of the estimate from the prior's mean in prior standard deviations."""
        return (self.value - self.mean) / self.std

    @property
    def status(self) -> str:
        """``"conflict"``, ``"data"`` (the data determined it), ``"prior"`` (the prior held it) or ``"shared"``."""
        if abs(self.z) > CONFLICT_SIGMA:
            return "conflict"
        ratio = self.posterior_std / self.std
        if ratio < DATA_DECIDED:
            return "data"
        return "prior" if ratio > PRIOR_HELD else "shared"

    def line(self) -> str:
        """One line in words."""
        change = (self.value - self.mean) / abs(self.mean) if self.mean != 0 else math.nan
        what = {"conflict": f"PRIOR CONFLICT: {abs(self.z):.1f} σ from the prior",
                "data": "the data determined it", "prior": "the prior held it (the data barely narrowed it)",
                "shared": "data and prior both shaped it"}[self.status]
        return (f"{self.name} = {self.value:.4g} ({change:+.0%} from the prior {self.mean:.4g} ± {self.std:.3g}; "
                f"posterior σ {self.posterior_std:.3g}): {what}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {"prior_mean": self.mean, "prior_std": self.std, "value": self.value,
                "posterior_std": self.posterior_std, "z": self.z, "status": self.status}


@dataclass(frozen=True, eq=False)
class Prior:
    """Gaussian priors on some of the unknowns ``names`` (``std`` infinite where there is none)."""

    names: tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray

    @classmethod
    def of(cls, config: BeamConfig, names: Sequence[str]) -> Prior:
        """The priors the config gives the unknowns ``names`` (positions and parameters without ``prior_std``:
        none)."""
        mean, std = [], []
        for n in names:
            spec = config.parameters.get(n) if n in config.parameters else None
            has = spec is not None and spec.prior_std is not None
            mean.append(spec.value if has else 0.0)           # type: ignore[union-attr]
            std.append(spec.prior_std if has else math.inf)   # type: ignore[union-attr]
        return cls(tuple(names), np.array(mean, dtype=float), np.array(std, dtype=float))

    @property
    def given(self) -> np.ndarray:
        """Mask of the unknowns with a prior."""
        return np.isfinite(self.std)

    @property
    def count(self) -> int:
        """Number of priors (of residuals :meth:`residuals` adds)."""
        return int(np.count_nonzero(self.given))

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """``(x - μ)/σ_p`` of the unknowns with a prior (their squares add to χ²: the negative log prior, ×2)."""
        g = self.given
        return (np.asarray(x, dtype=float)[g] - self.mean[g]) / self.std[g]

    def information(self, scales: np.ndarray) -> np.ndarray:
        """The prior's information matrix in the relative units ``x / scales`` of a Fisher matrix."""
        g = self.given
        d = np.zeros(len(self.names))
        d[g] = (np.asarray(scales, dtype=float)[g] / self.std[g]) ** 2
        return np.diag(d)

    def posterior_std(self, fisher: np.ndarray, scales: np.ndarray) -> np.ndarray:
        """Standard deviations from the data's Fisher matrix (relative units) plus the prior's information."""
        F = np.asarray(fisher, dtype=float) + self.information(scales)
        try:
            cov = np.linalg.inv(F)
        except np.linalg.LinAlgError:
            return np.full(len(self.names), math.inf)
        return np.asarray(scales, dtype=float) * np.sqrt(np.clip(np.diag(cov), 0.0, None))

    def judge(self, x: np.ndarray, posterior_std: np.ndarray) -> list[PriorCheck]:
        """Each prior's :class:`PriorCheck` at estimate ``x``."""
        return [PriorCheck(n, float(self.mean[i]), float(self.std[i]), float(x[i]), float(posterior_std[i]))
                for i, n in enumerate(self.names) if self.given[i]]
