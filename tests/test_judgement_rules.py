"""The verdict pipeline (:mod:`diagnosis.judgement.rules`) on hand-made rankings — no simulation: each rule in
its place, each reason credited to the rule that gave it, the text rendered once from the reasons.

A ranking here holds refit summaries made by hand (held-out gap ratio after, closure, ΔBIC) and the effect behind
each label reduced to what the rules read of it (``nested_in``, ``scale_degenerate``); the measured evidence
(:class:`~diagnosis.judgement.weigh.Weighed`) is given directly.
"""
from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from diagnosis.judgement.rules import RULES, Case, judge
from diagnosis.judgement.verdict import Kind
from diagnosis.judgement.weigh import Weighed
from diagnosis.search.rank import Ranking
from diagnosis.search.refits import EffectRefit
from diagnosis.settings import Thresholds

BEFORE = np.array([40.0, 60.0])      # the baseline's held-out gap ratio per sensor (mean 50)
SETTINGS = Thresholds()


def refit(label: str, after: float, delta_bic: float = -500.0) -> EffectRefit:
    """A refit leaving ``after`` noise variances on both sensors (its fit left at the same level)."""
    closed = (np.mean(BEFORE) - after) / (np.mean(BEFORE) - 1.0)
    fit = SimpleNamespace(rss=after * 100.0, n=100)
    return EffectRefit(label, fit, {}, 0.0, 0.0, delta_bic, 0.0, np.array([after, after]), float(closed),
                       np.array([closed, closed]))


def effect(nested_in: str | None = None, chain: bool = False) -> SimpleNamespace:
    return SimpleNamespace(nested_in=nested_in, scale_degenerate=chain)


def case(refits: dict[str, EffectRefit], *, effects: dict | None = None, share: float = 0.0,
         implausible: dict | None = None, evidence: dict | None = None, reversed_force: bool = False,
         where: tuple[str, ...] = (), before: np.ndarray = BEFORE, settings: Thresholds = SETTINGS) -> Case:
    """A case whose refits pay in held-out order (the search's ``paying``) and whose force's sign was decided."""
    paying = sorted((lab for lab, rf in refits.items() if rf.delta_bic < -settings.bic_margin),
                    key=lambda lab: float(np.mean(refits[lab].heldout_after)))
    ranking = Ranking(SimpleNamespace(beta=np.zeros(2)), before, {}, refits, list(paying), paying,
                      effects if effects is not None else {lab: effect() for lab in refits})
    polarity = SimpleNamespace(reversed=reversed_force, decided=True, overturned=False,
                               line=lambda: "the force's sign: reversed (odds 1e9)")
    problem = SimpleNamespace(settings=settings, prior=None)
    weighed = Weighed(implausible or {}, [], evidence or {}, {}, {})
    return Case(problem, ranking, weighed, share, "refine the grid to 80 nodes", polarity, where)


def test_the_rules_run_in_the_documented_order():
    assert [name for name, _ in RULES] == ["naming", "numerical adequacy", "plausibility", "nested cases",
                                           "evidence and ties", "notes", "set-ups", "plausible readings"]


def test_the_set_ups_apart_and_the_plausible_readings_are_said_by_the_rules():
    """What the orchestrator tried after a first judgement changes the verdict only through the rules: the set-ups
    told apart are said last but one, the readings held within plausibility last — and only when no effect is
    named (a named effect needs none)."""
    from diagnosis.judgement.apart import SetupsApart
    from diagnosis.search.plausible import PlausibleReading

    apart = SetupsApart("the modes disagree", frozenset({"shaker"}), "unexplained", False, "")
    rf = refit("point_mass", 2.0)
    reading = PlausibleReading("point_mass", None, "one set-up", rf, 0.05, None, 1.0)
    c = replace(case({"foundation": refit("foundation", 30.0)}), apart=apart, readings=(reading,))
    v = judge(c).verdict
    assert v.kind is Kind.UNEXPLAINED
    assert [r.rule for r in v.reasons][-2:] == ["set-ups", "plausible readings"], v.reasons
    assert v.reasons[-2].text == apart.text() and "point_mass" in v.reasons[-1].text
    named = judge(replace(case({"foundation": refit("foundation", 1.1)}), apart=apart, readings=(reading,))).verdict
    assert named.kind is Kind.EFFECT and [r.rule for r in named.reasons][-1] == "set-ups"


def test_a_named_effect_carries_its_reasons_and_their_rules():
    j = judge(case({"foundation": refit("foundation", 1.1)}, evidence={"none": 0.0, "foundation": 1.0}))
    v = j.verdict
    assert (v.kind, v.name) == (Kind.EFFECT, "foundation")
    assert [r.rule for r in v.reasons] == ["naming", "notes"]
    assert v.text() == "; ".join(r.text for r in v.reasons) and v.text().startswith("foundation closes")
    assert v.to_dict()["reasons"][1] == {"rule": "notes", "text": v.reasons[1].text}


def test_the_grid_takes_a_gap_that_refining_changes():
    """Above ``numerical_share_limit`` the verdict is the grid's, with no ties of the effect it replaces; a share
    above ``grid_caution`` only cautions; a gap at the noise floor stays ``none`` whatever the share."""
    refits = {"a": refit("a", 1.05), "b": refit("b", 1.1)}           # b ties with a
    v = judge(case(refits, share=0.7)).verdict
    assert v.kind is Kind.GRID and v.ties == () and "(the best-ranked effect, a, is not blamed)" in v.text()
    assert "refine the grid to 80 nodes" in v.text()
    refits = {"a": refit("a", 1.05), "b": refit("b", 3.0)}           # a alone
    v = judge(case(refits, share=0.3)).verdict
    assert v.name == "a" and v.reasons[-1].rule == "numerical adequacy" and v.reasons[-1].text.startswith(
        "caution: 30 %")
    v = judge(case({"a": refit("a", 45.0, delta_bic=5.0)}, share=0.7)).verdict    # nothing pays: unexplained
    assert v.kind is Kind.GRID and "not blamed" not in v.text()
    at_floor = np.full(2, 1.0 + 0.5 * SETTINGS.gap_threshold)
    assert judge(case(refits, share=0.9, before=at_floor)).verdict.kind is Kind.NONE
    # the limit is read from the settings: a laxer limit keeps the effect
    lax = replace(SETTINGS, numerical_share_limit=0.8)
    assert judge(case(refits, share=0.7, settings=lax)).verdict.name == "a"


def test_an_implausible_best_is_not_named():
    refits = {"point_mass": refit("point_mass", 1.05), "grounded_spring": refit("grounded_spring", 1.2)}
    v = judge(case(refits, implausible={"point_mass": ["point_mass: mass = 2.7 kg lies outside [0, 0.5] kg"]})
              ).verdict
    assert v.name == "grounded_spring" and v.reasons[0].rule == "plausibility"
    assert v.reasons[0].text.startswith("point_mass is not named: its refit needs implausible values (point_mass: "
                                        "mass = 2.7 kg") and "— among the plausible candidates: grounded_spring" \
        in v.reasons[0].text


def test_a_special_case_at_the_floor_is_named_instead_of_its_general_effect():
    refits = {"point_mass": refit("point_mass", 1.0), "transducer_mass[y2]": refit("transducer_mass[y2]", 1.02)}
    effects = {"point_mass": effect(), "transducer_mass[y2]": effect(nested_in="point_mass")}
    v = judge(case(refits, effects=effects)).verdict
    assert v.name == "transducer_mass[y2]" and v.ties == ()
    assert v.reasons[-1].rule == "nested cases" and "named instead of point_mass" in v.reasons[-1].text


def test_ties_go_to_the_evidence():
    refits = {"actuator_lag": refit("actuator_lag", 1.05), "sensor_lag[y1]": refit("sensor_lag[y1]", 1.06)}
    v = judge(case(refits, evidence={"actuator_lag": 0.5, "sensor_lag[y1]": 0.5})).verdict
    assert v.kind is Kind.INDISTINGUISHABLE and set(v.ties) == set(refits)
    assert v.reasons[0].rule == "evidence and ties" and v.reasons[1].rule == "naming"
    v = judge(case(refits, evidence={"actuator_lag": 0.01, "sensor_lag[y1]": 0.99})).verdict
    assert v.name == "sensor_lag[y1]" and v.ties == ()


def test_notes_say_the_force_sign_and_where_an_unexplained_gap_lies():
    v = judge(case({"a": refit("a", 45.0, delta_bic=5.0)}, reversed_force=True,
                   where=("rec: sensor y1 carries 90 % of the gap",))).verdict
    assert v.kind is Kind.UNEXPLAINED
    assert [r.rule for r in v.reasons] == ["naming", "notes", "notes"]
    assert v.reasons[1].text.startswith("the force's sign") and v.reasons[2].text == (
        "where the gap is: rec: sensor y1 carries 90 % of the gap")
    # a named effect gets no 'where' (the localisation is the lead only when nothing is named)
    v = judge(case({"a": refit("a", 1.05)}, where=("rec: y1",))).verdict
    assert "where the gap is" not in v.text()
