"""Parallel runners give exactly the serial objective values: local processes and a real Dask LocalCluster."""
from __future__ import annotations

import numpy as np
import pytest

import ebb_model as em
from identification.native import experiments_from_arrays
from identification.native import NativeEvaluator
from identification.parameters import parameter_space
from identification.runners import DaskRunner, ProcessRunner, SerialRunner

from conftest import make_identification_config


@pytest.fixture(scope="module")
def evaluator_and_population():
    cfg = make_identification_config(nodes=16, c=0.2, N=40.0)
    rng = np.random.default_rng(0)
    u = rng.standard_normal((500, 1))
    y = em.simulate_config(cfg, u).outputs
    ev = NativeEvaluator(cfg, parameter_space(cfg), experiments_from_arrays([("e", u, y)]))
    X = np.column_stack([rng.uniform(5, 20, 9), rng.uniform(0, 100, 9)])
    return ev, X


def test_process_runner_equals_serial(evaluator_and_population):
    ev, X = evaluator_and_population
    ref = SerialRunner()(ev, X)
    with ProcessRunner(2) as r:
        np.testing.assert_array_equal(r(ev, X), ref)


def test_dask_local_cluster_equals_serial(evaluator_and_population):
    import distributed
    ev, X = evaluator_and_population
    ref = SerialRunner()(ev, X)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        with DaskRunner(cluster.scheduler_address) as r:
            assert r.workers == 2
            np.testing.assert_array_equal(r(ev, X), ref)
            np.testing.assert_array_equal(r(ev, X[:3]), ref[:3])
