"""One verdict pipeline: an ordered list of rules (:data:`RULES`), each taking the verdict so far and returning
the next (:class:`~diagnosis.judgement.verdict.Verdict`), run by :func:`judge`.

1. **naming** — from the refits alone: nothing to explain, an effect (with its ties), or unexplained
   (:func:`~diagnosis.judgement.verdict.name_cause`);
2. **numerical adequacy** — a gap that refining the model's grid changes is the grid's, not an effect's;
3. **plausibility** — an effect named only with values no rig has is not named (the verdict goes to the best
   plausible candidate); a baseline at the floor only by breaking a prior yields to a plausible refit that keeps
   every prior; the baseline's prior conflicts said;
4. **nested cases** — a special case of a tied general effect (:attr:`~diagnosis.effects.Effect.nested_in`) that
   brings the held-out records to the floor on its own is named instead of it;
5. **evidence and ties** — between tied candidates the posterior odds decide, or the verdict is
   ``indistinguishable``;
6. **notes** — posterior probability, degeneracies, the measurement chain's scale, the measured modes, the force's
   sign, where an unexplained gap lies;
7. **set-ups** — the set-ups told apart, when tried; **plausible readings** — what the records allow with every
   closing refit held within plausibility, when no effect is named.

Every rule reads its thresholds from the one settings object (:attr:`GapProblem.settings
<diagnosis.problem.fitting.GapProblem.settings>`); the verdict's text is rendered once, from its reasons.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from ebb_model.space.adequacy import NumericalAdequacy
from ebb_model.space.grid_advice import GridAdvice

from ..baseline.polarity import PolarityCheck
from ..effects import PAIR_SEPARATOR
from ..localise import Localisation
from ..problem.fitting import GapProblem
from ..problem.ties import tie_ordered
from ..search.plausible import PlausibleReading, readings_text
from ..search.rank import Ranking
from .apart import SetupsApart
from .verdict import Kind, Reason, Verdict, by_evidence, name_cause, named
from .weigh import Weighed, chain_degeneracies

__all__ = ["Case", "Judgement", "RULES", "judge"]


@dataclass(frozen=True, eq=False)
class Case:
    """Everything the rules judge: the search's ranking (refits, and the effect behind each label), the measured
    evidence, the grid's share of the gap with its advice, the force's sign check and where the gap lies."""

    problem: GapProblem
    ranking: Ranking
    weighed: Weighed
    grid_share: float
    grid_advice: str
    polarity: PolarityCheck
    where: tuple[str, ...] = ()
    #: the set-ups told apart when they were tried (:mod:`diagnosis.judgement.apart`), said by the rules
    apart: SetupsApart | None = None
    #: what the records allow once the closing refits are held within plausibility (said when no effect is named)
    readings: tuple[PlausibleReading, ...] = ()
    #: the grid's adequacy and advice behind ``grid_share`` and ``grid_advice`` (for the report)
    adequacy: NumericalAdequacy | None = None
    advice: GridAdvice | None = None
    #: the localisation of the baseline's residual per record behind ``where`` (for the report)
    locs: tuple[Localisation, ...] = ()
    #: the measurement chain's degeneracies, measured when a rule first asks (:func:`chain_degeneracies`)
    _chain: dict[str, dict[str, str]] = field(default_factory=dict, repr=False)

    def chain(self) -> dict[str, str]:
        """:func:`~diagnosis.judgement.weigh.chain_degeneracies`, measured once."""
        if "lines" not in self._chain:
            self._chain["lines"] = chain_degeneracies(self.problem, self.ranking, self.weighed)
        return self._chain["lines"]


Rule = Callable[[Verdict, Case], Verdict]


def naming(_: Verdict, case: Case) -> Verdict:
    """The verdict from the refits alone (:func:`~diagnosis.judgement.verdict.name_cause`)."""
    r = case.ranking
    return name_cause(r.heldout_before, r.refits, r.paying, case.problem.settings)


def numerical(verdict: Verdict, case: Case) -> Verdict:
    """The grid's verdict when refining the model's grid changes more than ``numerical_share_limit`` of the
    baseline gap; a caution on a named effect from ``grid_caution``.  A held-out gap within the gap threshold of
    the noise floor is no gap: the verdict stays whatever share of that remainder the grid makes."""
    settings, share = case.problem.settings, case.grid_share
    if float(np.mean(case.ranking.heldout_before)) - 1.0 < settings.gap_threshold:
        return verdict
    if share > settings.numerical_share_limit:
        instead = f" (the best-ranked effect, {verdict.name}, is not blamed)" if verdict.kind is Kind.EFFECT else ""
        return Verdict(Kind.GRID, reasons=(Reason("numerical adequacy", (
            f"the model's grid: refining it changes the model by {100 * share:.0f} % of the baseline gap, so the "
            f"gap is largely the model's own discretisation error{instead}; {case.grid_advice}")),))
    if share > settings.grid_caution and verdict.kind is not Kind.NONE:
        return verdict.said("numerical adequacy", f"caution: {100 * share:.0f} % of the baseline gap is the "
                                                  f"model's grid; {case.grid_advice}")
    return verdict


def plausibility(verdict: Verdict, case: Case) -> Verdict:
    """An implausible refit is not named (the naming rule again among the plausible refits); a baseline at the
    noise floor only by breaking a prior yields to a plausible refit that keeps every prior, stays at the floor and
    pays for itself; the baseline's conflicts with the priors are said."""
    problem, ranking, issues = case.problem, case.ranking, case.weighed.implausible
    settings = problem.settings
    if verdict.kind is Kind.NONE:
        resolved = _prior_conflict(verdict, case)
        if resolved is not verdict:
            return resolved                   # its reason says the baseline's conflicts
    elif verdict.label in issues:
        refits = {lab: rf for lab, rf in ranking.refits.items() if lab not in issues}
        before = ranking.heldout_before
        paying = [lab for lab in ranking.order if lab in refits and refits[lab].delta_bic < -settings.bic_margin
                  and np.mean(refits[lab].heldout_after) < np.mean(before)]
        among = name_cause(before, refits, paying, settings, rule="plausibility")
        first, *rest = among.reasons
        why = Reason("plausibility", (
            f"{verdict.label} is not named: its refit needs implausible values ({'; '.join(issues[verdict.label])})"
            f" — among the plausible candidates: {first.text}"))
        verdict = replace(among, reasons=(why, *rest))
    if case.weighed.conflicts:
        verdict = verdict.said("plausibility", "baseline: " + "; ".join(c.line() for c in case.weighed.conflicts))
    return verdict


def _prior_conflict(verdict: Verdict, case: Case) -> Verdict:
    """``verdict`` (``none``) unchanged unless the baseline is in conflict with a prior and a plausible refit that
    keeps the records at the noise floor and pays for itself (ΔBIC with the priors' terms) resolves it."""
    problem, ranking = case.problem, case.ranking
    conflicts = case.weighed.conflicts
    if not conflicts:
        return verdict
    settings = problem.settings
    ok = [lab for lab in ranking.order if lab in ranking.refits and lab not in case.weighed.implausible
          and ranking.refits[lab].delta_bic < -settings.bic_margin
          and float(np.mean(ranking.refits[lab].heldout_after)) - 1.0 <= settings.gap_threshold]
    if not ok:
        return verdict
    best = tie_ordered(ok, lambda lab: ranking.refits[lab].delta_bic)[0]
    # the others that keep the priors as well and pay nearly as much are its ties, for the evidence to decide (a
    # sensor's gain and the force's on a record of one sensor: one model, their BICs apart by round-off only)
    ties = [lab for lab in ok if lab != best
            and ranking.refits[lab].delta_bic - ranking.refits[best].delta_bic < settings.bic_margin]
    names = ", ".join(c.name for c in conflicts)
    return named(best, ties, (Reason("plausibility", (
        f"the baseline matches the records only with {names} in conflict with the prior "
        f"({'; '.join(c.line() for c in conflicts)}); {best} matches them as well with every prior kept "
        f"(held-out gap ratio {np.mean(ranking.refits[best].heldout_after):.3g}, "
        f"dBIC {ranking.refits[best].delta_bic:.1f} with the priors' terms)")),))


def nested(verdict: Verdict, case: Case) -> Verdict:
    """Among the named effect and its ties, a special case of another of them (:attr:`Effect.nested_in
    <diagnosis.effects.Effect.nested_in>`) whose refit brings the held-out records within the gap threshold of the
    noise floor is named instead: the general effect's extra variables buy fit the held-out records do not
    confirm."""
    ranking = case.ranking
    if verdict.kind is not Kind.EFFECT or verdict.label not in ranking.refits:
        return verdict
    group = [verdict.label, *verdict.ties]
    # (a pair's label in either order: the armature is nested in the pair of a point mass and a spring)
    members = {frozenset(lab.split(PAIR_SEPARATOR)): lab for lab in group}
    for lab in group:
        e = ranking.effects.get(lab)
        general = None if e is None or e.nested_in is None else frozenset(e.nested_in.split(PAIR_SEPARATOR))
        if (general in members and lab in ranking.refits
                and float(np.mean(ranking.refits[lab].heldout_after)) - 1.0 <= case.problem.settings.gap_threshold):
            left = np.mean(ranking.refits[lab].heldout_after)
            return named(lab, (), verdict.reasons).said("nested cases", (
                f"{lab} is {members[general]} with fewer variables and brings the held-out records to the noise "
                f"floor on its own (gap ratio {left:.3g}): named instead of {members[general]}"))
    return verdict


def evidence(verdict: Verdict, case: Case) -> Verdict:
    """Between a named effect and its ties the posterior odds decide (by ``decisive_odds``), or the verdict is
    ``indistinguishable`` (:func:`~diagnosis.judgement.verdict.by_evidence`)."""
    if verdict.kind is not Kind.EFFECT or verdict.label not in case.ranking.refits or not verdict.ties:
        return verdict
    return by_evidence(verdict, case.weighed.evidence, case.problem.settings.decisive_odds,
                       remains=_remains(verdict, case))


def _remains(verdict: Verdict, case: Case) -> float | None:
    """The held-out gap ratio the named effect leaves when it is above the noise floor (beyond ``gap_threshold``),
    ``None`` when it reaches the floor or the verdict names no refit (``none`` is at the floor by its rule)."""
    refit = case.ranking.refits.get(verdict.label) if verdict.label is not None else None
    if refit is None:
        return None
    left = float(np.mean(refit.heldout_after))
    return left if left - 1.0 > case.problem.settings.gap_threshold else None


def notes(verdict: Verdict, case: Case) -> Verdict:
    """What else the evidence says of the verdict: its posterior probability (when it reaches the noise floor:
    :func:`~diagnosis.judgement.verdict.by_evidence`), a degeneracy with the baseline
    unknowns, for ``none`` the measurement chain's gains the data cannot tell from the beam's scale (listed as
    ties), its agreement with the measured modes, the force's sign when reversed or undecided, and for
    ``unexplained`` where the gap lies."""
    w, name = case.weighed, verdict.name
    if name in w.evidence and _remains(verdict, case) is None:    # a probability only among models that fit
        others = [f"{lab} {p:.2g}" for lab, p in w.evidence.items() if lab != name][:2]
        rivals = f"next: {', '.join(others)}" if others else "the only model weighed: no effect was refitted"
        verdict = verdict.said("notes", f"posterior probability {w.evidence[name]:.3g} (Laplace evidence; {rivals})")
    if name in w.confounded:
        verdict = verdict.said("notes", w.confounded[name])
    if verdict.kind is Kind.NONE and case.chain():
        verdict = replace(verdict, ties=tuple(case.chain())).said("notes", (
            "the data cannot tell a gain error of the measurement chain from the beam's own scale ("
            + "; ".join(case.chain().values()) + ")"))
    if w.modal_data:
        key = name if name in w.modal_data else "none"
        a = w.modal_data[key]
        verdict = verdict.said("notes", (
            f"the {'baseline' if key == 'none' else key} model {'agrees' if a['agrees'] else 'DISAGREES'} with the "
            f"{a['modes']} measured modes (chi2 {a['chi2']:.3g}, limit {a['chi2_limit']:.3g})"))
    if case.polarity.reversed or not case.polarity.decided or case.polarity.overturned:
        verdict = verdict.said("notes", case.polarity.line())
    if verdict.kind is Kind.UNEXPLAINED and case.where:
        # what the localisation found is the user's lead, not the least-bad name
        verdict = verdict.said("notes", "where the gap is: " + "; ".join(case.where))
    return verdict


def setups(verdict: Verdict, case: Case) -> Verdict:
    """The set-ups told apart, when they were tried: why, how, and whether that reading was adopted."""
    return verdict if case.apart is None else verdict.said("set-ups", case.apart.text())


def readings(verdict: Verdict, case: Case) -> Verdict:
    """When no effect is named: what the records allow with every closing refit held within plausibility."""
    if verdict.kind is Kind.EFFECT or not case.readings:
        return verdict
    return verdict.said("plausible readings", readings_text(list(case.readings)))


#: The rules in the order they apply, each with its name.
RULES: tuple[tuple[str, Rule], ...] = (
    ("naming", naming), ("numerical adequacy", numerical), ("plausibility", plausibility),
    ("nested cases", nested), ("evidence and ties", evidence), ("notes", notes), ("set-ups", setups),
    ("plausible readings", readings))


@dataclass(frozen=True)
class Judgement:
    """The verdict and the evidence behind it; ``confounded`` adds the measurement chain's degeneracies when the
    notes measured them."""

    verdict: Verdict
    weighed: Weighed
    confounded: dict[str, str]


def judge(case: Case, rules: tuple[tuple[str, Rule], ...] = RULES) -> Judgement:
    """Run ``rules`` in order on ``case``, from an empty verdict (the naming rule makes the first)."""
    verdict = Verdict(Kind.UNEXPLAINED)
    for _, rule in rules:
        verdict = rule(verdict, case)
    chain = case.chain() if verdict.kind is Kind.NONE else {}
    return Judgement(verdict, case.weighed, case.weighed.confounded | chain)
