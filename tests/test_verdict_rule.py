"""The diagnosis' verdict on its own: refit summaries in, verdict out — no simulation.

The summaries are made by hand (a held-out gap ratio per sensor after the refit, the closure, ΔBIC), so each
branch of the naming rule is checked at its threshold; then the whole pipeline of rules
(:mod:`diagnosis.judgement.rules`) on hand-made rankings: each rule in its place, the reasons as values.
"""
from __future__ import annotations

import numpy as np

from diagnosis.search.refits import EffectRefit
from diagnosis.settings import Thresholds
from diagnosis.judgement.verdict import Kind, Verdict, by_evidence, name_cause, named

SETTINGS = Thresholds()
GAP_THRESHOLD, NAMED_CLOSURE, DECISIVE_ODDS = SETTINGS.gap_threshold, SETTINGS.named_closure, SETTINGS.decisive_odds


UNEXPLAINED, INDISTINGUISHABLE = Kind.UNEXPLAINED.value, Kind.INDISTINGUISHABLE.value


def verdict_rule(before, refits, paying, settings=SETTINGS):
    """The naming rule with the default thresholds (the tests below check it at them), as ``(name, ties, text)``."""
    v = name_cause(before, refits, paying, settings)
    assert all(r.rule == "naming" for r in v.reasons)
    return v.name, list(v.ties), v.text()

BEFORE = np.array([40.0, 60.0])      # held-out gap ratio of the baseline, per sensor (mean 50)


def refit(label: str, after: float, delta_bic: float = -500.0) -> EffectRefit:
    """A refit leaving ``after`` noise variances on both sensors; closure as :func:`diagnosis.search.refits.summarise`
    defines it (share of the gap above the noise floor)."""
    closed = (np.mean(BEFORE) - after) / (np.mean(BEFORE) - 1.0)
    return EffectRefit(label, None, {}, 0.0, 0.0, delta_bic, 0.0, np.array([after, after]), float(closed),
                       np.array([closed, closed]))


def test_no_gap_is_none_whatever_the_refits():
    before = np.full(2, 1.0 + 0.5 * GAP_THRESHOLD)
    verdict, ties, reason = verdict_rule(before, {"point_mass": refit("point_mass", 1.0)}, ["point_mass"])
    assert (verdict, ties) == ("none", []) and "nothing to explain" in reason


def test_nothing_paying_is_unexplained():
    verdict, ties, reason = verdict_rule(BEFORE, {"foundation": refit("foundation", 45.0, delta_bic=3.0)}, [])
    assert verdict == UNEXPLAINED and ties == [] and "no candidate effect improves BIC" in reason


def test_the_best_must_close_the_named_share():
    """On a small gap (1.5 noise variances) a refit can reach the noise floor and still close too little of
    it to be named: the share is the second condition."""
    before = np.array([1.4, 1.6])

    def small(label: str, closed: float) -> EffectRefit:
        after = 1.5 - closed * 0.5
        return EffectRefit(label, None, {}, 0.0, 0.0, -500.0, 0.0, np.array([after, after]), closed,
                           np.array([closed, closed]))

    verdict, _, reason = verdict_rule(before, {"foundation": small("foundation", NAMED_CLOSURE - 0.01)},
                                      ["foundation"])
    assert verdict == UNEXPLAINED and f"closes only {NAMED_CLOSURE - 0.01:.0%}" in reason
    verdict, ties, _ = verdict_rule(before, {"foundation": small("foundation", NAMED_CLOSURE + 0.01)},
                                    ["foundation"])
    assert (verdict, ties) == ("foundation", [])


def test_ties_close_nearly_as_much_and_leave_no_more():
    refits = {"actuator_lag": refit("actuator_lag", 1.05), "sensor_lag[y1]": refit("sensor_lag[y1]", 1.1),
              "point_mass": refit("point_mass", 3.0)}
    verdict, ties, reason = verdict_rule(BEFORE, refits, ["actuator_lag", "sensor_lag[y1]", "point_mass"])
    # the sensor lag leaves 0.05 more (below the threshold): a tie; the point mass leaves 2 more: decided
    assert verdict == "actuator_lag" and ties == ["sensor_lag[y1]"] and "do not tell it from sensor_lag[y1]" in reason


def test_a_pair_is_not_tied_with_its_own_parts():
    refits = {"foundation+actuator_lag": refit("foundation+actuator_lag", 1.0, delta_bic=-600.0),
              "foundation": refit("foundation", 1.02)}          # the lag pays for itself: 100 BIC better
    verdict, ties, _ = verdict_rule(BEFORE, refits, ["foundation+actuator_lag", "foundation"])
    assert verdict == "foundation+actuator_lag" and ties == []


def test_an_effect_that_leaves_a_gap_is_named_as_the_dominant_part_only():
    """An effect that closes 99 % of a large gap and leaves 17.7 noise variances is named with what remains
    said; one that brings the gap to the noise floor is named without."""
    before = np.array([1630.0, 1630.0])
    closed = (1630.0 - 17.7) / 1629.0
    rf = EffectRefit("point_mass", None, {}, 0.0, 0.0, -5000.0, 0.0, np.array([17.7, 17.7]), closed,
                     np.array([closed, closed]))
    verdict, ties, reason = verdict_rule(before, {"point_mass": rf}, ["point_mass"])
    assert verdict == "point_mass" and "dominant part only: 17.7x the noise variance remains" in reason
    at_floor = 1.0 + GAP_THRESHOLD
    rf = EffectRefit("point_mass", None, {}, 0.0, 0.0, -5000.0, 0.0, np.array([at_floor] * 2), 0.9998,
                     np.array([0.9998] * 2))
    verdict, _, reason = verdict_rule(before, {"point_mass": rf}, ["point_mass"])
    assert verdict == "point_mass" and "remains" not in reason


def test_a_pair_with_an_insignificant_partner_is_not_named():
    """Kelvin–Voigt alone leaves 1.02; with a tiny point mass 1.0 — the pair's BIC only 4 better than
    Kelvin–Voigt's: the mass does not pay for its two parameters, and Kelvin–Voigt is named."""
    refits = {"point_mass+kelvin_voigt": refit("point_mass+kelvin_voigt", 1.0, delta_bic=-504.0),
              "kelvin_voigt": refit("kelvin_voigt", 1.02, delta_bic=-500.0)}
    verdict, _, _ = verdict_rule(BEFORE, refits, ["point_mass+kelvin_voigt", "kelvin_voigt"])
    assert verdict == "kelvin_voigt"
    refits["point_mass+kelvin_voigt"] = refit("point_mass+kelvin_voigt", 1.0, delta_bic=-600.0)
    verdict, _, _ = verdict_rule(BEFORE, refits, ["point_mass+kelvin_voigt", "kelvin_voigt"])
    assert verdict == "point_mass+kelvin_voigt"


def test_the_evidence_decides_between_ties_or_says_it_cannot():
    """Ties the fits cannot separate go to the evidence: strong odds (≥ 20) name the most probable — even when
    the fit rule ranked the other first —; weaker odds give ``indistinguishable`` with the candidates listed,
    the most probable first, and their probabilities in the reason."""
    def tied(*ties):
        return named("a", ties).said("naming", "a closes 99 % of the held-out gap")

    v = by_evidence(tied("b"), {"a": 0.04, "b": 0.95, "none": 0.01}, DECISIVE_ODDS)
    assert (v.name, v.ties) == ("b", ()) and "odds 23.8" in v.reasons[-1].text
    assert v.reasons[0].text == "a closes 99 % of the held-out gap"       # the fit rule's reason kept, first
    v = by_evidence(tied("b", "c"), {"a": 0.30, "b": 0.62, "c": 0.08}, DECISIVE_ODDS)
    assert v.kind is Kind.INDISTINGUISHABLE and v.name == INDISTINGUISHABLE and v.ties == ("b", "a", "c")
    # the sentence that says why none is named comes first, the fit rule's reason after it
    assert "b 0.62, a 0.3, c 0.08" in v.reasons[0].text and f"< {DECISIVE_ODDS:g}" in v.reasons[0].text
    assert v.reasons[0].rule == "evidence and ties" and v.reasons[1].rule == "naming"
    # the boundary itself: odds of exactly 20 decide
    assert by_evidence(tied("b"), {"a": 20.0 / 21.0, "b": 1.0 / 21.0}, DECISIVE_ODDS).name == "a"


def test_no_probability_is_quoted_where_every_candidate_misses_the_records():
    """When the best candidate leaves a gap (161 noise variances on a broadband record), the Laplace evidence ranks
    fits of models that all miss something: the same decision, said as a ranking of fits, no "posterior
    probability 1" and no "odds inf" (an underflowed ratio is printed as a bound)."""
    v = by_evidence(named("a", ("b",)), {"a": 1.0, "b": 0.0}, DECISIVE_ODDS, remains=161.0)
    text = v.reasons[-1].text
    assert v.name == "a" and "not a posterior probability" in text and "161x" in text
    assert "posterior probability 1" not in text and "inf" not in text and "above 1e+300" in text
    v = by_evidence(named("a", ("b",)), {"a": 0.6, "b": 0.4}, DECISIVE_ODDS, remains=161.0)
    assert v.kind is Kind.INDISTINGUISHABLE and "posterior" not in v.reasons[0].text
    v = by_evidence(named("a", ("b",)), {"a": 1.0, "b": 0.0}, DECISIVE_ODDS)          # at the floor: a probability
    assert "posterior probability 1" in v.reasons[-1].text and "odds above 1e+300" in v.reasons[-1].text


def test_a_threshold_moves_the_verdict():
    """The same refit named under the default closure (0.8) is not under a stricter one (0.9)."""
    rf = refit("foundation", 0.15 * np.mean(BEFORE))          # closes 86 % of the gap
    assert verdict_rule(BEFORE, {"foundation": rf}, ["foundation"])[0] == "foundation"
    strict = Thresholds(named_closure=0.9)
    assert verdict_rule(BEFORE, {"foundation": rf}, ["foundation"], strict)[0] == UNEXPLAINED


def test_a_verdict_names_an_effect_exactly_when_it_is_of_that_kind():
    assert named("foundation").name == "foundation" and Verdict(Kind.NONE).name == "none"
    for bad in (lambda: Verdict(Kind.EFFECT), lambda: Verdict(Kind.GRID, "foundation")):
        try:
            bad()
        except ValueError:
            continue
        raise AssertionError("a verdict's kind and label disagree without an error")


def test_a_pair_ties_with_the_pair_of_a_near_equal_rival():
    """The pairs a spring and a foundation each make with a lag explain the records alike: the named pair's tie is
    the other pair (then the evidence decides); a single that is one of its parts is never its tie."""
    refits = {"grounded_spring+sensor_lag[y1]": refit("grounded_spring+sensor_lag[y1]", 1.05, delta_bic=-700.0),
              "foundation+sensor_lag[y1]": refit("foundation+sensor_lag[y1]", 1.08, delta_bic=-690.0),
              "grounded_spring": refit("grounded_spring", 23.0), "foundation": refit("foundation", 24.0)}
    verdict, ties, reason = verdict_rule(BEFORE, refits, list(refits))
    assert verdict == "grounded_spring+sensor_lag[y1]" and ties == ["foundation+sensor_lag[y1]"], reason
    # a single effect's verdict is never tied with a pair
    verdict, ties, _ = verdict_rule(BEFORE, {"point_mass": refit("point_mass", 1.02),
                                             "foundation+sensor_lag[y1]": refit("foundation+sensor_lag[y1]", 1.05)},
                                    ["point_mass", "foundation+sensor_lag[y1]"])
    assert (verdict, ties) == ("point_mass", [])
