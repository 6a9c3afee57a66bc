"""Benchmark: the hints a full default ``identify`` prints on records where every sign, level and units hint is false.

The family (``tests/hint_family.py``): broadband records of random benches — a quarter each correct, with a withheld
effect (a point mass, a crack, a compliant clamp, an intermediate spring), with an undeclared delay and with an
undeclared anti-alias filter on the sensor channels — every one read with its true sign and in its true units, the
truth inside the newcomer's bounds.  Each record through :func:`identification.run.identify` with its defaults (the
calling process, as ``ebb identify``).  Counted per record: every hint line of the result (``identified.hints``;
the numerics' own line — "the records ask for finer numerics", a measurement — apart), each of them false here;
for the correct quarter also whether the fit is at the family's criterion (≤ 1.5 noise variances, EI and ρA within
1 %, N within 2 % of the Euler load).  Printed: the false-hint rate with its binomial 95 % upper bound (none of
``n``: ``1 − 0.05^(1/n)``), the correct records' accuracy, the time per record.

The truths here have 128 elements, so that the correct records' accuracy is the identification's, not the
truth's (``tests/test_hint_rates.py`` takes 64: a hint on these records is false whatever the truth's
convergence).  ``tests/test_hint_rates.py`` asserts the same rate at the end of a successful search (from the truth's
parameters), cheaper; this benchmark is the whole run, the search's own misses included.

The grid's two lines are claims too ("grid: adequate / too coarse / these records fit it better", and "refine
[beam] nodes before blaming physics"): each record's are checked against refits on the model's grid and on a finer
one from the identified point (``tests/grid_truth.py``: what counts as false, and the borderline truths where
nothing does).

Usage: ``python benchmarks/bench_hint_rates.py [--records 64]``.
"""
from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from hint_family import hint_bench, write_hint_case  # noqa: E402  (tests/hint_family.py)
from grid_truth import false_grid_claims, grid_claims, grid_truth  # noqa: E402  (tests/grid_truth.py)
from identification.native import NativeEvaluator  # noqa: E402
from identification.run import _arrays, identify, read_data  # noqa: E402

from figures import add_json_argument, write_figures  # noqa: E402  (benchmarks/figures.py)

#: The truth's elements: a correct record within the noise of the model (``tests/hint_family.py``).
ELEMENTS = 128
#: The numerics' line is a measurement of the numerics, not a claim about the records' sign, level or units.
NUMERICS = "the records ask for finer numerics"


def run(i: int, work: Path) -> dict:
    """Record ``i`` of the family: default ``identify``, its hints, its accuracy, its time."""
    case = hint_bench(i, elements=ELEMENTS)
    b = case.bench
    cfg, rec = write_hint_case(case, work / str(i))
    t0 = time.perf_counter()
    res = identify(cfg, [rec], work / str(i) / "run", progress=False, export=False)
    seconds = time.perf_counter() - t0
    ident = res.identified
    hints = [h for h in ident.get("hints") or () if not h.startswith(NUMERICS)]
    p = ident["parameters"]
    errs = {k: 100.0 * (p[k] / b.truth[k] - 1.0) for k in ("EI", "rhoA")}
    if "N" in p:
        errs["N"] = 100.0 * (p["N"] - b.truth["N"]) / b.euler_load
    gap = max((ident.get("fit_gap_ratio") or {"-": float("inf")}).values())
    right = gap <= 1.5 and abs(errs["EI"]) <= 1 and abs(errs["rhoA"]) <= 1 and abs(errs.get("N", 0.0)) <= 2
    claim, refine = grid_claims(res.grid_advice["summary"], res.adequacy.summary())
    evaluator = NativeEvaluator(res.config, res.space, _arrays(res.config, read_data(res.config, [rec])))
    x = res.polished[0].x if res.polished else res.pareto.X[res.pareto.knee]
    truth = grid_truth(evaluator, x, res.noise, res.adequacy.shift)
    return dict(record=case.name, kind=case.kind, seconds=seconds, gap=gap, hints=len(hints), first_hint=hints[:1],
                right=right, worst_error_percent=max(abs(e) for e in errs.values()), grid=claim, refine=refine,
                grid_truth=truth, grid_false=false_grid_claims(claim, refine, truth))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=64)
    add_json_argument(ap)
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp())
    rows = []
    try:
        for i in range(args.records):
            r = run(i, work)
            rows.append(r)
            print(f"{r['record']:<44} {r['seconds']:5.1f} s  fit {r['gap']:9.3g}  "
                  + ("" if r["kind"] != "correct" else ("right  " if r["right"] else "WRONG  "))
                  + f"grid {r['grid']}{' +refine' if r['refine'] else ''} (answer {r['grid_truth']['moves']:.2g} sd, "
                  f"outputs {r['grid_truth']['change']:.2g}: {r['grid_truth']['truth']})  "
                  + (f"FALSE: {', '.join(r['grid_false'])}  " if r["grid_false"] else "")
                  + (f"HINT: {r['first_hint'][0]}" if r["hints"] else ""), flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    n = len(rows)
    fired = sum(r["hints"] > 0 for r in rows)
    bound = 1.0 - 0.05 ** (1.0 / n) if fired == 0 else None
    correct = [r for r in rows if r["kind"] == "correct"]
    right = sum(r["right"] for r in correct)
    med = statistics.median(r["seconds"] for r in rows)
    grid_false = sum(bool(r["grid_false"]) for r in rows)
    claims = {k: sum(r["grid"] == k for r in rows) for k in ("adequate", "undecided", "fit_better", "too_coarse")}
    borderline = sum(r["grid_truth"]["truth"] == "borderline" for r in rows)
    grid_bound = 1.0 - 0.05 ** (1.0 / n) if grid_false == 0 else None
    print(f"false sign/level/units hints on {fired} of {n} records ("
          + (f"95 % upper bound {100 * bound:.1f} %" if bound is not None else f"{100 * fired / n:.1f} %")
          + f"); correct records at the criterion: {right} of {len(correct)}; median {med:.1f} s, "
          f"largest {max(r['seconds'] for r in rows):.1f} s")
    print(f"grid claims {claims}, refine on {sum(r['refine'] for r in rows)}; false on {grid_false} of {n} records "
          f"(the truth borderline on {borderline})")
    write_figures(args.json, {"records": n, "fired": fired, "rate_percent": 100.0 * fired / n,
                              "upper_bound_percent": None if bound is None else 100.0 * bound,
                              "correct": len(correct), "correct_right": right, "median_s": med,
                              "largest_s": max(r["seconds"] for r in rows), "grid_claims": claims,
                              "grid_refine": sum(r["refine"] for r in rows), "grid_false": grid_false,
                              "grid_borderline": borderline,
                              "grid_upper_bound_percent": None if grid_bound is None else 100.0 * grid_bound,
                              "wrong": [r["record"] for r in correct if not r["right"]], "rows": rows})


if __name__ == "__main__":
    main()
