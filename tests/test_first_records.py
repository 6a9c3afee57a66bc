"""A user's first own record: default ``identify`` finds the global answer from a config written as a newcomer
writes it, on records from the independent truth (``tests/first_records.py``), and says so when it cannot.

Tolerances: the family's criterion (issue 51) — the fit at the noise floor, ≤ 1.5 noise variances per sensor,
EI and ρA within 1 %, N within 2 % of the Euler load scale.  What the truth itself leaves on the model's grid
(the spline force of the generator against the model's cubic hold, the grid's modes above the band) is
measured per case in ``benchmarks/bench_first_records.py``: at most 1.43 noise variances at 80 nodes
(the cantilever's tip accelerometer under the random force), so the 1.5 criterion is reachable on every case and
a search that stops short of the global optimum fails it.
"""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from ebb_model.space.adequacy import DECISIVE_EVIDENCE, GRID_SHIFT, NOISE_FLOOR_EXCESS, at_the_floor
from first_records import BROADBAND, CASES, DECLARED, write_case
from identification.run import identify

ROOT = Path(__file__).resolve().parents[1]


def _identified_at_the_criterion(case, tmp_path):
    """Default ``identify`` on the case's record, checked against the family's criterion (module docstring)."""
    cfg, rec = write_case(case, tmp_path / "bench")
    res = identify(cfg, [rec], tmp_path / "run", progress=False, export=False)
    p, gap = res.identified["parameters"], res.identified["fit_gap_ratio"]
    assert max(gap.values()) <= 1.5, (case.name, gap, p)
    for k in ("EI", "rhoA"):
        assert abs(p[k] / case.truth[k] - 1.0) <= 0.01, (case.name, k, p)
    if "N" in p:
        assert abs(p["N"] - case.truth["N"]) <= 0.02 * case.euler_load, (case.name, p)
    return res


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_first_record_reaches_the_truth(case, tmp_path):
    """No bound reached and no hint but the numerics' measurement: at the noise floor the records may ask for a
    finer grid when they tell it apart by the floor's evidence (:func:`identification.numerics.records_tell_apart`;
    measured on the compressed clamped beam's mixed sensors and the clamped–pinned hammer record: 1.04 → 1.02 and
    1.1 → 1.06 noise variances per sample on 323 nodes, far more than 2 ln 100 in χ² over their records) — a
    measurement of the numerics, not a claim about the records' sign, level or units."""
    res = _identified_at_the_criterion(case, tmp_path)
    ident = res.identified
    hints = ident.get("hints") or []
    assert "on_bounds" not in ident, (case.name, ident)
    assert all(h.startswith("the records ask for finer numerics") for h in hints), (case.name, hints)


@pytest.mark.parametrize("case", BROADBAND, ids=[c.name for c in BROADBAND])
def test_broadband_record_reaches_the_truth(case, tmp_path):
    """What labs record most (a shaker fed broadband noise, one to three sensors; ``tests/first_records.py``) from a
    newcomer's config — 80 nodes, the cubic between samples: default ``identify`` takes the numerics the records
    ask for (:mod:`identification.numerics`) and lands at the family's criterion, saying so in one line and
    nothing else.  On 80 nodes with the cubic the strip's tip accelerometer was left at 409 noise variances and EI
    4 % low; the truth itself is 0.004 noise variances from its own refinement (``elements``).  The grid line
    reads the answer's shift (below)."""
    res = _identified_at_the_criterion(case, tmp_path)
    ident = res.identified
    hints = ident.get("hints") or []
    assert all(h.startswith("the records ask for finer numerics") for h in hints), (case.name, hints)
    # the grid line says what the refined grid does to the answer (identification.grid_shift): on these long,
    # lightly damped records the grid identify takes still moves some unknown by 2-3.4 Cramér–Rao deviations (the
    # line said "adequate" by the outputs' change alone) — "too coarse" where the records prefer the refined grid
    # decisively, "undecided" where not; where it says "too coarse" by twice the deviation (the bias dominates the
    # noise) the shifted value is nearer the truth (the strip, the beam with three sensors)
    shift, line = res.adequacy.shift, res.grid_advice["summary"]
    assert shift is not None, case.name
    moves = shift.largest > GRID_SHIFT
    better_here = (shift.gain < -DECISIVE_EVIDENCE and float(np.max(res.adequacy.change)) > NOISE_FLOOR_EXCESS
                   and at_the_floor(res.adequacy.gap))
    said = ("too coarse" if moves and shift.gain > DECISIVE_EVIDENCE else "these records fit it better" if better_here
            else "undecided" if moves else "adequate")
    assert line.startswith(f"grid: {said}") or line.startswith("grid: too coarse"), (case.name, line, shift)
    i = shift.worst
    name, x = shift.names[i], ident["parameters"][shift.names[i]]
    if said == "too coarse" and abs(shift.deviations[i]) > 2.0 and name in case.truth:
        assert abs(x + shift.step[i] - case.truth[name]) < abs(x - case.truth[name]), (case.name, shift)


@pytest.mark.parametrize("case", DECLARED, ids=[c.name for c in DECLARED])
def test_a_bench_with_declared_parts_reaches_the_truth(case, tmp_path):
    """A declared tip accelerometer's mass, a spring support (``tests/first_records.py``): the family's criterion,
    and no hint but the numerics'.  Before the modes' pattern gave the start its level, the strip ended at EI
    0.86 and ρA 4.0 times the truth, c on its bound, 4,660 noise variances."""
    res = _identified_at_the_criterion(case, tmp_path)
    hints = res.identified.get("hints") or []
    assert all(h.startswith("the records ask for finer numerics") for h in hints), (case.name, hints)


def _model_record(folder: Path, *, scale: float = 1.0) -> tuple[Path, Path]:
    """Issue 51's first record: the project's own model (40 nodes) at EI 7, ρA 0.9, c 0.6 — a clamped–free strip
    of 0.8 m, one tip accelerometer, a shaker at 0.6 m driven by white noise, 1 kHz, 4 s, 2 % noise — and the
    config the user wrote (EI 10 in 2–20, ρA 1.2 in 0.3–3, c 1.0 in 0.05–5); ``scale`` multiplies the record
    (1000: read in mm as if in m)."""
    from ebb_model import fast_model, simulate
    from ebb_model.config import config_from_dict
    from ebb_model.io.tomlio import dumps

    d = {"beam": {"length": 0.8, "nodes": 40, "left": "clamped", "right": "free"}, "time": {"dt": 1e-3},
         "parameters": {"EI": {"value": 10.0, "bounds": [2.0, 20.0], "identify": True},
                        "rhoA": {"value": 1.2, "bounds": [0.3, 3.0], "identify": True},
                        "c": {"value": 1.0, "bounds": [0.05, 5.0], "identify": True},
                        "eta": {"value": 0.0}, "N": {"value": 0.0}},
         "actuators": [{"name": "F1", "x": 0.6}], "sensors": [{"name": "a1", "x": 0.8, "kind": "acceleration"}]}
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "config.toml").write_text(dumps(d), encoding="utf-8")
    rng = np.random.default_rng(0)
    u = rng.standard_normal(4000)
    y = simulate(fast_model(config_from_dict(d), {"EI": 7.0, "rhoA": 0.9, "c": 0.6}), u[:, None]).outputs[:, 0]
    y = (y + 0.02 * np.std(y) * rng.standard_normal(y.size)) * scale
    np.savetxt(folder / "record.csv", np.column_stack([np.arange(4000) * 1e-3, u, y]), delimiter=",",
               header="time,F1,a1", comments="")
    return folder / "config.toml", folder / "record.csv"


def test_issue_case_lands_on_the_truth(tmp_path):
    """The record of issue 51 (EI, ρA 78 % off with exit 0 before the records' start): the truth within four
    Cramér–Rao standard deviations, the fit at the floor."""
    cfg, rec = _model_record(tmp_path / "bench")
    res = identify(cfg, [rec], tmp_path / "run", progress=False, export=False)
    ident = res.identified
    for k, v in {"EI": 7.0, "rhoA": 0.9, "c": 0.6}.items():
        assert abs(ident["parameters"][k] - v) <= 4 * ident["cramer_rao_std"][k], (k, ident)
    assert ident["fit_gap_ratio"]["a1"] <= 1.1
    doc = json.loads((tmp_path / "run" / "pareto.json").read_text())
    assert doc["data_start"]["modes_hz"] and doc["data_start"]["parameters"]


def test_a_record_in_mm_gets_the_scale_hint(tmp_path):
    """The same record read in mm as if in m: the level is out of the bounds' reach; the run says which scale the
    records ask for, and flags what ended on a bound."""
    cfg, rec = _model_record(tmp_path / "bench", scale=1000.0)
    res = identify(cfg, [rec], tmp_path / "run", progress=False, export=False)
    ident = res.identified
    import re

    level = [h for h in ident["hints"] if h.startswith("the records' level asks for")]
    assert len(level) == 1 and "units" in level[0], ident["hints"]
    # the level asked for is the truth's in mm: EI 7e-3, rhoA 9e-4 (the start's level, within 5 %)
    asked = dict((k, float(v)) for k, v in re.findall(r"(EI|rhoA) ([0-9.e+-]+)", level[0])[:2])
    assert abs(asked["EI"] / 7e-3 - 1) < 0.05 and abs(asked["rhoA"] / 9e-4 - 1) < 0.05, level
    # the gain that would bring the fit down is named, and rhoA is flagged on the bound that stopped it
    assert any("gain of" in h and "a1" in h for h in ident["hints"]), ident["hints"]
    assert ident["on_bounds"]["rhoA"] == {"bound": "lower", "value": 0.3}, ident


def test_scripted_run_without_a_main_guard(tmp_path):
    """A page's snippet saved as a script and run: identify on worker processes from the script's top level,
    no ``if __name__ == "__main__":`` — runs once, no BrokenProcessPool."""
    cfg, rec = _model_record(tmp_path / "bench")
    script = tmp_path / "snippet.py"
    script.write_text(textwrap.dedent(f"""
        from identification.run import identify
        print("top level ran")
        res = identify({str(cfg)!r}, [{str(rec)!r}], {str(tmp_path / 'run')!r}, progress=False, workers=2,
                       pop=8, generations=2, export=False)
        print("identified", sorted(res.identified["parameters"]))
    """), encoding="utf-8")
    out = subprocess.run([sys.executable, str(script)], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.count("top level ran") == 1, out.stdout
    assert "identified ['EI', 'c', 'rhoA']" in out.stdout


def test_one_grid_advice_and_it_delivers(tmp_path):
    """The issue's record: ``identify``, ``diagnose`` with its result and ``diagnose`` alone give the same grid
    advice, and the grid advised resolves what it promises — every listed mode within 5 % of its half-power
    bandwidth of the analytic clamped–free beam (independent of the model and of the advice's own reference).
    Either way the diagnosis sees a record its baseline explains and says ``none`` (alone, the fit from the config's
    values stops at a gap the grid was blamed for — 67 % of it —; the records' own start reaches the floor, so the
    baseline is that fit and there is no gap to diagnose)."""
    from dataclasses import replace

    from diagnosis.run import diagnose
    from ebb_model.space.grid_advice import BANDWIDTH_FRACTION
    from ebb_model.modal.modal import discrete_frequencies
    from ebb_model.reference.analytic import analytic_frequencies_hz

    cfg, rec = _model_record(tmp_path / "bench")
    res = identify(cfg, [rec], tmp_path / "run", progress=False, export=False)
    with_result = diagnose(cfg, [rec], tmp_path / "gap1", result=res, progress=None)
    alone = diagnose(cfg, [rec], tmp_path / "gap2", progress=None)
    advised = res.grid_advice
    assert advised is not None and advised["nodes_needed"] is not None
    for d in (with_result, alone):
        grid = d.document["baseline"]["grid_advice"]
        assert grid["nodes_needed"] == advised["nodes_needed"], (grid, advised)
    # a record the model explains: no gap, whichever start the baseline had
    for d in (with_result, alone):
        assert d.verdict == "none", d.document["reason"]
    # the advice delivers: the advised grid's modes against the closed form, in half-power bandwidths
    p = res.identified["parameters"]
    c = res.config
    fine = replace(c, beam=replace(c.beam, nodes=advised["nodes_needed"]))
    k = len(advised["frequencies_hz"])
    f, z = discrete_frequencies(fine, {**c.parameter_values(), **p}, k)
    exact = analytic_frequencies_hz("clamped", "free", length=0.8, EI=p["EI"], rhoA=p["rhoA"], N=0.0, n_modes=k)
    err = np.abs(f - exact) / (2 * np.maximum(z, 1e-3) * exact)
    assert np.all(err <= BANDWIDTH_FRACTION), err


@pytest.mark.parametrize("name", ["pinned-tension-velocity-chirp", "clamped-compression-mixed-random"])
def test_more_effort_never_gives_a_worse_answer(name, tmp_path):
    """A longer GA (three times the generations), a larger population (twice) or another seed reaches at least the
    default's fit: every stage's best point is polished and the best polished one is the answer (the χ² of the
    same optimum agrees to 1e-3 of a noise variance between runs: the polish's stopping tolerance)."""
    case = {c.name: c for c in CASES}[name]
    cfg, rec = write_case(case, tmp_path / "bench")

    def worst_gap(tag: str, **options) -> float:
        res = identify(cfg, [rec], tmp_path / tag, progress=False, export=False, **options)
        return max(res.identified["fit_gap_ratio"].values())

    default = worst_gap("default")
    assert default <= 1.5
    for tag, options in (("longer", {"generations": 90}), ("larger", {"pop": 80}), ("seed", {"seed": 7})):
        gap = worst_gap(tag, **options)
        assert gap <= default + 1e-3, (tag, gap, default)


@pytest.mark.parametrize("record", [54, 17])
def test_the_answer_is_where_the_polish_settles(record, tmp_path):
    """On a record the model does not describe the local fit can stop short: the hint family's h54 (an undeclared
    10-sample delay) ended on ``xtol`` where one more polish lowered χ² by 3,490 noise variances and moved the answer
    21 Cramér–Rao deviations; h17 (a withheld rotational spring at the clamp) by 6,040 and 41.  The answer is now where
    polishing it again gains less than the polish's own resolution (:data:`identification.polish.CHI2_RESOLUTION`
    residual variances) — measured under the noise model ``identify`` reports, estimated at the answer."""
    from hint_family import hint_bench, write_hint_case
    from identification.native import NativeEvaluator
    from identification.polish import CHI2_RESOLUTION, ResidualEvaluator, polish
    from identification.run import _arrays, read_data

    case = hint_bench(record, elements=128)
    assert case.kind != "correct"
    cfg, rec = write_hint_case(case, tmp_path / "bench")
    res = identify(cfg, [rec], tmp_path / "run", progress=False, export=False)
    ev = NativeEvaluator(res.config, res.space, _arrays(res.config, read_data(res.config, [rec])))
    x = res.polished[0].x
    cost = float(np.sum(ResidualEvaluator(ev, res.noise).residuals(x) ** 2))
    again = polish(ev, x, noise=res.noise, max_evaluations=400)
    n = sum(e.outputs.size for e in ev.experiments) - ev.space.dim
    assert cost - again.cost <= CHI2_RESOLUTION * cost / n, (cost, again.cost)


def test_a_fit_at_the_floor_on_coarse_numerics_takes_the_finer(tmp_path):
    """A cantilever's accelerometer near the clamp under noise to 0.2 fs (the hint family's first-draw record 48, its
    truth on 128 elements), from the newcomer's 80-node config with the cubic: the fit ended at 1.13 noise variances
    with EI and ρA 1.26 % high — six Cramér–Rao deviations, the parameters taking up the numerics' error where each
    finer numerics alone fits no better (1.2, 1.18) — because the refinements were not tried at the floor.  Both at once
    are kept (decisively better: :data:`identification.numerics.FLOOR_EVIDENCE`) and the truth is within 1 %."""
    from hint_family import first_draw, write_hint_case

    case = first_draw(48, elements=128)
    assert case.kind == "correct"
    cfg, rec = write_hint_case(case, tmp_path / "bench")
    res = identify(cfg, [rec], tmp_path / "run", progress=False, export=False)
    ident = res.identified
    p, gap = ident["parameters"], ident["fit_gap_ratio"]
    assert max(gap.values()) <= 1.5, gap
    for k in ("EI", "rhoA"):
        assert abs(p[k] / case.bench.truth[k] - 1.0) <= 0.01, (k, p)
    assert any(h.startswith("the records ask for finer numerics: with the band-limited force between samples and a "
                            "finer grid") for h in ident["hints"]), ident["hints"]
