"""``ebb diagnose`` scaled out (issue 32): the refits on a real Dask LocalCluster, and a batch of records
diagnosed one task each (``--each``) on local processes or on the cluster.

Every task runs with one BLAS thread and is deterministic, so where it ran must not change the result: the
cluster's diagnosis equals the single-process one (the verdict, the posterior probabilities and every refit's
parameters, to 1e-9).
"""
from __future__ import annotations

import json

import pytest

from ebb_cli import main

from diagnosis.run import diagnose

from test_diagnose_cli import _toml
from test_evidence import siso_lag_record
from test_noise_model import truth_config, truth_records


def _same_diagnosis(here: dict, there: dict, *, refitted: bool = True) -> None:
    """The verdict, the posterior probabilities, the baseline's parameters, every score and every refit's
    parameters (to 1e-9) agree; ``refitted``: there are refits to compare (a record without effect whose baseline
    is at the floor has none: no refit could change its verdict)."""
    assert there["verdict"] == here["verdict"] and there["indistinguishable"] == here["indistinguishable"]
    for lab, p in here["posterior_probability"].items():
        assert there["posterior_probability"][lab] == pytest.approx(p, rel=1e-9, abs=1e-12)
    for k, v in here["baseline"]["parameters"].items():
        assert there["baseline"]["parameters"][k] == pytest.approx(v, rel=1e-9), k
    scores = {e["label"]: e["score"] for e in here["effects"]}
    assert {e["label"]: e["score"] for e in there["effects"]} == pytest.approx(scores, rel=1e-9, abs=1e-9)
    refits = {e["label"]: e["refit"] for e in here["effects"] if e.get("refit")}
    assert bool(refits) == refitted, refits
    for e in there["effects"]:
        if e.get("refit"):
            for k, v in refits[e["label"]]["effect_parameters"].items():
                assert e["refit"]["effect_parameters"][k] == pytest.approx(v, rel=1e-9), (e["label"], k)


@pytest.mark.parametrize("where", [{"dask": "local:2"}, {"workers": 2}, {"workers": 4}],
                         ids=["dask", "processes", "4-processes"])
def test_the_refits_on_other_processes_give_the_single_process_result(tmp_path, where):
    """1, 2 and 4 local processes and a Dask cluster: the same diagnosis (the continuation refits, run
    ``parallel`` at a time, are taken in order up to the first that explains the gap, as one process takes them:
    diagnosis/search/rank._continuation_stage)."""
    cfg, rec = siso_lag_record(tmp_path)
    here = diagnose(cfg, [rec], tmp_path / "here", plots=False, export=False, workers=1).document
    there = diagnose(cfg, [rec], tmp_path / "there", plots=False, export=False, **where).document
    _same_diagnosis(here, there)


def _square(x: float) -> float:
    return x * x


def _fits_inside(xs: list[float]) -> tuple[bool, list[float]]:
    """A task that runs fits as tasks of its own cluster (what a batch's record does)."""
    from diagnosis.search.workers import DaskExecutor, side_by_side, task_cluster

    client = task_cluster()
    return client is not None, side_by_side(DaskExecutor(client), _square, [(x,) for x in xs])


def test_a_tasks_fits_run_on_its_cluster_without_holding_the_worker():
    """On a cluster of one single-threaded worker a task waiting for its own fits would wait forever if it kept
    the worker's only thread; it gives the thread back while it waits.  Outside a task there is no task cluster."""
    from distributed import Client

    from diagnosis.search.workers import task_cluster
    from identification.cluster import local_cluster

    assert task_cluster() is None
    with local_cluster(1) as cluster, Client(cluster) as client:
        inside, squares = client.submit(_fits_inside, [1.0, 2.0, 3.0], pure=False).result(timeout=120)
    assert inside and squares == [1.0, 4.0, 9.0]


@pytest.mark.parametrize("where", [["--workers", "2"], ["--dask", "local:2"]], ids=["processes", "dask"])
def test_each_record_is_diagnosed_on_its_own(tmp_path, capsys, where):
    cfg = truth_config()
    (tmp_path / "bench.toml").write_text(_toml(cfg))
    files = truth_records(tmp_path, cfg)
    out = tmp_path / "batch"
    assert main(["diagnose", str(tmp_path / "bench.toml"), *map(str, files), "--each", "--out", str(out),
                 "--quiet", "--no-plots", *where]) == 0
    printed = capsys.readouterr().out
    for f in files:
        doc = json.loads((out / f.stem / "gap.json").read_text())
        assert doc["verdict"] == "none", doc["reason"]
        assert f"{f}: verdict none" in printed
    # a record diagnosed in the batch (on the cluster: its fits as tasks of it) is the record diagnosed alone
    alone = diagnose(cfg, [files[0]], None, plots=False, export=False, workers=1).document
    _same_diagnosis(alone, json.loads((out / files[0].stem / "gap.json").read_text()), refitted=False)


def test_bad_batches_and_addresses_stop_before_anything_is_written(tmp_path, capsys):
    cfg = truth_config()
    (tmp_path / "bench.toml").write_text(_toml(cfg))
    files = truth_records(tmp_path, cfg, seeds=(41,))
    (tmp_path / "b").mkdir()
    twin = tmp_path / "b" / files[0].name
    twin.write_bytes(files[0].read_bytes())
    cases = [([str(files[0]), str(twin), "--each"], "same name"),
             ([str(files[0]), "--dask", "local:0"], "local:K"),
             ([str(files[0]), str(tmp_path / "missing.csv"), "--each"], "missing.csv")]
    for i, (args, words) in enumerate(cases):
        out = tmp_path / f"o{i}"
        assert main(["diagnose", str(tmp_path / "bench.toml"), *args, "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and words in err, err
        assert not out.exists()


def test_a_batch_that_fails_in_a_task_keeps_nothing(tmp_path):
    """A record that reads but cannot be diagnosed (ten samples) stops the batch after another record finished:
    the staged batch is removed, ``OUT`` is not created."""
    from diagnosis.batch import diagnose_each
    from ebb_model.errors import EbbError

    cfg = truth_config()
    good = truth_records(tmp_path, cfg, seeds=(41,))[0]
    short = tmp_path / "short.csv"
    short.write_text("time,F1,y1,y2\n" + "".join(f"{k * 5e-4},0,0,0\n" for k in range(10)))
    with pytest.raises(EbbError):
        diagnose_each(cfg, [good, short], tmp_path / "batch", workers=1, plots=False, export=False)
    assert not (tmp_path / "batch").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".batch")]
