"""The local refits a diagnosis would repeat are made once (:mod:`diagnosis.search.reuse`).

Ranking again with the measured modes taken without the records' rig parts changes only the residuals of the
effects that model those parts: for any other effect the refit made fresh is the first ranking's to the last bit
(the premise, checked here on the set-ups' bench: the armature in the record, the bare beam's modes), so it is taken
from the memo; the armature's refit changes and is never looked up.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from diagnosis.candidates.catalogue import catalogue_of
from diagnosis.candidates.score import score_effect
from diagnosis.problem.fitting import GapProblem
from diagnosis.problem.records import split_records
from diagnosis.search.refits import map_refits
from diagnosis.search.reuse import RefitMemo
from diagnosis.search.state import Search
from diagnosis.stages import StageClock
from ebb_model.reference.excitation import band_limited_input
from ebb_model.reference.synthetic import synthesize
from identification.modal_data import ModalData
from identification.parameters import parameter_space
from test_diagnosis_blind import DT, TRUTH, bench_config
from test_rig_effects import ARMATURE, _armature
from test_setups import _bare_modes


def _problem() -> GapProblem:
    cfg = bench_config()
    u = band_limited_input(2000, DT, 2.0, 60.0, seed=4)
    rec = synthesize(cfg, u, params=TRUTH, effect=_armature(0.55, ARMATURE), noise=0.01, seed=5)
    modes = _bare_modes()
    return GapProblem(cfg, parameter_space(cfg), split_records([("r", u, rec.outputs)], holdout_fraction=0.3),
                      np.asarray(rec.noise_std), modes=ModalData(np.array(modes["frequencies_hz"]),
                                                                 np.array(modes["std_hz"])))


def test_a_ranking_without_the_rig_parts_takes_the_refits_it_would_repeat():
    problem = _problem()
    baseline = problem.fit(np.array([TRUTH[n] for n in problem.space.names]))
    cfg, params = problem.space.apply(problem.config, baseline.beta)
    catalogue = catalogue_of(problem, cfg, params, np.array([2.0, 20.0, 60.0]), 60.0)
    effects = {e.label: e for e in catalogue.effects()}
    armature = next(lab for lab, e in effects.items() if e.rig_part == "shaker")
    labels = ["point_mass", armature]
    two = replace(problem, modes_lack=frozenset({"shaker"}))
    scores = {lab: score_effect(problem, baseline, effects[lab]) for lab in labels}
    # the premise: made fresh without the shaker in the modes' model, the point mass's refit is the first's to the
    # bit; the armature's is not (its modes' rows are computed without it)
    first = map_refits(None, problem, catalogue, labels, baseline, scores, 60, stage="first")
    again = map_refits(None, two, catalogue, labels, baseline, scores, 60, stage="first")
    fit, fit_again = first["point_mass"][0], again["point_mass"][0]
    assert np.array_equal(fit.beta, fit_again.beta) and np.array_equal(fit.s, fit_again.s)
    assert fit.rss == fit_again.rss
    assert first[armature][0].rss != again[armature][0].rss
    # the keys say so: the same for the point mass, none for the armature once the modes lack the shaker
    key = RefitMemo.key(problem, baseline, effects["point_mass"], scores["point_mass"], "first", 60)
    assert key is not None and key == RefitMemo.key(two, baseline, effects["point_mass"], scores["point_mass"],
                                                    "first", 60)
    assert RefitMemo.key(two, baseline, effects[armature], scores[armature], "first", 60) is None
    assert RefitMemo.key(problem, baseline, effects["point_mass"], scores["point_mass"], "continuation", 60) is None
    # a search shares the memo: the second ranking's point mass is the first's object, the armature refitted
    memo = RefitMemo()

    def search(p: GapProblem) -> Search:
        return Search(p, baseline, catalogue, effects, np.ones(1), scores, 60, None, lambda _m: None, StageClock(),
                      {}, memo)

    made = search(problem).refit(labels, stage="first")
    taken = search(two).refit(labels, stage="first")
    assert taken["point_mass"] is made["point_mass"]
    assert taken[armature] is not made[armature] and taken[armature][0].rss == again[armature][0].rss
