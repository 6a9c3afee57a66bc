"""No candidate dropped unseen (:mod:`diagnosis.search.exclusions`): every significant score without a refit has
its reason, said from what the effect declares and what the search did — checked on hand-made scores."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from diagnosis.candidates.score import EffectScore
from diagnosis.effects import Landing
from diagnosis.search.exclusions import not_refitted
from diagnosis.settings import Thresholds


def effect(label, *, landings=(), nested_in=None, chain=False):
    return SimpleNamespace(label=label, landings=landings, nested_in=nested_in, scale_degenerate=chain)


def score(label, lm, p):
    return EffectScore(label, lm, p, np.zeros(1), 1)


def test_every_significant_score_without_a_refit_is_said_with_its_reason():
    effects = {"shaker_armature[F1]": effect("shaker_armature[F1]", nested_in="point_mass+grounded_spring",
                                            landings=(Landing("point_mass", 1, ((0, 0),), 0.05),
                                                      Landing("grounded_spring", 1, ((1, 0),), 0.05))),
               "point_mass": effect("point_mass"), "rotary_inertia": effect("rotary_inertia"),
               "foundation": effect("foundation"), "sensor_gain[y1]": effect("sensor_gain[y1]", chain=True),
               "kelvin_voigt": effect("kelvin_voigt")}
    scores = {"shaker_armature[F1]": score("a", 4.7e6, 0.0), "point_mass": score("p", 7.3e5, 0.0),
              "rotary_inertia": score("r", 2.1e5, 0.0), "foundation": score("f", 9e4, 1e-9),
              "sensor_gain[y1]": score("g", 5e4, 1e-8), "kelvin_voigt": score("k", 3.0, 0.08)}
    patterns = {"baseline": SimpleNamespace(chi2=900.0), "rotary_inertia": SimpleNamespace(chi2=40.0),
                "point_mass": SimpleNamespace(chi2=12.0)}
    said = not_refitted(effects, scores, {"point_mass"}, patterns, {}, Thresholds(), with_prior=False)
    # the refitted one and the insignificant one are not listed; the others are, in score order
    assert list(said) == ["shaker_armature[F1]", "rotary_inertia", "foundation", "sensor_gain[y1]"]
    assert said["shaker_armature[F1]"].startswith("score 4.7e+06 (rank 1 of 6, p 0)")
    assert "grounded_spring or point_mass refit lands within 5% of the beam's length of it: none did" in \
        said["shaker_armature[F1]"]
    assert "its modal pattern (chi2 40, the best match 12) was not among the 2 refitted" in said["rotary_inertia"]
    assert "beyond the shortlist of the 4 best-scoring effects" in said["foundation"]
    assert "no prior on the beam" not in said["sensor_gain[y1]"] and "none is given" in said["sensor_gain[y1]"]
    # a special case refitted and dropped says why; the significance level is the settings'
    said = not_refitted(effects, scores, {"point_mass"}, patterns,
                        {"shaker_armature[F1]": "not more than its parts (…)"},
                        Thresholds(score_significance=1e-10), with_prior=False)
    assert list(said) == ["shaker_armature[F1]", "rotary_inertia"]
    assert said["shaker_armature[F1]"].endswith("refitted but dropped: not more than its parts (…)")
