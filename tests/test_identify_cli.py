"""``ebb identify`` / ``ebb export`` end to end on a small synthetic case, and their bad-input handling."""
from __future__ import annotations

import json

import numpy as np
import pytest

import ebb_model as em
from ebb_cli import main
from ebb_model.modal.truncation import design_model
from identification.export_statespace import load_metadata, load_statespace

from conftest import IDENTIFY_CFG as CFG
from conftest import run_identify_signalled

@pytest.fixture
def case(identify_case):
    return identify_case


def test_identify_writes_results_and_exports(case, capsys):
    cfg, data, tmp = case
    out = tmp / "out"
    rc = main(["identify", str(cfg), str(data), "--out", str(out), "--pop", "8", "--generations", "3",
               "--no-progress"])
    assert rc == 0
    doc = json.loads((out / "pareto.json").read_text())
    assert doc["parameter_names"] == ["EI", "N"]
    # the default (exact) scheme: no stabilising objective, which belongs to the seed's θ-scheme
    assert doc["objective_names"] == ["nrmse_y1", "nrmse_y2"]
    assert sum(p["knee"] for p in doc["points"]) == 1
    adequacy = doc["numerical_adequacy"]
    # refined: 4n + 3 nodes, or the finer grid the grid advice asks for the excited band (here up to Nyquist)
    assert adequacy["refined_nodes"] >= 4 * 16 + 3 and set(adequacy["sensors"]) == {"y1", "y2"}
    assert doc["identified"]["polished"] and doc["config_name"] == "cfg"
    # (what the share means is tested in test_adequacy.py against independent truth; here the data come from
    # the 16-node model itself, so refining moves away from them)
    assert all(np.isfinite(v["numerical_share"]) and v["change"] >= 0 for v in adequacy["sensors"].values())
    for p in doc["points"]:
        assert set(p) >= {"parameters", "objectives", "cramer_rao_std", "growth_factor", "stable"}
    for f in ("pareto.csv", "identifiability.json", "pareto_front.png", "knee_fit.png", "checkpoint.pkl"):
        assert (out / f).exists(), f
    header = (out / "pareto.csv").read_text().splitlines()[0].split(",")
    assert header.count("growth_factor") == 1 and len(set(header)) == len(header)
    sys0 = load_statespace(out / "export" / "point_0.npz")
    assert list(sys0.output_labels) == ["y1", "y2"] and sys0.dt == 1e-4


def test_result_reads_back_and_exports_by_target_name(case, capsys):
    """``pareto.json`` is :meth:`IdentificationResult.to_dict`; :meth:`IdentificationResult.read` gives back the
    same document, and ``ebb export --target`` writes exactly the named targets (an unknown name: exit 2, nothing
    written)."""
    from identification.result import IdentificationResult

    cfg, data, tmp = case
    out = tmp / "out"
    assert main(["identify", str(cfg), str(data), "--out", str(out), "--pop", "8", "--generations", "2",
                 "--no-progress", "--target", "statespace"]) == 0
    assert sorted(p.suffix for p in (out / "export").iterdir()) == [".npz"] * len(list((out / "export").iterdir()))
    res = IdentificationResult.read(out)
    assert res.to_dict() == json.loads((out / "pareto.json").read_text())   # the GA's history included:
    assert res.pareto.history.shape == (2, 3) and res.pareto.history[-1, 0] == res.pareto.n_evaluations
    assert res.best == json.loads((out / "pareto.json").read_text())["identified"]["parameters"]
    capsys.readouterr()
    assert main(["export", str(out), "--polished", "0", "--target", "nonsense"]) == 2
    assert ("--target: unknown export target 'nonsense'; allowed: statespace, fmu, fmu_fmi3, standalone, "
            "standalone_fmi3" in capsys.readouterr().err)
    before = sorted(p.name for p in (out / "export").iterdir())
    assert main(["export", str(out), "--polished", "0", "--target", "fmu"]) == 0
    assert sorted(p.name for p in (out / "export").iterdir()) == sorted(set(before) | {"polished_0.fmu"})


@pytest.mark.parametrize("case_name", ["nan data", "missing column", "bad bounds", "wrong dt", "not empty",
                                       "bad local cluster"])
def test_identify_bad_input_exit_2_no_result_dir(case, case_name, capsys):
    cfg, data, tmp = case
    out = tmp / "out"
    if case_name == "nan data":
        lines = data.read_text().splitlines()
        lines[5] = ",".join(lines[5].split(",")[:-1] + ["nan"])
        data.write_text("\n".join(lines) + "\n")
    elif case_name == "missing column":
        data.write_text(data.read_text().replace("time,F1,y1,y2", "time,F1,y1,yy"))
    elif case_name == "bad bounds":
        cfg.write_text(CFG.replace("bounds = [5.0, 20.0]", "bounds = [20.0, 5.0]"))
    elif case_name == "wrong dt":
        cfg.write_text(CFG.replace("dt = 1e-4", "dt = 2e-4"))
    elif case_name == "not empty":
        out.mkdir()
        (out / "something").write_text("x")
    extra = ["--dask", "local:0"] if case_name == "bad local cluster" else []
    rc = main(["identify", str(cfg), str(data), "--out", str(out), "--pop", "8", "--generations", "2",
               "--no-progress", *extra])
    assert rc == 2
    err = capsys.readouterr().err
    assert "error" in err
    if extra:
        assert "local:K" in err
    if case_name != "not empty":
        assert not out.exists()


def test_identify_with_fmu_backend_gives_the_native_front(case):
    """Same seed, same data: the FMU backend (fmpy) and the native backend produce the same Pareto set."""
    cfg, data, tmp = case
    args = ["--pop", "6", "--generations", "2", "--no-progress", "--no-export", "--seed", "4"]
    assert main(["identify", str(cfg), str(data), "--out", str(tmp / "n"), "--backend", "native", *args]) == 0
    assert main(["identify", str(cfg), str(data), "--out", str(tmp / "f"), "--backend", "fmu", *args]) == 0
    a = json.loads((tmp / "n" / "pareto.json").read_text())
    b = json.loads((tmp / "f" / "pareto.json").read_text())
    assert [p["parameters"] for p in a["points"]] == [p["parameters"] for p in b["points"]]
    for pa, pb in zip(a["points"], b["points"]):
        for k, v in pa["objectives"].items():
            assert pb["objectives"][k] == pytest.approx(v, rel=1e-9)


def test_kill_9_then_resume_gives_the_uninterrupted_front(case):
    import signal

    cfg, data, tmp = case
    args = ["--pop", "8", "--generations", "30", "--no-progress", "--no-export", "--seed", "9"]
    assert main(["identify", str(cfg), str(data), "--out", str(tmp / "ref"), *args]) == 0
    out = tmp / "killed"
    # killed right after the checkpoint of generation 3, however fast the machine (no polling race)
    proc = run_identify_signalled(cfg, data, out, signal.SIGKILL, 3, *args)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    assert (out / "checkpoint.pkl").exists()
    assert not (out / "pareto.json").exists()
    assert main(["identify", str(cfg), str(data), "--out", str(out), "--resume", *args]) == 0
    a = json.loads((tmp / "ref" / "pareto.json").read_text())
    b = json.loads((out / "pareto.json").read_text())
    assert a["points"] == b["points"]


def test_resume_refuses_what_the_checkpoint_was_not_made_with(case, capsys):
    """``--resume`` continues the run the checkpoint belongs to, or says in one line why not (exit 2, the checkpoint
    untouched): the record scaled by 1000 (it exited 0 before: the GA front from the old data, the polish on the
    new), a changed bound, another population; options not given are the checkpoint's."""
    import signal

    cfg, data, tmp = case
    args = ["--pop", "8", "--generations", "30", "--no-progress", "--no-export", "--seed", "9"]
    out = tmp / "killed"
    proc = run_identify_signalled(cfg, data, out, signal.SIGKILL, 3, *args)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    saved = (out / "checkpoint.pkl").read_bytes()
    table = np.loadtxt(data, delimiter=",", skiprows=1)
    header = data.read_text().splitlines()[0]
    scaled = tmp / "scaled" / "data.csv"
    scaled.parent.mkdir()
    table[:, 2:] *= 1000.0
    np.savetxt(scaled, table, delimiter=",", header=header, comments="")
    bounds = tmp / "bounds.toml"
    bounds.write_text(_widened(cfg.read_text()))
    for config, record, extra, expected in ((cfg, scaled, [], "different data in data"),
                                            (bounds, data, [], "a different config"),
                                            (cfg, data, ["--pop", "20"], "made with pop 8 (now 20)")):
        capsys.readouterr()
        assert main(["identify", str(config), str(record), "--out", str(out), "--resume", "--no-progress",
                     "--no-export", *extra]) == 2, expected
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and expected in err[0], (expected, err)
        assert (out / "checkpoint.pkl").read_bytes() == saved and not (out / "pareto.json").exists()
    # nothing but the directory: the checkpoint's options, the same front as an uninterrupted run
    assert main(["identify", str(cfg), str(data), "--out", str(out), "--resume", "--no-progress", "--no-export"]) == 0
    assert main(["identify", str(cfg), str(data), "--out", str(tmp / "ref"), *args]) == 0
    a = json.loads((tmp / "ref" / "pareto.json").read_text())
    assert a["points"] == json.loads((out / "pareto.json").read_text())["points"]


def _widened(text: str) -> str:
    """The config with its first unknown's upper bound doubled."""
    import re

    m = re.search(r"bounds\s*=\s*\[\s*([^,\]]+),\s*([^\]]+)\]", text)
    assert m, text
    return text[:m.start()] + f"bounds = [{m.group(1)}, {2 * float(m.group(2))}]" + text[m.end():]


def test_identify_polish_writes_polished_points_and_exports_them(case, capsys):
    """``--polish 2``: the two points nearest the knee refined, and the records' start beside them (the lower
    χ² of the knee's and the start's first); counts, files and exports."""
    cfg, data, tmp = case
    out = tmp / "out"
    rc = main(["identify", str(cfg), str(data), "--out", str(out), "--pop", "8", "--generations", "3",
               "--no-progress", "--no-export", "--polish", "2", "--seed", "3"])
    assert rc == 0
    printed = capsys.readouterr().out
    doc = json.loads((out / "pareto.json").read_text())
    pol = doc["polished"]
    assert len(pol) == min(2, len(doc["points"])) + 1
    starts = [q["from_index"] for q in pol]
    assert sorted(starts[:2]) == sorted([doc["knee"], -1]) and doc["data_start"]["parameters"]
    assert pol[0]["cost"] <= pol[1]["cost"]
    for q in pol:
        assert set(q) >= {"parameters", "objectives", "cramer_rao_std", "growth_factor", "stable",
                          "n_evaluations", "from_index"}
        assert q["stable"] and q["n_evaluations"] > len(doc["parameter_names"])
        if q["from_index"] < 0:
            continue
        # a least-squares polish never ends worse than its start: sum of squared output errors
        start = doc["points"][q["from_index"]]["objectives"]
        sse = sum(v ** 2 for k, v in q["objectives"].items() if k.startswith("nrmse_"))
        assert sse <= sum(v ** 2 for k, v in start.items() if k.startswith("nrmse_"))
    assert doc["n_evaluations_ga"] == 8 * 3
    assert doc["n_evaluations_polish"] == sum(q["n_evaluations"] for q in pol)
    assert doc["n_evaluations"] == doc["n_evaluations_ga"] + doc["n_evaluations_polish"]
    # data from the model itself with 1 % noise: the polished knee is the truth within 4 Cramér–Rao std
    truth = {"EI": 10.0, "N": 50.0}
    for k, v in truth.items():
        assert abs(pol[0]["parameters"][k] - v) <= 4 * pol[0]["cramer_rao_std"][k], (k, pol[0])
    rows = (out / "polished.csv").read_text().splitlines()
    assert rows[0].startswith("index,from_index,EI,N,") and len(rows) == 1 + len(pol)
    origin = "the records' start" if pol[0]["from_index"] < 0 else f"Pareto point {doc['knee']}"
    assert f"identified model (polished, from {origin}):" in printed
    assert f"total evaluations (GA + polish): {doc['n_evaluations']}" in printed
    assert doc["identified"]["parameters"] == pol[0]["parameters"] and doc["identified"]["cramer_rao_valid"]
    # exports of a polished point: StateSpace with the polished values, and an FMU
    assert main(["export", str(out), "--polished", "0"]) == 0
    sys_p = load_statespace(out / "export" / "polished_0.npz")
    c = em.config_from_dict(doc["config"], extra_sections=("identification",))
    # (the design model: the modes up to the Nyquist frequency the grid resolves, the rest a static correction)
    ref = design_model(c, {**c.parameter_values(), **pol[0]["parameters"]})
    np.testing.assert_allclose(sys_p.A, ref.A, rtol=1e-12, atol=0)
    modes = load_metadata(out / "export" / "polished_0.npz")["modes"]
    kept = [m for m in modes["modes"] if m["kept"]]
    assert tuple(sys_p.state_labels[:2 * len(kept)]) == tuple(f"mode{i}_{p}" for i in range(1, len(kept) + 1)
                                                        for p in ("re", "im"))
    assert all(m["error_bandwidths"] <= modes["error_limit_bandwidths"] for m in kept)
    assert (out / "export" / "polished_0.fmu").is_file()
    assert not (out / "export" / "point_0.npz").exists()  # only the selection
    assert main(["export", str(out), "--polished", "5"]) == 2  # out of range: clear error


def test_identify_on_a_local_dask_cluster_gives_the_serial_front(case):
    """``--dask local:2`` starts its own low-overhead cluster, evaluates there and closes it: same front."""
    cfg, data, tmp = case
    args = ["--pop", "6", "--generations", "2", "--no-progress", "--no-export", "--seed", "3"]
    assert main(["identify", str(cfg), str(data), "--out", str(tmp / "s"), *args]) == 0
    assert main(["identify", str(cfg), str(data), "--out", str(tmp / "d"), "--dask", "local:2", *args]) == 0
    a = json.loads((tmp / "s" / "pareto.json").read_text())
    b = json.loads((tmp / "d" / "pareto.json").read_text())
    assert [p["parameters"] for p in a["points"]] == [p["parameters"] for p in b["points"]]
    assert [p["objectives"] for p in a["points"]] == [p["objectives"] for p in b["points"]]
