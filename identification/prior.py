"""What the user knows before the data: a Gaussian prior per identified parameter, and what the data did to it.

A parameter of the config's ``[parameters]`` table may carry ``prior_std``: the standard deviation of a Gaussian
prior about its ``value`` (the nominal value from drawings, a data sheet, the geometry)::

    EI = { value = 88.0, bounds = [50.0, 160.0], identify = true, prior_std = 27.0 }   # N.m2

or the section's geometry and material give EI and ρA a joint prior (:mod:`identification.geometry`: correlated — a
thicker strip is both stiffer and heavier). The bounds stay the hard limits; the prior says how far from the nominal
value the user expects the truth. Fits then minimise the negative log posterior — the whitened residuals' squares
plus ``((x - μ)/σ_p)²`` per prior (``(x − μ)ᵀ Σ⁻¹ (x − μ)`` for the correlated pair) — and every result says, per
parameter, what moved it (:meth:`Prior.judge`):

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
    source: str = "config"
    #: A check of several correlated priors together: ``value`` is then the normal deviate with the tail
    #: probability of their Mahalanobis distance (a strip whose EI and ρA each lie within their priors, but
    #: not in the ratio the section allows, is in conflict).
    joint: bool = False

    @property
    def z(self) -> float:
        """Distance of the estimate from the prior's mean in prior standard deviations."""
        return (self.value - self.mean) / self.std

    @property
    def status(self) -> str:
        """``"conflict"``, ``"data"`` (the data determined it), ``"prior"`` (the prior held it) or ``"shared"``;
        a joint check: ``"conflict"`` or ``"consistent"``."""
        if abs(self.z) > CONFLICT_SIGMA:
            return "conflict"
        if self.joint:
            return "consistent"
        ratio = self.posterior_std / self.std
        if ratio < DATA_DECIDED:
            return "data"
        return "prior" if ratio > PRIOR_HELD else "shared"

    def line(self) -> str:
        """One line in words."""
        if self.joint:
            what = (f"PRIOR CONFLICT: together {abs(self.z):.1f} σ from their joint prior" if self.status == "conflict"
                    else f"together within their joint prior ({abs(self.z):.1f} σ)")
            return f"{self.name} (correlated prior from the {self.source}): {what}"
        change = (self.value - self.mean) / abs(self.mean) if self.mean != 0 else math.nan
        what = {"conflict": f"PRIOR CONFLICT: {abs(self.z):.1f} σ from the prior",
                "data": "the data determined it", "prior": "the prior held it (the data barely narrowed it)",
                "shared": "data and prior both shaped it"}[self.status]
        return (f"{self.name} = {self.value:.4g} ({change:+.0%} from the prior {self.mean:.4g} ± {self.std:.3g}"
                f"{'' if self.source == 'config' else ' from the ' + self.source}; "
                f"posterior σ {self.posterior_std:.3g}): {what}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {"prior_mean": self.mean, "prior_std": self.std, "value": self.value,
                "posterior_std": None if math.isnan(self.posterior_std) else self.posterior_std, "z": self.z,
                "status": self.status, "source": self.source, "joint": self.joint}


@dataclass(frozen=True, eq=False)
class Prior:
    """Gaussian priors on some of the unknowns ``names`` (``std`` infinite where there is none); ``corr`` their
    correlation matrix (``None``: independent), ``sources`` where each came from."""

    names: tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray
    corr: np.ndarray | None = None
    sources: tuple[str, ...] = ()

    @classmethod
    def of(cls, config: BeamConfig, names: Sequence[str]) -> Prior:
        """The priors the config gives the unknowns ``names``: a parameter's ``prior_std``, or EI and ρA from
        ``[identification.geometry]`` (positions and parameters without either: none).

        Raises
        ------
        ConfigError
            An invalid ``[identification.geometry]`` table.
        """
        from .geometry import geometry_prior

        section = geometry_prior(config)
        mean, std, sources = [], [], []
        corr = np.eye(len(names))
        for i, n in enumerate(names):
            spec = config.parameters.get(n) if n in config.parameters else None
            if section is not None and n in section.names:
                k = section.names.index(n)
                mean.append(float(section.mean[k]))
                std.append(float(np.sqrt(section.cov[k, k])))
                sources.append(section.source)
                for j, m in enumerate(names[:i]):
                    if m in section.names and m != n:
                        kk = section.names.index(m)
                        corr[i, j] = corr[j, i] = section.cov[k, kk] / np.sqrt(section.cov[k, k]
                                                                               * section.cov[kk, kk])
                continue
            if spec is not None and spec.prior_std is not None:
                mean.append(spec.value)
                std.append(spec.prior_std)
            else:
                mean.append(0.0)
                std.append(math.inf)
            sources.append("config")
        return cls(tuple(names), np.array(mean, dtype=float), np.array(std, dtype=float),
                   None if np.array_equal(corr, np.eye(len(names))) else corr, tuple(sources))

    def _corr_given(self) -> np.ndarray:
        g = self.given
        return np.eye(int(np.count_nonzero(g))) if self.corr is None else self.corr[np.ix_(g, g)]

    @property
    def given(self) -> np.ndarray:
        """Mask of the unknowns with a prior."""
        return np.isfinite(self.std)

    @property
    def count(self) -> int:
        """Number of priors (of residuals :meth:`residuals` adds)."""
        return int(np.count_nonzero(self.given))

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """``L⁻¹ (x - μ)/σ_p`` of the unknowns with a prior (``L Lᵀ`` their correlation; independent: ``(x - μ)/σ_p``
        each): their squares add to χ², the negative log prior ×2."""
        g = self.given
        z = (np.asarray(x, dtype=float)[g] - self.mean[g]) / self.std[g]
        if self.corr is None:
            return z
        return np.asarray(np.linalg.solve(np.linalg.cholesky(self._corr_given()), z), dtype=float)

    def log_det_corr(self) -> float:
        """``ln det`` of the priors' correlation matrix (0 when independent): the normaliser's share of it."""
        return 0.0 if self.corr is None else float(np.linalg.slogdet(self._corr_given())[1])

    def information(self, scales: np.ndarray) -> np.ndarray:
        """The prior's information matrix in the relative units ``x / scales`` of a Fisher matrix."""
        g = self.given
        info = np.zeros((len(self.names), len(self.names)))
        d = np.asarray(scales, dtype=float)[g] / self.std[g]
        info[np.ix_(g, g)] = d[:, None] * np.linalg.inv(self._corr_given()) * d[None, :]
        return info

    def posterior_std(self, fisher: np.ndarray, scales: np.ndarray) -> np.ndarray:
        """Standard deviations from the data's Fisher matrix (relative units) plus the prior's information."""
        F = np.asarray(fisher, dtype=float) + self.information(scales)
        try:
            cov = np.linalg.inv(F)
        except np.linalg.LinAlgError:
            return np.full(len(self.names), math.inf)
        return np.asarray(scales, dtype=float) * np.sqrt(np.clip(np.diag(cov), 0.0, None))

    def judge(self, x: np.ndarray, posterior_std: np.ndarray) -> list[PriorCheck]:
        """Each prior's :class:`PriorCheck` at estimate ``x``, and with correlated priors one check of them
        together (their Mahalanobis distance as a normal deviate of the same tail probability)."""
        checks = [PriorCheck(n, float(self.mean[i]), float(self.std[i]), float(x[i]), float(posterior_std[i]),
                             self.sources[i] if self.sources else "config")
                  for i, n in enumerate(self.names) if self.given[i]]
        if self.corr is not None:
            from scipy import stats

            linked = self.given & (np.sum(np.abs(self.corr - np.eye(len(self.names))), axis=1) > 0)
            sub = Prior(tuple(n for n, k in zip(self.names, linked) if k), self.mean[linked], self.std[linked],
                        self.corr[np.ix_(linked, linked)])
            d = sub.residuals(np.asarray(x, dtype=float)[linked])
            chi2 = float(d @ d)
            tail = float(stats.chi2.sf(chi2, d.size))
            # far in the tail the probability underflows: the deviate is then √χ² to within its log terms
            z = float(stats.norm.isf(0.5 * tail)) if tail > 1e-300 else math.sqrt(chi2)
            source = self.sources[int(np.argmax(linked))] if self.sources else "config"
            checks.append(PriorCheck("+".join(sub.names), 0.0, 1.0, z, math.nan, source, joint=True))
        return checks
