"""Which effect, from measured natural frequencies alone: a diagnosis without a record or a force.

A free decay or another lab's modal test gives a beam's frequencies (:mod:`identification.output_modes`); a
support inside the span, a point mass, a crack or a compliant clamp moves them each by its own pattern over the
modes (:mod:`diagnosis.search.modal_pattern`).  Here the baseline — the config's unknowns fitted to the frequencies
and the config's priors, :func:`identification.modes_only.fit_modes`, with its refusals (no scale without a prior)
— and every structural effect of the catalogue (:mod:`diagnosis.effects`: the ones that change the beam, not a
signal) fitted with the baseline's unknowns to the same frequencies, from every value of the effect's coarse grid
(:func:`diagnosis.candidates.score.trial_values`), are weighed by the Bayesian information criterion
``χ² + k ln n`` (``k`` the free unknowns, ``n`` the frequencies and priors):

- ``none`` when the baseline reproduces the frequencies (χ² within its 99.9 % point) and no effect beats it by the
  BIC margin (:attr:`diagnosis.settings.Thresholds.bic_margin`);
- the effect, with its sizes and their standard deviations, when it beats the baseline and every other effect by
  the margin and reproduces the frequencies;
- ``ambiguous`` when several effects reproduce them within the margin of each other, or several reproduce them
  with as many unknowns as there are frequencies (then any would: :attr:`identification.modes_only.ModesFit.
  overdetermined`) — a handful of frequencies cannot tell every pattern apart, and the tool says which it cannot
  tell, never picks one;
- ``unexplained`` when no model reproduces them.

The modes are the lowest ones, in order (:class:`identification.modal_data.ModalData`).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ebb_model.config import BeamConfig
from ebb_model.errors import EbbError
from identification.modal_data import ModalData
from identification.modes_only import Extension, ModesFit, fit_modes, modes_input
from identification.parameters import parameter_space
from identification.prior import Prior
from identification.tracking import TrackedSegment

from .candidates.score import trial_values
from .effects import Catalogue, Effect, Scales
from .settings import thresholds_from_config

__all__ = ["EffectFromModes", "ModalDiagnosis", "diagnose_from_modes", "diagnose_segments", "segment_verdict"]


@dataclass(frozen=True)
class EffectFromModes:
    """One model of the modes: its label, fit, BIC, and for an effect its physical sizes with their standard
    deviations."""

    label: str
    fit: ModesFit
    bic: float
    sizes: dict[str, float]
    size_std: dict[str, float]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {"label": self.label, "chi2": self.fit.chi2, "chi2_with_priors": self.fit.chi2_total,
                "bic": self.bic, "agrees": self.fit.agreement["agrees"], "model_hz": self.fit.agreement["model_hz"],
                "sizes": self.sizes, "size_std": self.size_std,
                "unknowns": dict(zip(self.fit.names, map(float, self.fit.x)))}


@dataclass(frozen=True)
class ModalDiagnosis:
    """What :func:`diagnose_from_modes` concluded: the verdict (``none``, an effect's label, ``ambiguous``,
    ``unexplained``), the reason in words, the baseline, every effect's fit best first, the tied labels."""

    verdict: str
    reason: str
    baseline: EffectFromModes
    effects: tuple[EffectFromModes, ...]
    tied: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (``gap.json`` of a diagnosis from modes)."""
        return {"evidence": "measured natural frequencies only (no time record)", "verdict": self.verdict,
                "reason": self.reason, "tied": list(self.tied), "baseline": self.baseline.to_dict(),
                "effects": [e.to_dict() for e in self.effects]}

    def lines(self) -> list[str]:
        """What a user reads: the verdict and its reason, the named effect's sizes, every model's χ² and BIC."""
        out = [f"verdict: {self.verdict} — {self.reason}"]
        named = self.named
        if named is not None:
            out += [f"  {k} = {v:.5g} ± {named.size_std[k]:.2g} (1σ)" for k, v in named.sizes.items()]
        for e in (self.baseline, *self.effects):
            sizes = ", ".join(f"{k} {v:.4g}" for k, v in e.sizes.items())
            out.append(f"  {e.label}: chi2 {e.fit.chi2:.3g}, BIC {e.bic:.4g}" + (f" ({sizes})" if sizes else ""))
        return out

    @property
    def named(self) -> EffectFromModes | None:
        """The named effect's fit (``None`` unless the verdict names one)."""
        return next((e for e in self.effects if e.label == self.verdict), None)


def _structural(effect: Effect, cfg: BeamConfig, params: Mapping[str, float]) -> bool:
    """Whether ``effect`` changes the beam (config or parameters) without a signal-level part."""
    s = np.asarray(trial_values(effect.lower, effect.upper, effect.off)[-1])
    moved = effect.apply(cfg, params, s)
    return not moved.signals and (moved.config is not cfg or dict(moved.params) != dict(params))


def _extension(effect: Effect) -> Extension:
    def apply(cfg: BeamConfig, params: Mapping[str, float], s: np.ndarray) -> tuple[BeamConfig, Mapping[str, float]]:
        moved = effect.apply(cfg, params, s)
        return moved.config, moved.params

    return Extension(effect.label, effect.variables, np.asarray(effect.lower, float), np.asarray(effect.upper, float),
                     np.asarray(effect.off, float),
                     tuple(np.asarray(t, float) for t in trial_values(effect.lower, effect.upper, effect.off)), apply,
                     tuple(effect.scaled))


def _sizes(effect: Effect, fit: ModesFit) -> tuple[dict[str, float], dict[str, float]]:
    """The effect's physical sizes at the fit and their standard deviations (the covariance carried through
    the map's forward differences)."""
    k = len(effect.variables)
    s, cov = fit.x[-k:], fit.cov[-k:, -k:]
    sizes = effect.physical(s)
    keys = list(sizes)
    G = np.zeros((len(keys), k))
    for j in range(k):
        h = 1e-6 * max(abs(s[j]), abs(effect.upper[j] - effect.lower[j]) * 1e-3)
        sj = s.copy()
        sj[j] += h
        moved = effect.physical(sj)
        G[:, j] = [(moved[key] - sizes[key]) / h for key in keys]
    var = np.einsum("ij,jk,ik->i", G, cov, G)
    return sizes, {key: float(math.sqrt(max(v, 0.0))) for key, v in zip(keys, var)}


def _bic(fit: ModesFit, n: int) -> float:
    return fit.chi2_total + int(np.count_nonzero(fit.free)) * math.log(n)


def _judge(baseline: EffectFromModes, fits: list[EffectFromModes], m: int, margin: float
           ) -> tuple[str, str, tuple[str, ...]]:
    """The verdict, its reason and the tied labels (module docstring); ``fits`` best first."""
    base = baseline.fit
    beating = [e for e in fits if e.fit.agreement["agrees"] and baseline.bic - e.bic > margin]
    if not beating:
        if base.agreement["agrees"]:
            return "none", (f"the baseline reproduces the {m} frequencies (chi2 {base.chi2:.3g}) and no effect "
                            f"beats it by the BIC margin {margin:g}"), ()
        best = f"{fits[0].fit.chi2:.3g}" if fits else "none"
        return "unexplained", (f"no model reproduces the {m} frequencies (the baseline's chi2 {base.chi2:.3g}, the "
                               f"best effect's {best})"), ()
    best_fit = beating[0]
    # a fit that has as many unknowns the frequencies see as there are frequencies reproduces any of them: among
    # such fits the criterion weighs only the priors and the parameter count, not the modes' pattern
    blind = any(not e.fit.overdetermined for e in beating)
    tied = tuple(e.label for e in beating
                 if e.bic - best_fit.bic <= margin or (blind and not e.fit.overdetermined))
    if len(tied) == 1:
        return best_fit.label, (f"{best_fit.label} reproduces the {m} frequencies (chi2 {best_fit.fit.chi2:.3g}, "
                                f"the baseline's {base.chi2:.3g}) and beats every other model by the BIC margin "
                                f"{margin:g}"), ()
    return "ambiguous", (f"{', '.join(tied)} reproduce the {m} frequencies alike: these frequencies cannot tell "
                         f"them apart (more modes, shapes, or a record with its force can)"), tied


def diagnose_from_modes(config: BeamConfig | str | Path, out_dir: str | Path | None = None, *,
                        modes: ModalData | None = None) -> ModalDiagnosis:
    """Weigh the baseline and every structural effect against measured natural frequencies (module docstring).

    Parameters
    ----------
    config
        The baseline config (path or value): its unknowns with bounds and priors.
    out_dir
        Directory for ``gap.json`` (must not exist or be empty); ``None`` writes nothing.
    modes
        The measured frequencies; default the config's ``[identification.modes]``.

    Raises
    ------
    ModesOnlyError
        No measured frequencies, or the frequencies and priors leave the baseline's scale free.
    ConfigError
        An invalid config.
    """
    cfg, modes, out = modes_input(config, modes, out_dir)
    settings = thresholds_from_config(cfg)
    space = parameter_space(cfg)
    base = fit_modes(cfg, modes)
    n = modes.count + Prior.of(cfg, space.names).count          # the frequencies and the priors' pseudo-data
    baseline = EffectFromModes("baseline", base, _bic(base, n), {}, {})
    bcfg, params = space.apply(cfg, base.x)
    w = 2 * math.pi * modes.frequencies_hz
    scales = Scales(EI=params["EI"], rhoA=params["rhoA"], N=params["N"], length=cfg.beam.length,
                    omega_low=float(w[0]), omega_high=float(w[-1]), duration=1.0)
    fits = []
    for effect in Catalogue(cfg, scales, tuple(space.names)).effects():
        if not _structural(effect, bcfg, params):
            continue
        fit = fit_modes(cfg, modes, extension=_extension(effect), baseline=base)
        sizes, std = _sizes(effect, fit)
        fits.append(EffectFromModes(effect.label, fit, _bic(fit, n), sizes, std))
    fits.sort(key=lambda e: e.bic)
    verdict, reason, tied = _judge(baseline, fits, modes.count, settings.bic_margin)
    result = ModalDiagnosis(verdict, reason, baseline, tuple(fits), tied)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "gap.json").write_text(json.dumps(result.to_dict(), indent=2) + "\n", encoding="utf-8")
    return result


def diagnose_segments(config: BeamConfig, tracked: Sequence[TrackedSegment]) -> list[ModalDiagnosis | str]:
    """Per still segment of a tracked record (:func:`identification.tracking.track`), the diagnosis of its modes —
    ``none``, the effect with its sizes, ``ambiguous`` or ``unexplained``, so a series says whether some segment
    shows what the model lacks (a support come loose in one dwell, a mass added in another) — or why there is none
    (no mode; the modes and priors leave the baseline's scale free)."""
    out: list[ModalDiagnosis | str] = []
    for row in tracked:
        if row.modes.frequencies_hz.size == 0:
            out.append("the segment shows no mode")
            continue
        try:
            out.append(diagnose_from_modes(config, None, modes=row.evidence.modal_data()))
        except EbbError as exc:
            out.append(str(exc))
    return out


def segment_verdict(result: ModalDiagnosis | str) -> dict[str, Any]:
    """A segment's diagnosis as a row of ``tracked.json``: the verdict, its reason, the named effect's sizes with
    their standard deviations (or ``verdict`` None and why)."""
    if isinstance(result, str):
        return {"verdict": None, "why": result}
    named = result.named
    return {"verdict": result.verdict, "reason": result.reason, "tied": list(result.tied),
            "sizes": None if named is None else named.sizes, "size_std": None if named is None else named.size_std}
