"""The FMU backend (fmpy) gives the native backend's objective values to 1e-9 relative."""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import ebb_model as em
from fmu_build import build_fmu
from identification.native import experiments_from_arrays
from identification.fmu_backend import FmuEvaluator
from identification.native import NativeEvaluator
from identification.parameters import parameter_space
from identification.runners import DaskRunner, ProcessRunner

from conftest import make_identification_config


def test_fmu_and_native_objectives_agree(tmp_path):
    cfg = make_identification_config(nodes=16, c=0.3, N=40.0, sensors=[("y1", 0.5, "displacement"),
                                                                      ("a2", 0.8, "acceleration")])
    rng = np.random.default_rng(2)
    u = rng.standard_normal((400, 1))
    y = em.simulate_config(cfg, u).outputs
    y += 0.01 * y.std(0) * rng.standard_normal(y.shape)
    exps = experiments_from_arrays([("e", u, y)])
    space = parameter_space(cfg)
    fmu = build_fmu(cfg, tmp_path / "beam.fmu")
    native = NativeEvaluator(cfg, space, exps)
    fe = FmuEvaluator(str(fmu), cfg, space, exps)
    try:
        X = np.array([[10.0, 40.0], [12.5, 3.0], [7.0, 90.0]])
        F_native = native.evaluate(X)
        F_fmu = fe.evaluate(X)
        np.testing.assert_allclose(F_fmu, F_native, rtol=1e-9, atol=0)
        # invalid (EI = 0) and buckled (U = -40 < -4 pi^2) candidates: finite penalties on both backends,
        # the same stabilising objective
        Xbad = np.array([[0.0, 40.0], [10.0, -400.0]])
        bad_fmu, bad_native = fe.evaluate(Xbad), native.evaluate(Xbad)
        assert np.all(np.isfinite(bad_fmu)) and np.all(bad_fmu[:, :2] > 1e3) and np.all(bad_native[:, :2] > 1e3)
        np.testing.assert_array_equal(bad_fmu[:, 2], bad_native[:, 2])
        # and the reused instance still gives the right answer afterwards
        np.testing.assert_allclose(fe.evaluate(X[:1]), F_native[:1], rtol=1e-9, atol=0)
        assert fe.instantiations() == 1  # one instance for all eight candidates
        fe.close()
        np.testing.assert_allclose(fe.evaluate(X[:1]), F_native[:1], rtol=1e-9, atol=0)
        assert fe.instantiations() == 2  # closed, then created afresh
    finally:
        fe.close()


@dataclass(frozen=True, eq=False)
class _Reporting:
    """Test wrapper: the objectives plus, per row, the worker's pid and its FMU instantiations for this run."""

    inner: FmuEvaluator

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        F = self.inner.evaluate(X)
        return np.column_stack([F, np.full(len(F), os.getpid()), np.full(len(F), self.inner.instantiations())])

    def close(self) -> None:
        self.inner.close()


@pytest.fixture(scope="module")
def small_case(tmp_path_factory):
    cfg = make_identification_config(nodes=12, c=0.3, N=40.0)
    rng = np.random.default_rng(5)
    u = rng.standard_normal((150, 1))
    y = em.simulate_config(cfg, u).outputs
    exps = experiments_from_arrays([("e", u, y)])
    fmu = build_fmu(cfg, tmp_path_factory.mktemp("fmu") / "beam.fmu")
    return cfg, exps, fmu


def _extractions(d: Path) -> list[Path]:
    """FMU extraction directories (``fmpy.extract`` → ``tempfile.mkdtemp``) under ``d``."""
    return [p for p in d.iterdir() if p.is_dir() and p.name.startswith("tmp")]


@pytest.mark.parametrize("kind", ["process", "dask"])
def test_one_fmu_instance_per_worker_for_the_whole_run(small_case, kind, tmp_path, monkeypatch):
    """Several generations through 2 workers: every worker instantiates the FMU once and frees it at the end."""
    cfg, exps, fmu = small_case
    space = parameter_space(cfg)
    scratch = tmp_path / "worker_tmp"
    scratch.mkdir()
    monkeypatch.setenv("TMPDIR", str(scratch))  # the workers' tempfile directory (FMU extractions)
    ev = _Reporting(FmuEvaluator(str(fmu), cfg, space, exps))
    native = NativeEvaluator(cfg, space, exps)
    rng = np.random.default_rng(1)
    generations = [np.column_stack([rng.uniform(5, 20, 6), rng.uniform(0, 100, 6)]) for _ in range(4)]
    seen: dict[int, list[int]] = {}
    if kind == "process":
        runner_cm = ProcessRunner(2)
        cluster = None
    else:
        import distributed

        cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                           dashboard_address=None, local_directory=str(tmp_path / "dask"))
        runner_cm = DaskRunner(cluster.scheduler_address)
    try:
        with runner_cm as runner:
            for X in generations:
                out = runner(ev, X)
                np.testing.assert_allclose(out[:, :3], native.evaluate(X), rtol=1e-9, atol=0)
                for pid, n in out[:, 3:].astype(int):
                    seen.setdefault(pid, []).append(n)
            assert 1 <= len(seen) <= 2 and os.getpid() not in seen
            # every worker made exactly one instance, however many chunks and generations it evaluated
            assert all(set(ns) == {1} for ns in seen.values()), seen
            assert sum(len(ns) for ns in seen.values()) == 4 * 6
            assert max(len(ns) for ns in seen.values()) > 6  # instances were reused across generations
            assert len(_extractions(scratch)) == len(seen)  # one extracted FMU per worker, alive
        # runner closed: pool workers exited / Dask workers ran close(): extractions freed
        assert _extractions(scratch) == []
    finally:
        if cluster is not None:
            cluster.close()
    assert ev.inner.instantiations() == 0  # nothing was instantiated in this process
