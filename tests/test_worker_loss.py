"""A Dask worker lost mid-run (issue 54): one worker process of a real ``LocalCluster`` killed (SIGKILL, as the
kernel's OOM killer or a lost machine would) in the middle of ``identify`` and of ``diagnose``.  Dask runs the
lost worker's tasks again on the others (the nanny restarts it), the evaluator scattered to every worker is
fetched from another or, when the lost worker held its last copy, sent again, and every evaluation is
deterministic: the run completes with the result of a run without the loss, and says what happened (``events``
in ``pareto.json`` / ``gap.json``, a ``note:`` line).

The kill comes from the run's own progress callback, at a point with work still to do on the cluster (after the
GA's third generation; at the diagnosis' first score, before its refits are sent out), so the test does not
depend on timing.
"""
from __future__ import annotations

import json
import os
import signal
import time

import numpy as np

from diagnosis.run import diagnose
from identification.cluster import local_cluster
from identification.run import identify

from test_diagnose_dask import _same_diagnosis
from test_evidence import siso_lag_record


def _kill_one_worker(client) -> str:
    """SIGKILL one worker process of the cluster; its address."""
    address, pid = sorted(client.run(os.getpid).items())[0]
    os.kill(pid, signal.SIGKILL)
    return address


def _kill_the_worker_holding_the_evaluator(client) -> str:
    """SIGKILL the one worker left holding the scattered evaluator; its address.

    The runner scatters its evaluator to every worker, but Dask's active memory manager (on by default, every 2 s)
    drops the replicas of data no task is waiting for: between two generations the evaluator has one copy left.
    Waiting for that and killing its holder is the loss that failed a CI run ("cancelled for reason: already
    forgotten"), made certain instead of a matter of timing."""
    deadline = time.monotonic() + 30.0
    while True:
        held = {k: w for k, w in client.who_has().items() if w and not str(k).startswith("_evaluate_chunk")}
        holders = {a for w in held.values() for a in w}
        if len(held) == 1 and len(holders) == 1:
            address = holders.pop()
            break
        assert time.monotonic() < deadline, f"the evaluator is still held by {held} after 30 s"
        time.sleep(0.2)
    pid = client.run(os.getpid, workers=[address])[address]
    os.kill(pid, signal.SIGKILL)
    return address


def test_identify_completes_with_the_same_result_when_a_worker_is_killed(identify_case):
    from distributed import Client

    cfg, data, tmp = identify_case
    opts = dict(pop=16, generations=8, seed=3, progress=False, export=False)
    alone = identify(cfg, [data], tmp / "alone", **opts)
    killed: list[str] = []
    with local_cluster(2) as cluster, Client(cluster) as client:
        def kill_after_third_generation(p) -> None:
            if p.stage == "generation" and p.step == 3 and not killed:
                killed.append(_kill_the_worker_holding_the_evaluator(client))

        res = identify(cfg, [data], tmp / "dask", dask=cluster.scheduler_address,
                       on_progress=kill_after_third_generation, **opts)
    assert killed
    np.testing.assert_array_equal(res.pareto.X, alone.pareto.X)
    np.testing.assert_array_equal(res.pareto.F, alone.pareto.F)
    assert res.best == alone.best
    doc = json.loads((tmp / "dask" / "pareto.json").read_text())
    assert len(doc["events"]) == 1 and killed[0] in doc["events"][0] and "lost" in doc["events"][0], doc["events"]
    assert json.loads((tmp / "alone" / "pareto.json").read_text())["events"] == []


def test_diagnose_completes_with_the_same_result_when_a_worker_is_killed(tmp_path):
    from distributed import Client

    cfg, rec = siso_lag_record(tmp_path)
    alone = diagnose(cfg, [rec], tmp_path / "alone", plots=False, export=False, workers=1).document
    killed: list[str] = []
    said: list[str] = []
    with local_cluster(2) as cluster, Client(cluster) as client:
        def kill_at_first_score(message: str) -> None:
            said.append(message)
            if message.startswith("score") and not killed:
                killed.append(_kill_one_worker(client))

        there = diagnose(cfg, [rec], tmp_path / "dask", plots=False, export=False, dask=client,
                         progress=kill_at_first_score).document
    assert killed
    _same_diagnosis(alone, there)
    assert len(there["events"]) == 1 and killed[0] in there["events"][0], there.get("events")
    assert any(m.startswith("note: ") and killed[0] in m for m in said)
    assert "events" not in alone
