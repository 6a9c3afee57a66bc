"""The diagnosis' result as typed values, and its one serialisation (``gap.json``).

:class:`GapReport` is what :func:`diagnosis.run.diagnose` found — the verdict and its reason, the baseline, the
measured modes, where the gap is (:class:`~diagnosis.localise.Localisation` per record) and every effect's row
(:class:`EffectRow`: score, refit, modal pattern).  The text report, the plots and the command line read these
fields; :meth:`GapReport.to_dict` is the ``gap.json`` document (strict JSON: :func:`ebb_model.io.jsonio.jsonable`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

from ebb_model.space.adequacy import NumericalAdequacy, grid_line
from ebb_model.space.grid_advice import GridAdvice
from ebb_model.io.jsonio import jsonable
from identification.prior import PriorCheck

from ..localise import Localisation
from ..search.modal_estimate import MeasuredModes
from ..baseline.polarity import PolarityCheck
from ..judgement.verdict import Verdict
from ..settings import Thresholds
from ..design import NextExperiment
from ..judgement.apart import SetupsApart
from ..search.plausible import PlausibleReading
from ..setups import Setups

__all__ = ["BandClosure", "RefitSummary", "PatternMatch", "EffectRow", "BaselineSummary", "DiagnosisSettings",
           "GapReport"]


@dataclass(frozen=True)
class BandClosure:
    """Held-out gap ratio in one frequency band before and after an effect's refit (1 = the noise floor);
    ``closed`` is ``None`` where the band had no gap to close."""

    band_hz: tuple[float, float]
    gap_ratio_before: float
    gap_ratio_after: float
    closed: float | None


@dataclass(frozen=True)
class RefitSummary:
    """An effect's refit together with the baseline unknowns (:mod:`diagnosis.search.refits`), per sensor by name.

    ``model_modes_hz`` are the refitted model's modes (the baseline's in-band ones and the next), for a
    cross-check against an independent modal test.
    """

    effect_parameters: Mapping[str, float]
    baseline_parameters: Mapping[str, float]
    delta_bic: float
    delta_aic: float
    heldout_gap_ratio_before: Mapping[str, float]
    heldout_gap_ratio_after: Mapping[str, float]
    closed: float
    closed_per_sensor: Mapping[str, float | None]
    closed_per_band: tuple[BandClosure, ...]
    n_evaluations: int
    model_modes_hz: tuple[float, ...]


@dataclass(frozen=True)
class PatternMatch:
    """An effect's modal-pattern fit to the measured modes (:mod:`diagnosis.search.modal_pattern`)."""

    chi2: float
    freq_hz: tuple[float, ...]
    damping: tuple[float, ...]


@dataclass(frozen=True)
class EffectRow:
    """One candidate effect in ranking order: its score test and, when refitted, its refit and modal match.

    ``score`` and ``p_value`` are ``None`` for a pair (it has no score test of its own).
    """

    rank: int
    label: str
    effect: str
    target: str | None
    description: str
    score: float | None
    p_value: float | None
    shortlisted: bool
    refit: RefitSummary | None = None
    modal_pattern: PatternMatch | None = None
    #: for a candidate with a significant score and no refit: why (:mod:`diagnosis.search.exclusions`)
    not_refitted: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready row (``refit``, ``modal_pattern`` and ``not_refitted`` only when there is one)."""
        row = {k: jsonable(v) for k, v in vars(self).items() if k not in ("refit", "modal_pattern", "not_refitted")}
        if self.not_refitted is not None:
            row["not_refitted"] = self.not_refitted
        if self.refit is not None:
            row["refit"] = jsonable(self.refit)
        if self.modal_pattern is not None:
            row["modal_pattern"] = jsonable(self.modal_pattern)
        return row


@dataclass(frozen=True)
class BaselineSummary:
    """The baseline fit (the model without effect): parameters, gap ratios (1 = the noise floor), BIC, its in-band
    modes, and how much of its gap is the model's own grid (:mod:`ebb_model.space.adequacy`,
    :mod:`ebb_model.space.grid_advice`)."""

    parameters: Mapping[str, float]
    fit_gap_ratio: float
    heldout_gap_ratio: Mapping[str, float]
    bic: float
    n_evaluations: int
    model_modes_hz: tuple[float, ...]
    numerical_adequacy: NumericalAdequacy
    grid_advice: GridAdvice

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {"parameters": jsonable(self.parameters), "fit_gap_ratio": jsonable(self.fit_gap_ratio),
                "heldout_gap_ratio": jsonable(self.heldout_gap_ratio), "bic": jsonable(self.bic),
                "n_evaluations": self.n_evaluations, "model_modes_hz": jsonable(self.model_modes_hz),
                "numerical_adequacy": self.numerical_adequacy.to_dict(),
                "grid_advice": self.grid_advice.to_dict() | {"summary": self.grid_summary}}

    @property
    def grid_summary(self) -> str:
        """The one grid advice from the records (:func:`ebb_model.space.adequacy.grid_line`)."""
        return grid_line(self.grid_advice, self.numerical_adequacy)


@dataclass(frozen=True)
class DiagnosisSettings:
    """The settings a diagnosis ran with: held-out records or fraction, and every threshold
    (:class:`~diagnosis.settings.Thresholds`, with the reason for each value)."""

    holdout: tuple[str, ...]
    holdout_fraction: float | None
    thresholds: Thresholds

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the held-out choice and the thresholds, side by side."""
        return {"holdout": list(self.holdout), "holdout_fraction": self.holdout_fraction} | self.thresholds.to_dict()


@dataclass(frozen=True)
class GapReport:
    """What the diagnosis found (module docstring).

    Attributes
    ----------
    judged
        The verdict (:class:`~diagnosis.judgement.verdict.Verdict`: its kind, the named effect, its ties and the
        reasons each rule gave); :attr:`verdict`, :attr:`reason` and :attr:`indistinguishable` are its name, its
        text and its ties.
    noise_std, excited_band_hz
        Noise standard deviation per sensor and the excited frequency band.
    baseline
        The baseline fit.
    measured_modes, baseline_pattern_chi2
        The measured modes and the baseline's modal-pattern χ², when the modal pattern was needed.
    localisation, summary
        Where the gap is, per record, and its summary lines.
    effects
        Every candidate in ranking order.
    settings
        The settings of the run.
    corrected_files
        The corrected model's files (in ``corrected/`` beside ``gap.json``), when it was exported.
    implausible
        The refits that need implausible values (:mod:`diagnosis.problem.plausibility`), with what is implausible:
        never the verdict, never exported.
    priors
        The baseline's unknowns against the user's priors (:class:`identification.prior.PriorCheck`).
    evidence
        Posterior probability of the baseline (``"none"``) and of each refit (:mod:`diagnosis.problem.evidence`).
    log_posterior
        Their natural logarithms (``log_posterior`` in ``gap.json``: a later diagnosis of the same bench starts
        from them, ``diagnose(..., earlier=)``).
    confounded
        The refits degenerate with the baseline unknowns, and with which (only a prior separates them).
    modal_data
        The baseline (``"none"``) and each refit against the measured modes of the config
        (:meth:`identification.modal_data.ModalData.agreement`), when it gives them.
    polarity
        The baseline with the measured force as read and reversed (:mod:`diagnosis.baseline.polarity`).
    stage_seconds
        Wall seconds per stage of the run, each second counted once (:mod:`diagnosis.stages`).
    setups
        Which set-up each kind of evidence was measured in, with its rig parts (:mod:`diagnosis.setups`).
    setups_apart
        When the records and the measured modes disagreed more than one structure explains: the reading as two
        set-ups and whether it was adopted (:mod:`diagnosis.judgement.apart`).
    plausible_readings
        When no effect is named: the closing refits held within the plausibility limits that still close the named
        share of the gap, most probable first (:mod:`diagnosis.search.plausible`).
    next_experiment
        When candidates remain tied or the gap is unexplained, the record that would separate the leading
        candidates best (:mod:`diagnosis.design`).
    events
        What happened to the run's workers worth telling (a Dask worker lost mid-run), one sentence each.
    """

    judged: Verdict
    noise_std: Mapping[str, float]
    excited_band_hz: tuple[float, float]
    baseline: BaselineSummary
    measured_modes: MeasuredModes | None
    baseline_pattern_chi2: float | None
    localisation: Mapping[str, Localisation]
    summary: tuple[str, ...]
    effects: tuple[EffectRow, ...]
    settings: DiagnosisSettings
    corrected_files: tuple[str, ...] | None = field(default=None)
    implausible: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    priors: tuple[PriorCheck, ...] = ()
    evidence: Mapping[str, float] = field(default_factory=dict)
    log_posterior: Mapping[str, float] = field(default_factory=dict)
    confounded: Mapping[str, str] = field(default_factory=dict)
    modal_data: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    polarity: PolarityCheck | None = None
    stage_seconds: Mapping[str, float] = field(default_factory=dict)
    setups: Setups | None = None
    next_experiment: NextExperiment | None = None
    setups_apart: SetupsApart | None = None
    plausible_readings: tuple[PlausibleReading, ...] = ()
    events: tuple[str, ...] = ()

    @property
    def verdict(self) -> str:
        """The effect's label, ``"none"``, ``"unexplained"``, ``"indistinguishable"`` or ``"grid"``."""
        return self.judged.name

    @property
    def reason(self) -> str:
        """Why, in words (the verdict's reasons in the order the rules gave them)."""
        return self.judged.text()

    @property
    def indistinguishable(self) -> tuple[str, ...]:
        """Effects the data cannot tell from the verdict (for ``"indistinguishable"``: the candidates, the most
        probable first)."""
        return self.judged.ties

    def row(self, label: str) -> EffectRow | None:
        """The row of effect ``label`` (``None`` if it is not in the catalogue)."""
        return next((r for r in self.effects if r.label == label), None)

    def to_dict(self) -> dict[str, Any]:
        """The ``gap.json`` document."""
        modes = None
        if self.measured_modes is not None:
            modes = self.measured_modes.to_dict() | (
                {} if self.baseline_pattern_chi2 is None else {"baseline_pattern_chi2": self.baseline_pattern_chi2})
        doc: dict[str, Any] = {
            "verdict": self.verdict, "reason": self.reason, "indistinguishable": list(self.indistinguishable),
            "noise_std": jsonable(self.noise_std), "excited_band_hz": jsonable(self.excited_band_hz),
            "baseline": self.baseline.to_dict(), "measured_modes": jsonable(modes),
            "localisation": {name: loc.to_dict() for name, loc in self.localisation.items()},
            "summary": list(self.summary), "effects": [r.to_dict() for r in self.effects],
            "settings": self.settings.to_dict(), "judgement": self.judged.to_dict()}
        if self.evidence:
            doc["posterior_probability"] = {k: float(v) for k, v in self.evidence.items()}
        if self.log_posterior:
            doc["log_posterior"] = {k: float(v) for k, v in self.log_posterior.items()}
        if self.confounded:
            doc["confounded"] = dict(self.confounded)
        if self.modal_data:
            doc["against_measured_modes"] = {k: dict(v) for k, v in self.modal_data.items()}
        if self.implausible:
            doc["implausible"] = {k: list(v) for k, v in self.implausible.items()}
        if self.polarity is not None:
            doc["force_sign"] = self.polarity.to_dict()
        if self.setups is not None:
            doc["setups"] = self.setups.to_dict()
        if self.setups_apart is not None:
            doc["setups_apart"] = self.setups_apart.to_dict()
        if self.plausible_readings:
            doc["plausible_readings"] = [r.to_dict() for r in self.plausible_readings]
        if self.next_experiment is not None:
            doc["next_experiment"] = self.next_experiment.to_dict()
        if self.priors:
            doc["baseline"]["priors"] = {c.name: c.to_dict() for c in self.priors}
        if self.corrected_files is not None:
            doc["corrected"] = {"directory": "corrected", "files": list(self.corrected_files)}
        if self.events:
            doc["events"] = list(self.events)
        if self.stage_seconds:
            doc["stage_seconds"] = {k: float(v) for k, v in self.stage_seconds.items()}
        return doc
