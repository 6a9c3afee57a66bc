"""The score tests are comparable across effects: on records without any effect their p-values are calibrated
(each effect's statistic against its own degrees of freedom), so a significant score means the same for every
candidate; and on records with an effect, a candidate that is not there does not outscore the one that is.

The null here is the score test's own: the records are the model's own response plus white Gaussian noise of a
known level, so the baseline is right and only the statistic's distribution is tested (records from an
independent truth carry the model's discretisation error, which every score rightly sees — that is the blind
families' business, not this test's).

Measured (40 records × 21 candidates, the blind family's clamped–pinned bench, two displacement sensors): 11 of
840 scores significant at 1 % (the binomial 99.9 % bound 19), at most 2 of 40 for any candidate.  The null alone
did not show what was wrong with the shaker armature's old score (10 of 840, the armature 1 of 40): evaluated with
its suspension already on, it was a supremum over models that are not the baseline, harmless at the right
baseline and inflated at a wrong one — 2.19e6, the best of all, on a record whose only effect is rotary inertia
(now 0), 7.27e6 on a Kelvin–Voigt record (now 0).  :func:`test_a_candidate_that_is_not_there_does_not_outscore`
checks that on the independent truth.
"""
from __future__ import annotations

import numpy as np
from scipy.stats import binom

from diagnosis.candidates.catalogue import catalogue_of
from diagnosis.candidates.score import score_effect
from diagnosis.problem.fitting import GapProblem
from diagnosis.problem.records import split_records
from ebb_model.modal.modal import discrete_frequencies
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


def _blind_scores(tmp_path, effect) -> dict[str, float]:
    """Every candidate's score statistic at the baseline of a blind accelerometer record (the independent truth
    of ``tests/test_diagnosis_blind.py``, ``effect`` withheld), the baseline fitted as the diagnosis fits it."""
    from diagnosis.baseline.fit import baseline_fit
    from identification.noise import records_noise_std
    from identification.run import read_data
    from diagnosis.problem.records import ordered_record
    from test_diagnosis_blind import PRIOR, _write

    cfg = bench_config("acceleration")
    tmp_path.mkdir()
    path = _write(tmp_path, cfg, effect, seed=3, f_max=150.0)
    records = split_records([ordered_record(cfg, e) for e in read_data(cfg, [path])], holdout_fraction=0.3)
    space = parameter_space(cfg)
    sigma = records_noise_std([r.inputs for r in records], [r.outputs for r in records], DT)
    problem, baseline = baseline_fit(GapProblem(cfg, space, records, sigma),
                                     np.array([PRIOR[k] for k in space.names]))
    base_cfg, base_params = space.apply(cfg, baseline.beta)
    f, _ = discrete_frequencies(base_cfg, base_params)
    catalogue = catalogue_of(problem, base_cfg, base_params, f[f <= 180.0], 150.0)
    return {e.label: score_effect(problem, baseline, e).lm for e in catalogue.effects()}


def test_a_candidate_that_is_not_there_does_not_outscore(tmp_path):
    """Rotary inertia withheld: the shaker's armature (absent) scores far below the best candidate (measured 0 of
    1.82e6; in the diagnosis before, 2.19e6 and the best of all).  (Where the armature is there, its one-sided
    score is what the baseline left of it — best of all on the compressed bench, 0 where the baseline compensated
    it; those are found through the modal pattern and the landings, :mod:`diagnosis.search`.)"""
    from ebb_model.reference.withheld import WithheldEffect

    lm = _blind_scores(tmp_path / "rotary", WithheldEffect("rotary_inertia", {"rhoI": 4e-4}))
    print(f"\nrotary inertia withheld: armature {lm['shaker_armature[F1]']:.3g}, best {max(lm.values()):.3g}")
    assert lm["shaker_armature[F1]"] < 1e-3 * max(lm.values()), lm
