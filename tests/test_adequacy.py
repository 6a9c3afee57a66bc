"""The numerical-adequacy check: how much of a model-vs-measurement gap is the model's own grid.

On the lightly damped records of ``test_exact_scheme.py`` (independent, converged FE truth plus 1 % noise), at
the true parameters: the seed's θ-scheme on 60 nodes has a gap of thousands of noise variances, of which
refining the grid changes about 60 % (measured 0.60–0.62) — numerical, not physical; the exact scheme's gap is
at the noise floor and refinement changes at most 2 % of it (measured 0.0055–0.0185).
"""
from __future__ import annotations

import numpy as np
import pytest

from ebb_model.adequacy import numerical_adequacy, refined_grid
from test_exact_scheme import CASES, SAMPLES_PER_CASE, band_limited_input, config, truth


@pytest.fixture(scope="module", params=sorted(CASES))
def noisy_record(request):
    case = CASES[request.param]
    u = band_limited_input(SAMPLES_PER_CASE[request.param], case["dt"], *case["band"], seed=4)
    y = truth(case, u, 96, 16)
    sd = 0.01 * y.std(axis=0)
    return case, u, y + sd * np.random.default_rng(0).standard_normal(y.shape), sd


def test_the_seed_scheme_gap_is_mostly_numerical(noisy_record):
    case, u, y, sd = noisy_record
    cfg = config(case, 60, "theta")
    a = numerical_adequacy(cfg, cfg.parameter_values(), [(u, y)], sd)
    assert np.all(a.gap > 10), a.gap
    assert np.all(a.numerical_share > 0.5), a.numerical_share
    assert np.all(a.gap_refined < a.gap / 5), (a.gap_refined, a.gap)


def test_the_exact_scheme_gap_is_not_numerical(noisy_record):
    case, u, y, sd = noisy_record
    cfg = config(case, 60, "exact")
    a = numerical_adequacy(cfg, cfg.parameter_values(), [(u, y)], sd)
    assert np.all(a.gap < 2.5), a.gap                       # noise floor 1 plus <= 1.5 of model error
    assert np.all(a.numerical_share < 0.05), a.numerical_share
    assert a.to_dict()["max_numerical_share"] == pytest.approx(float(np.max(a.numerical_share)))


def test_refinement_is_a_genuinely_finer_pair_of_grids():
    """For the exact scheme the refined config's Richardson pair must not be the original pair again."""
    from ebb_model.exact_modal import companion_config

    case = CASES["cantilever-mixed"]
    for nodes in (20, 60, 120):
        cfg = config(case, nodes, "exact")
        fine = refined_grid(cfg)
        pair = {cfg.beam.nodes, companion_config(cfg).beam.nodes}
        fine_pair = {fine.beam.nodes, companion_config(fine).beam.nodes}
        assert min(fine_pair) > min(pair) and max(fine_pair) > max(pair), (pair, fine_pair)
