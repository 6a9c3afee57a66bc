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


def _dask_settings() -> dict:
    import dask

    from identification.cluster import LOW_OVERHEAD

    return {k: dask.config.get(k) for k in LOW_OVERHEAD}


def test_local_dask_cluster_runs_with_low_overhead_settings_and_closes(evaluator_and_population):
    """``local:K``: K single-threaded workers with the profiler off and slow health checks; closed with the runner."""
    import dask

    from identification.cluster import LOW_OVERHEAD

    ev, X = evaluator_and_population
    ref = SerialRunner()(ev, X)
    before = dask.config.get("distributed.worker.profile.enabled")
    with DaskRunner("local:2") as r:
        assert r.workers == 2
        info = r.client.scheduler_info()["workers"]
        assert sorted(w["nthreads"] for w in info.values()) == [1, 1]
        for settings in r.client.run(_dask_settings).values():
            assert settings == dict(LOW_OVERHEAD)
        np.testing.assert_array_equal(r(ev, X), ref)
        cluster = r._cluster
    assert cluster.status.name == "closed"
    assert dask.config.get("distributed.worker.profile.enabled") == before  # the caller's settings untouched


def test_low_overhead_settings_are_dask_settings_and_the_readme_says_the_same():
    """Dask accepts unknown keys silently: every setting must be one of distributed's own; docs/benchmarks.md's YAML
    block for hand-started clusters must give exactly these values."""
    import re
    from pathlib import Path

    import dask
    import distributed  # noqa: F401 - registers distributed's defaults
    import yaml

    from identification.cluster import LOW_OVERHEAD

    sentinel = object()
    for key in LOW_OVERHEAD:
        assert dask.config.get(key, default=sentinel) is not sentinel, key
    readme = (Path(__file__).resolve().parents[1] / "docs" / "benchmarks.md").read_text()
    block = re.search(r"```yaml\n(.*?)```", readme, re.S)
    assert block is not None
    flat: dict = {}

    def walk(d: dict, prefix: str) -> None:
        for k, v in d.items():
            if isinstance(v, dict):
                walk(v, f"{prefix}{k}.")
            else:
                flat[prefix + k] = v

    walk(yaml.safe_load(block.group(1)), "")
    assert flat == dict(LOW_OVERHEAD)


@pytest.mark.parametrize("address", ["local:0", "local:", "local:two", "local:-1", "local"])
def test_bad_local_cluster_address_is_a_config_error(address):
    from ebb_model.errors import ConfigError
    from identification.cluster import parse_local_address

    with pytest.raises(ConfigError, match="local:K"):
        parse_local_address(address)


def test_scheduler_addresses_are_not_local_clusters():
    from identification.cluster import parse_local_address

    assert parse_local_address("tcp://127.0.0.1:8786") is None
    assert parse_local_address("127.0.0.1:8786") is None
    assert parse_local_address("localhost:8786") is None


class _CountingEvaluator:
    """Test wrapper: the native evaluator, counting its simulations (serial use only)."""

    def __init__(self, inner):
        self.inner = inner
        self.space = inner.space
        self.experiments = inner.experiments
        self.calls = 0

    def simulate(self, x):
        self.calls += 1
        return self.inner.simulate(x)


def test_polish_counts_every_evaluation_and_runs_the_same_on_worker_processes(evaluator_and_population):
    from identification.polish import polish

    ev, _ = evaluator_and_population
    counting = _CountingEvaluator(ev)
    x0 = np.array([12.0, 60.0])
    serial = polish(counting, x0)
    assert serial.n_evaluations == counting.calls > 3  # residuals and Jacobian columns, all counted
    np.testing.assert_allclose(serial.x, [10.0, 40.0], rtol=1e-6)  # noise-free data of the model itself
    with ProcessRunner(2) as r:
        parallel = polish(ev, x0, runner=r)
    assert parallel.n_evaluations == serial.n_evaluations
    np.testing.assert_allclose(parallel.x, serial.x, rtol=1e-12, atol=0)
