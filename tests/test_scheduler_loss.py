"""A Dask scheduler lost mid-run (issue 74): the scheduler of a real cluster — a ``dask scheduler`` process and a
``dask worker`` process started here — killed (SIGKILL) in the middle of ``identify``, of ``diagnose`` and of a
batch.  Nothing the cluster was computing can come back, so the run ends at once with one line saying so and what
was kept: the last finished generation's checkpoint (``resume`` on another cluster then completes with the result
of a run without the loss: every evaluation and the GA's state are deterministic), nothing for a diagnosis, the
finished records of a batch (``resume`` diagnoses the others).  The kills come from the run's own progress callback
(after the GA's third generation, at the diagnosis' first score) or, for a batch, once either record's results
are written while the other still waits or runs.
"""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from diagnosis.run import diagnose
from ebb_model.errors import ClusterError, ConfigError
from identification.optimise import CHECKPOINT
from identification.run import identify

from test_evidence import siso_lag_record


class _Cluster:
    """A scheduler and one single-threaded worker, each its own process (a cluster started by hand)."""

    def __init__(self, where: Path):
        where.mkdir(parents=True, exist_ok=True)
        self.file = where / "scheduler.json"
        quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--port", "0",
                                           "--no-dashboard", "--scheduler-file", str(self.file)], **quiet)
        deadline = time.monotonic() + 60
        while not (self.file.is_file() and self.file.stat().st_size) and time.monotonic() < deadline:
            time.sleep(0.1)
        self.address = json.loads(self.file.read_text())["address"]
        self.worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file",
                                        str(self.file), "--nthreads", "1", "--no-dashboard"], **quiet)
        from distributed import Client

        with Client(self.address) as client:
            client.wait_for_workers(1, timeout=60)

    def close(self) -> None:
        for p in (self.worker, self.scheduler):
            p.kill()
            p.wait()


def test_identify_ends_with_one_line_and_resumes_when_the_scheduler_is_lost(identify_case):
    cfg, data, tmp = identify_case
    opts = dict(pop=16, generations=6, seed=3, progress=False, export=False)
    alone = identify(cfg, [data], tmp / "alone", **opts)
    first = _Cluster(tmp / "first")
    try:
        def kill_the_scheduler(p) -> None:
            if p.stage == "generation" and p.step == 3 and first.scheduler.poll() is None:
                first.scheduler.kill()
                first.scheduler.wait()

        t0 = time.monotonic()
        with pytest.raises(ClusterError) as lost:
            identify(cfg, [data], tmp / "run", dask=first.address, on_progress=kill_the_scheduler, **opts)
        ended = time.monotonic() - t0
    finally:
        first.close()
    said = str(lost.value)
    assert "\n" not in said and first.address in said and "went away" in said and "resume" in said, said
    assert (tmp / "run" / CHECKPOINT).is_file() and not (tmp / "run" / "pareto.json").exists()
    assert ended < 60, ended                    # not the client's 30 s of reconnecting, nor a hang
    second = _Cluster(tmp / "second")
    try:
        res = identify(cfg, [data], tmp / "run", dask=second.address, resume=True, **opts)
    finally:
        second.close()
    np.testing.assert_array_equal(res.pareto.X, alone.pareto.X)
    np.testing.assert_array_equal(res.pareto.F, alone.pareto.F)
    assert res.best == alone.best


def test_the_command_line_says_it_in_one_line(identify_case):
    """``ebb identify --dask ADDRESS`` with the scheduler killed once the first generation is checkpointed: exit
    2, and standard error holds the progress bar and one line — not the client's traceback of its cancelled
    reconnection, which it logs when it is closed while reconnecting."""
    cfg, data, tmp = identify_case
    cluster = _Cluster(tmp / "cluster")
    out = tmp / "cli"
    try:
        run = subprocess.Popen([sys.executable, "-c", "import sys; from ebb_cli import main; sys.exit(main())",
                                "identify", str(cfg), str(data), "--out",
                                str(out), "--dask", cluster.address, "--pop", "16", "--generations", "500",
                                "--no-export"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 120
        while not (out / CHECKPOINT).is_file() and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        cluster.scheduler.kill()
        _, err = run.communicate(timeout=120)
    finally:
        cluster.close()
    lines = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip() and "gen/s]" not in ln]
    assert run.returncode == 2 and len(lines) == 1, err[-3000:]
    assert lines[0].startswith("ebb identify: error: the Dask scheduler at") and "--resume" in lines[0], lines


def test_diagnose_ends_with_one_line_and_writes_nothing_when_the_scheduler_is_lost(tmp_path):
    """The scheduler killed at the diagnosis' first score (its refits about to be sent out): one line naming the
    scheduler, saying that nothing was written, and nothing in the output directory."""
    cfg, rec = siso_lag_record(tmp_path)
    cluster = _Cluster(tmp_path / "cluster")
    try:
        def kill_at_first_score(message: str) -> None:
            if message.startswith("score") and cluster.scheduler.poll() is None:
                cluster.scheduler.kill()
                cluster.scheduler.wait()

        with pytest.raises(ClusterError) as lost:
            diagnose(cfg, [rec], tmp_path / "gap", plots=False, export=False, dask=cluster.address,
                     progress=kill_at_first_score)
    finally:
        cluster.close()
    said = str(lost.value)
    assert "\n" not in said and cluster.address in said and "nothing was written" in said, said
    assert not (tmp_path / "gap").exists() or not any((tmp_path / "gap").iterdir())


def _long_record(tmp_path: Path) -> Path:
    """The same bench and lag as :func:`test_evidence.siso_lag_record`, three times as long (its diagnosis takes
    longer than the short record's whole batch task)."""
    from ebb_model.reference.excitation import band_limited_input
    from ebb_model.reference.synthetic import synthesize
    from ebb_model.reference.withheld import WithheldEffect
    from test_diagnosis_blind import DT, N_SAMPLES, TRUTH

    (tmp_path / "long").mkdir()
    cfg, _ = siso_lag_record(tmp_path / "long")
    u = band_limited_input(3 * N_SAMPLES, DT, 2.0, 60.0, seed=4)
    rec = synthesize(cfg, u, params=TRUTH, effect=WithheldEffect("actuator_lag", {"tau": 5e-4}), noise=0.01,
                     seed=104)
    path = tmp_path / "long.npz"
    np.savez(path, time=rec.time, F1=rec.inputs[:, 0], y2=rec.outputs[:, 0])
    return path


def test_a_batch_keeps_its_finished_records_and_resumes_the_others(tmp_path):
    """``diagnose --each`` on a cluster whose scheduler is killed once the first record's ``gap.json`` is written
    (the other still waiting or running): one line saying 1 of 2 records is kept, the finished record's results and
    the checkpoint in OUT; ``resume`` on another cluster diagnoses the other record alone, and the batch's verdicts
    and the kept record's results are those of a batch without the loss.  A resume with another option is refused.

    Which record the worker takes first is the scheduler's choice (the two tasks may reach it in one graph, ordered
    by their keys), so the kill waits for either: waiting for the short one alone raced — with the long record taken
    first, both were done when the short one's results appeared, and nothing was lost."""
    import threading

    from diagnosis.batch import BATCH_FILE, diagnose_each

    cfg, short = siso_lag_record(tmp_path)
    long = _long_record(tmp_path)
    opts = dict(plots=False, export=False)
    alone = diagnose_each(cfg, [short, long], tmp_path / "alone", workers=1, **opts)
    out = tmp_path / "batch"
    first = _Cluster(tmp_path / "first")
    stop = threading.Event()

    finished: list[str] = []

    def kill_once_a_record_is_done() -> None:
        while not stop.is_set():
            # a record's folder is written as ``.STEM.XXXXXXXX.part`` and renamed when whole: only renamed ones are
            # done (counting the hidden one raced: its name is no record's stem)
            done = [p.parent.name for p in tmp_path.glob(f".{out.name}.*.part/*/gap.json")
                    if not p.parent.name.startswith(".")]
            if done:
                first.scheduler.kill()
                finished.extend(done)
                return
            time.sleep(0.02)

    watcher = threading.Thread(target=kill_once_a_record_is_done, daemon=True)
    watcher.start()
    try:
        with pytest.raises(ClusterError) as lost:
            diagnose_each(cfg, [short, long], out, dask=first.address, **opts)
    finally:
        stop.set()
        watcher.join()
        first.close()
    said = str(lost.value)
    assert "\n" not in said and "1 of 2 records are done and kept" in said and "resume" in said, said
    assert len(finished) == 1, finished
    [kept_stem] = finished
    [other_stem] = {short.stem, long.stem} - {kept_stem}
    assert (out / BATCH_FILE).is_file() and (out / kept_stem / "gap.json").is_file()
    assert not (out / other_stem).exists()
    kept = (out / kept_stem / "gap.json").read_bytes()
    with pytest.raises(ConfigError, match="options differ"):
        diagnose_each(cfg, [short, long], out, workers=1, resume=True, plots=False, export=False,
                      holdout_fraction=0.25)
    second = _Cluster(tmp_path / "second")
    said_too: list[str] = []
    try:
        docs = diagnose_each(cfg, [short, long], out, dask=second.address, resume=True, progress=said_too.append,
                             **opts)
    finally:
        second.close()
    assert any("diagnosing 1 records" in m and "1 done before the resume" in m for m in said_too), said_too
    assert [d["verdict"] for d in docs] == [d["verdict"] for d in alone]
    assert (out / kept_stem / "gap.json").read_bytes() == kept
    assert (out / other_stem / "gap.json").is_file() and not (out / BATCH_FILE).exists()
    assert sorted(p.name for p in out.iterdir()) == sorted([short.stem, long.stem])


def test_a_scheduler_lost_while_the_runner_closes_does_not_mask_what_the_run_says(tmp_path):
    """The scheduler killed just before the runner releases the evaluators on the workers — before the client has
    noticed (the race a CI run met: the release then failed on a reset connection, and its traceback replaced the
    run's one line): the run's ClusterError comes out, and the client closes without a word."""
    from identification.runners import DaskRunner

    class Closable:       # an evaluator with something to release on the workers (as the FMU backend's); local:
        def evaluate(self, X: np.ndarray) -> np.ndarray:     # pickled by value for the worker
            return np.asarray(X, dtype=float).sum(axis=1, keepdims=True)

        def close(self) -> None:
            pass

    cluster = _Cluster(tmp_path / "cluster")
    try:
        with pytest.raises(ClusterError, match="went away"):
            with DaskRunner(cluster.address) as runner:
                assert runner(Closable(), np.ones((4, 2))).ravel().tolist() == [2.0] * 4
                cluster.scheduler.kill()
                cluster.scheduler.wait()
                raise ClusterError(f"the scheduler at {cluster.address} went away (as the run says it)")
    finally:
        cluster.close()
