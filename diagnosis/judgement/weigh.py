"""The evidence the rules judge by, measured once (:func:`weigh`): what is implausible about each refit, the
baseline against the user's priors, the posterior probabilities of the baseline and the refits, the refits
degenerate with the baseline unknowns, and each model against the measured modes.  Nothing here decides; the
rules of :mod:`diagnosis.judgement.rules` do."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

from identification.prior import PriorCheck

from ..problem.fitting import GapProblem
from ..search.rank import Ranking
from ..problem.evidence import log_posteriors, numerics_shift
from ..problem.plausibility import confounded, implausibilities, prior_checks

__all__ = ["Weighed", "weigh", "chain_degeneracies"]


@dataclass(frozen=True)
class Weighed:
    """What :func:`weigh` measured.

    Attributes
    ----------
    implausible
        Per refit that needs implausible values, what is implausible (one line each).
    priors
        The baseline's unknowns against the user's priors (:class:`identification.prior.PriorCheck`, empty without
        priors); :attr:`conflicts` are those in conflict.
    evidence
        Posterior probabilities of the baseline (``"none"``) and the refits (:mod:`diagnosis.problem.evidence`).
    log_posterior
        Their natural logarithms (what a later diagnosis of the same bench weighs its records against).
    confounded
        Per refit degenerate with the baseline unknowns, the line saying with which combination.
    modal_data
        Per model (``"none"``: the baseline) its agreement with the config's measured modes (empty without them).
    """

    implausible: dict[str, list[str]]
    priors: list[PriorCheck]
    evidence: dict[str, float]
    confounded: dict[str, str]
    modal_data: dict[str, dict[str, Any]]
    log_posterior: dict[str, float] = field(default_factory=dict)

    @property
    def conflicts(self) -> list[PriorCheck]:
        """The baseline's priors in conflict with it."""
        return [c for c in self.priors if c.status == "conflict"]


def weigh(problem: GapProblem, ranking: Ranking, band_hz: float,
          earlier: Mapping[str, float] | None = None) -> Weighed:
    """Measure the evidence on every refit of ``ranking`` (the effects it carries, :attr:`Ranking.effects`); the
    posterior probabilities on the finer numerics for the excited band's top ``band_hz``
    (:func:`~diagnosis.problem.evidence.numerics_shift`), from the prior ``earlier`` (an earlier diagnosis' log
    posteriors, :func:`~diagnosis.problem.evidence.log_posteriors`) when given."""
    effects = ranking.effects
    issues = {lab: implausibilities(problem, effects[lab], rf.fit) for lab, rf in ranking.refits.items()}
    priors = prior_checks(problem, ranking.baseline)
    logp = log_posteriors(problem, ranking.baseline, {lab: rf.fit for lab, rf in ranking.refits.items()},
                          effects=effects, shift=numerics_shift(problem, ranking.baseline, band_hz), earlier=earlier)
    probs = {lab: math.exp(v) for lab, v in logp.items()}
    tangled = {lab: line for lab, rf in ranking.refits.items()
               if (line := confounded(problem, effects[lab], rf.fit)) is not None}
    agreement: dict[str, dict[str, Any]] = {}
    if problem.modes is not None:
        m = problem.modes_model(ranking.baseline.beta)
        agreement["none"] = problem.modes.agreement(m.config, m.params)
        for lab, rf in ranking.refits.items():
            m = problem.modes_model(rf.fit.beta, effects[lab], rf.fit.s)
            agreement[lab] = problem.modes.agreement(m.config, m.params)
    return Weighed({lab: v for lab, v in issues.items() if v}, priors, probs, tangled, agreement, logp)


def chain_degeneracies(problem: GapProblem, ranking: Ranking, weighed: Weighed) -> dict[str, str]:
    """The measurement chain's gains (:attr:`~diagnosis.effects.Effect.scale_degenerate`) the data cannot tell
    from the beam's unknowns at the baseline, each with its line — what a model at the noise floor may still owe
    to a miscalibrated chain (refits already found degenerate are not measured again)."""
    return {lab: line for lab, e in ranking.effects.items() if e.scale_degenerate and lab not in weighed.confounded
            and (line := confounded(problem, e, ranking.baseline, at_baseline=True)) is not None}
