"""The evidence behind a verdict, weighed and said: priors, posterior probabilities, degeneracies and the
measured modes (:func:`weigh`)."""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Mapping

import numpy as np

from ..effects import PAIR_SEPARATOR, Effect
from .evidence import posterior_probabilities
from ..problem.fitting import GapProblem
from .plausibility import confounded, prior_checks
from ..search.rank import Ranking
from .verdict import INDISTINGUISHABLE, by_evidence

__all__ = ["Weighed", "weigh"]


@dataclass(frozen=True)
class Weighed:
    """What :func:`weigh` found: posterior probabilities, degenerate refits, agreement with measured modes."""

    evidence: dict[str, float]
    confounded: dict[str, str]
    modal_data: dict[str, dict[str, Any]]


def _adequate_special_case(ranking: Ranking, by_label: Mapping[str, Effect], gap_threshold: float
                           ) -> tuple[str, str] | None:
    """Among the verdict and its ties, a special case of another of them (:attr:`Effect.nested_in`) whose refit
    brings the held-out records within the gap threshold of the noise floor — the
    general effect's extra variables then buy fit the held-out records do not confirm.  Returns the special
    case's label and the general one's."""
    group = [ranking.verdict, *ranking.indistinguishable]
    if ranking.verdict not in ranking.refits:
        return None
    # (a pair's label in either order: the armature is nested in the pair of a point mass and a spring)
    members = {frozenset(lab.split(PAIR_SEPARATOR)): lab for lab in group}
    for lab in group:
        e = by_label.get(lab)
        general = None if e is None or e.nested_in is None else frozenset(e.nested_in.split(PAIR_SEPARATOR))
        if (general in members and lab in ranking.refits
                and float(np.mean(ranking.refits[lab].heldout_after)) - 1.0 <= gap_threshold):
            return lab, members[general]
    return None


def weigh(problem: GapProblem, ranking: Ranking, by_label: Mapping[str, Effect]) -> tuple[Ranking, Weighed]:
    """The evidence behind the verdict, said in its reason: the baseline against the user's priors (a conflict
    — the prior, the data or the model is wrong — is said, not hidden), the posterior probabilities of the
    baseline and the refits (:mod:`diagnosis.judgement.evidence`), the refits degenerate with the baseline unknowns
    (:func:`diagnosis.judgement.plausibility.confounded`), and each model against the measured modes when the config
    gives them (:mod:`identification.modal_data`)."""
    reason = ranking.reason
    conflicts = [c.line() for c in prior_checks(problem, ranking.baseline) if c.status == "conflict"]
    if conflicts:
        reason += "; baseline: " + "; ".join(conflicts)
    probs = posterior_probabilities(problem, ranking.baseline, {lab: rf.fit for lab, rf in ranking.refits.items()})
    special = _adequate_special_case(ranking, by_label, problem.settings.gap_threshold)
    if special is not None:
        simpler, general = special
        rf = ranking.refits[simpler]
        reason += (f"; {simpler} is {general} with fewer variables and brings the held-out records to the noise "
                   f"floor on its own (gap ratio {np.mean(rf.heldout_after):.3g}): named instead of {general}")
        ranking = replace(ranking, verdict=simpler, indistinguishable=[])
    elif ranking.verdict in ranking.refits and ranking.indistinguishable:
        # the fits could not separate the verdict from its ties: the evidence decides, or says it cannot
        verdict, listed, sentence = by_evidence(ranking.verdict, ranking.indistinguishable, probs,
                                                problem.settings.decisive_odds)
        reason = (f"{sentence}; {reason}" if verdict == INDISTINGUISHABLE else f"{reason}; {sentence}")
        ranking = replace(ranking, verdict=verdict, indistinguishable=listed)
    if ranking.verdict in probs:
        others = [f"{lab} {p:.2g}" for lab, p in probs.items() if lab != ranking.verdict][:2]
        reason += (f"; posterior probability {probs[ranking.verdict]:.3g} (Laplace evidence; next: "
                   f"{', '.join(others)})")
    tangled = {lab: line for lab, rf in ranking.refits.items()
               if (line := confounded(problem, by_label[lab], rf.fit)) is not None}
    if ranking.verdict in tangled:
        reason += "; " + tangled[ranking.verdict]
    if ranking.verdict == "none":
        # a model at the noise floor may still owe its scale to a miscalibrated chain: say which gains the data
        # cannot tell from the beam's unknowns
        chain = {lab: line for lab, e in by_label.items() if e.scale_degenerate and lab not in tangled
                 and (line := confounded(problem, e, ranking.baseline, at_baseline=True)) is not None}
        tangled |= chain
        if chain:
            reason += ("; the data cannot tell a gain error of the measurement chain from the beam's own scale ("
                       + "; ".join(chain.values()) + ")")
            ranking = replace(ranking, indistinguishable=list(chain))
    agreement: dict[str, dict[str, Any]] = {}
    if problem.modes is not None:
        m = problem.model(ranking.baseline.beta)
        agreement["none"] = problem.modes.agreement(m.config, m.params)
        for lab, rf in ranking.refits.items():
            m = problem.model(rf.fit.beta, by_label[lab], rf.fit.s)
            agreement[lab] = problem.modes.agreement(m.config, m.params)
        key = ranking.verdict if ranking.verdict in agreement else "none"
        a = agreement[key]
        reason += (f"; the {'baseline' if key == 'none' else key} model "
                   f"{'agrees' if a['agrees'] else 'DISAGREES'} with the {a['modes']} measured modes "
                   f"(chi2 {a['chi2']:.3g}, limit {a['chi2_limit']:.3g})")
    return replace(ranking, reason=reason), Weighed(probs, tangled, agreement)
