"""The score tests are comparable across effects: on records without any effect their p-values are calibrated
(each effect's statistic against its own degrees of freedom), so a significant score means the same for every
candidate.

The null here is the score test's own: the records are the model's own response plus white Gaussian noise of a
known level, so the baseline is right and only the statistic's distribution is tested (records from an
independent truth carry the model's discretisation error, which every score rightly sees — that is the blind
families' business, not this test's).

Measured: MEASURE_ME
"""
from __future__ import annotations

import numpy as np
from scipy.stats import binom

from diagnosis.candidates.catalogue import catalogue_of
from diagnosis.candidates.score import score_effect
from diagnosis.problem.fitting import GapProblem
from diagnosis.problem.records import split_records
from ebb_model.modal import discrete_frequencies
from ebb_model.reference.excitation import band_limited_input
from ebb_model.simulate import fast_model, simulate
from identification.parameters import parameter_space
from test_diagnosis_blind import DT, TRUTH, bench_config

RECORDS = 40
N = 3000
LEVEL = 0.01


def _scores(seed: int) -> dict[str, float]:
    """p-value of every candidate's score test at the baseline fitted to one record without effect."""
    cfg = bench_config("displacement")
    space = parameter_space(cfg)
    truth = np.array([TRUTH[k] for k in space.names])
    true_cfg, true_params = space.apply(cfg, truth)
    u = band_limited_input(N, DT, 2.0, 60.0, seed=seed)
    clean = simulate(fast_model(true_cfg, true_params), u).outputs
    sigma = 0.01 * np.sqrt(np.mean(clean ** 2, axis=0))
    y = clean + np.random.default_rng(seed + 1000).standard_normal(clean.shape) * sigma
    records = split_records([("null", u.reshape(-1, 1), y)], holdout_fraction=0.3)
    problem = GapProblem(cfg, space, records, sigma)
    baseline = problem.fit(truth)
    base_cfg, base_params = space.apply(cfg, baseline.beta)
    f, _ = discrete_frequencies(base_cfg, base_params)
    catalogue = catalogue_of(problem, base_cfg, base_params, f[f <= 72.0], 60.0)
    return {e.label: score_effect(problem, baseline, e).p_value for e in catalogue.effects()}


def test_scores_are_calibrated_on_records_without_an_effect():
    """At most the level's share of significant scores over all candidates (within the binomial 99.9 % bound),
    and no single candidate significant more often than that bound allows over the records."""
    p = [_scores(seed) for seed in range(RECORDS)]
    labels = list(p[0])
    hits = {lab: sum(ps[lab] < LEVEL for ps in p) for lab in labels}
    trials = RECORDS * len(labels)
    overall = binom.ppf(0.999, trials, LEVEL)
    each = binom.ppf(0.999, RECORDS, LEVEL)
    print(f"\nsignificant at {LEVEL:.0%}: {sum(hits.values())} of {trials} (bound {overall:.0f}); per candidate "
          + ", ".join(f"{k} {v}" for k, v in hits.items() if v))
    assert sum(hits.values()) <= overall, hits
    assert all(v <= each for v in hits.values()), hits
