"""``ebb diagnose`` / ``ebb demo`` from the command line: outputs, bad input (exit 2, nothing written)."""
from __future__ import annotations

import json
import time

import pytest

from ebb_cli import main
from ebb_model.reference.excitation import band_limited_input
from ebb_model.reference.synthetic import synthesize
from ebb_model.reference.withheld import WithheldEffect

from test_diagnosis_blind import DT, bench_config


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    d = tmp_path_factory.mktemp("bench")
    cfg = bench_config()
    (d / "bench.toml").write_text(_toml(cfg))
    files = []
    for seed in (21, 22):
        u = band_limited_input(3000, DT, 2.0, 60.0, seed=seed)
        rec = synthesize(cfg, u, effect=WithheldEffect("actuator_lag", {"tau": 6e-4}), noise=0.01, seed=seed)
        path = d / f"rec{seed}.csv"
        rec.to_csv(path)
        files.append(path)
    return d, files


def _toml(cfg) -> str:
    d = cfg.to_dict()
    lines = ["[beam]"] + [f"{k} = {json.dumps(v)}" for k, v in d["beam"].items()]
    lines += ["[time]"] + [f"{k} = {json.dumps(v)}" for k, v in d["time"].items()]
    lines += ["[parameters]"]
    for k, p in d["parameters"].items():
        items = ", ".join(f"{kk} = {json.dumps(vv)}" for kk, vv in p.items())
        lines.append(f"{k} = {{ {items} }}")
    for a in d["actuators"]:
        lines += ["[[actuators]]", f"name = {json.dumps(a['name'])}", f"x = {a['x']}"]
    for s in d["sensors"]:
        lines += ["[[sensors]]", f"name = {json.dumps(s['name'])}", f"x = {s['x']}", f"kind = {json.dumps(s['kind'])}"]
    return "\n".join(lines) + "\n"


def test_diagnose_with_holdout_file_writes_gap_json_and_plots(bench, capsys):
    d, (fit, held) = bench
    out = d / "gap"
    t0 = time.perf_counter()
    rc = main(["diagnose", str(d / "bench.toml"), str(fit), "--holdout", str(held), "--out", str(out), "--quiet"])
    elapsed = time.perf_counter() - t0
    assert rc == 0
    doc = json.loads((out / "gap.json").read_text())
    assert doc["verdict"] == "actuator_lag"
    # where the time went, each second once: the stages add up to less than the call (reading the records and
    # writing the results are outside them) and cover most of it
    stages = doc["stage_seconds"]
    assert {"baseline and the force's sign", "noise model", "score tests", "local refits",
            "localisation"} <= set(stages)
    assert all(v >= 0 for v in stages.values()) and 0.5 * elapsed < sum(stages.values()) < elapsed
    # the gap is the withheld lag's, not the grid's: refining the baseline's grid changes little of it
    assert doc["baseline"]["numerical_adequacy"]["max_numerical_share"] < 0.1
    top = doc["effects"][0]
    assert top["label"] == "actuator_lag" and top["refit"]["closed"] >= 0.8
    assert abs(top["refit"]["effect_parameters"]["tau"] - 6e-4) < 1.5e-4
    assert set(doc["localisation"]) == {"rec21", "holdout:rec22"}
    assert (out / "effects.png").is_file() and (out / "heldout_residuals.png").is_file()
    printed = capsys.readouterr().out
    assert "verdict: actuator_lag" in printed and "baseline's numerical share of the gap:" in printed
    # the beam's values with and without the named effect, as gap.json has them
    for head, params in (("baseline (no effect): ", doc["baseline"]["parameters"]),
                         ("with actuator_lag: ", top["refit"]["baseline_parameters"])):
        assert head + ", ".join(f"{k} = {v:.5g}" for k, v in params.items()) in printed


@pytest.mark.parametrize("extra,problem", [
    (["--holdout-fraction", "1.5"], "holdout-fraction"),
    (["--shortlist", "0"], "shortlist"),
    (["--workers", "0"], "workers"),
    (["--result", "nowhere"], "pareto.json"),
])
def test_bad_settings_exit_2_and_write_nothing(bench, tmp_path, capsys, extra, problem):
    d, (fit, _) = bench
    out = tmp_path / "gap"
    rc = main(["diagnose", str(d / "bench.toml"), str(fit), "--out", str(out), "--quiet", *extra])
    assert rc == 2
    assert problem in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("content, said", [
    (None, "no such file"),
    (b"\x00\x9f\xffjunk", "not a readable gap.json"),
    (b'{"verdict": "none"}', "no 'log_posterior'"),
    (b'{"log_posterior": {"none": 0.5}}', "not a log probability"),
    (b'{"log_posterior": {"none": NaN}}', "not a log probability"),
])
def test_a_bad_earlier_diagnosis_exits_2_and_writes_nothing(bench, tmp_path, capsys, content, said):
    """``--earlier`` a missing file, binary junk, a JSON document that is no diagnosis' ``gap.json``, a log
    probability above 0 or not a number: one line naming it, exit 2, nothing written."""
    d, (fit, _) = bench
    earlier = tmp_path / "earlier.json"
    if content is not None:
        earlier.write_bytes(content)
    out = tmp_path / "gap"
    rc = main(["diagnose", str(d / "bench.toml"), str(fit), "--out", str(out), "--quiet", "--earlier", str(earlier)])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2 and len(err) == 1 and said in err[0] and str(earlier) in err[0], err
    assert not out.exists()


def test_bad_data_exit_2_and_write_nothing(bench, tmp_path, capsys):
    d, (fit, _) = bench
    text = fit.read_text().splitlines()
    cells = text[50].split(",")
    cells[-1] = "nan"
    text[50] = ",".join(cells)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(text) + "\n")
    out = tmp_path / "gap"
    rc = main(["diagnose", str(d / "bench.toml"), str(bad), "--out", str(out), "--quiet"])
    assert rc == 2
    assert "bad.csv" in capsys.readouterr().err
    assert not out.exists()


def test_non_empty_out_is_refused(bench, tmp_path, capsys):
    d, (fit, _) = bench
    (tmp_path / "keep.txt").write_text("x")
    rc = main(["diagnose", str(d / "bench.toml"), str(fit), "--out", str(tmp_path), "--quiet"])
    assert rc == 2 and "exists and is not empty; choose a new directory" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


def test_demo_quick_runs_the_whole_workflow(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--quiet", "--out", str(out)]) == 0
    text = (out / "report.txt").read_text()
    assert text.startswith("ebb demo: ")                  # a title, not a blank line
    assert "withheld effect: boundary_rotational_left -> diagnosis RIGHT" in text
    assert (out / "diagnosis" / "gap.json").is_file()
    # the identified model (polished knee) is what is exported; the corrected model comes from the diagnosis
    assert sorted(p.name for p in (out / "identify" / "export").iterdir()) == ["polished_0.fmu", "polished_0.npz"]
    assert sorted(p.name for p in (out / "diagnosis" / "corrected").iterdir()) == [
        "corrected.fmu", "corrected.json", "corrected.npz", "corrected.toml"]
    header = next(line for line in text.splitlines() if "identified" in line and "corrected" in line)
    assert header.split() == ["unit", "identified", "corrected", "truth"]
    kr = next(line for line in text.splitlines() if line.startswith("boundary_rotational_left.kr"))
    assert kr.split()[1] == "N.m/rad" and kr.split()[-1] == "300"    # unit, withheld value
    assert "held-out gap ratio (1 = noise floor):" in text and "-> corrected" in text
    _check_pages(out, tmp_path)


def _check_pages(out, tmp_path):
    """The demo's three pages (the demo's, the identification's, the diagnosis') open in a real headless Chromium:
    titled, every figure loaded and its smallest text shown at 10 px or more, nothing failed, the verdict and the
    identified values on them."""
    from browser import render, smallest_text_shown

    from ebb_model.io.figureio import MIN_TEXT_PX

    verdict, identified = "verdict: boundary_rotational_left", "identified model (polished, from "
    pages = {out / "report.html": (["Result", "Identification — Identified model", "Diagnosis — Verdict",
                                    "Diagnosis — Effects", "Diagnosis — Figures", "Identification — Figures"],
                                   [verdict, identified]),
             out / "identify" / "report.html": (["Identified model", "Uncertainty", "Search", "Figures"],
                                                [identified, "rhoA"]),
             out / "diagnosis" / "report.html": (["Verdict", "Baseline (the identifying model without an effect)",
                                                  "Effects", "Corrected model", "Figures"], [verdict])}
    for page, (headings, texts) in pages.items():
        seen = render(page, tmp_path / f"{page.parent.name}.png")
        assert seen.title.startswith("ebb "), seen.title
        assert all(h in seen.headings for h in headings), (page, seen.headings)
        assert seen.images and all(ok and width > 0 for _, ok, width, _ in seen.images), seen.images
        # every figure legible at the page's width: its smallest text as shown, measured (ebb_model.io.figureio)
        shown = smallest_text_shown(page, seen)
        assert all(px >= MIN_TEXT_PX for px in shown.values()), shown
        assert not seen.errors, seen.errors
        assert all(t in seen.text for t in texts), (page, texts)
    # the demo's page shows every figure of both runs
    demo = render(out / "report.html")
    n_figures = len(list((out / "identify").glob("*.png"))) + len(list((out / "diagnosis").rglob("*.png")))
    assert len(demo.images) == n_figures
