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
[beam] nodes before blaming physics"), made from one Gauss–Newton step on the line's refined grid.  Checked here
against refits (:func:`identification.polish.polish`, bounded, nonlinear) on the model's grid and on a finer one
(``2n + 1`` nodes, at least :data:`FINE` — finer than the line's own for the config's 80; on grids of 1,295 nodes
and more the eigen-solver's round-off moves a correct record's answer by deviations), both from the identified
point: the answer moves by ``max |x_fine − x| / σ`` (the deviations the line quotes) and the outputs by
``mean((y_fine − y)²) / σ_noise²`` (the line's noise level).  The grid *matters* when the answer moves by more than
twice :data:`~ebb_model.space.adequacy.GRID_SHIFT` or the outputs by twice
:data:`~ebb_model.space.adequacy.NOISE_FLOOR_EXCESS`, does *not* when both stay below half of them; between, the
truth is borderline and no claim is counted false.  False: "adequate" where it matters, "too coarse" or "refine"
where it does not, "fit it better" where the finer grid's refit does not raise χ² decisively; "undecided" claims
nothing.

Usage: ``python benchmarks/bench_hint_rates.py [--records 64]``.
"""
from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from hint_family import hint_bench, write_hint_case  # noqa: E402  (tests/hint_family.py)
from ebb_model.space.adequacy import DECISIVE_EVIDENCE, GRID_SHIFT, NOISE_FLOOR_EXCESS  # noqa: E402
from identification.native import NativeEvaluator  # noqa: E402
from identification.polish import ResidualEvaluator, polish  # noqa: E402
from identification.run import _arrays, identify, read_data  # noqa: E402

from figures import add_json_argument, write_figures  # noqa: E402  (benchmarks/figures.py)

#: The truth's elements: a correct record within the noise of the model (``tests/hint_family.py``).
ELEMENTS = 128
#: The numerics' line is a measurement of the numerics, not a claim about the records' sign, level or units.
NUMERICS = "the records ask for finer numerics"
#: The finest grid's least number of nodes in the check of the grid's claims (module docstring).
FINE = 647


def grid_claims(res) -> tuple[str, bool]:
    """The grid line's claim (``adequate``, ``undecided``, ``fit better``, ``too coarse``) and whether the
    numerical-share line says to refine the grid."""
    line = res.grid_advice["summary"]
    kind = next(k for k, text in (("adequate", "grid: adequate"), ("undecided", "grid: undecided"),
                                  ("fit better", "grid: these records fit it better"),
                                  ("too coarse", "grid: too coarse")) if line.startswith(text))
    return kind, "before blaming physics" in res.adequacy.summary()


def grid_truth(res, rec: Path) -> dict:
    """What the grid does to the answer, by refits on the model's grid and on a finer one (module docstring)."""
    cfg, space, noise = res.config, res.space, res.noise
    x = res.polished[0].x if res.polished else res.pareto.X[res.pareto.knee]
    exps = _arrays(cfg, read_data(cfg, [rec]))
    fine_cfg = replace(cfg, beam=replace(cfg.beam, nodes=max(2 * cfg.beam.nodes + 1, FINE)))
    here, fine = (NativeEvaluator(c, space, exps, stabilising=False) for c in (cfg, fine_cfg))
    a, b = (polish(ev, x, noise=noise, max_evaluations=300).x for ev in (here, fine))
    shift = res.adequacy.shift
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma = None if shift is None else np.abs(shift.step / shift.deviations)
    moves = 0.0 if sigma is None else float(np.nanmax(np.abs(b - a) / sigma, initial=0.0))
    white = np.median(noise.std, axis=0) ** 2
    ya, yb = here.simulate(a).outputs, fine.simulate(b).outputs
    change = float(max(np.max(np.mean((q - p) ** 2, axis=0) / white) for p, q in zip(ya, yb)))
    chi2 = [float(np.sum(ResidualEvaluator(ev, noise).residuals(v) ** 2)) for ev, v in ((here, a), (fine, b))]
    matters = moves > 2 * GRID_SHIFT or change > 2 * NOISE_FLOOR_EXCESS
    not_at_all = moves < GRID_SHIFT / 2 and change < NOISE_FLOOR_EXCESS / 2
    return dict(fine_nodes=fine_cfg.beam.nodes, moves=moves, change=change, raises=chi2[1] - chi2[0],
                truth="matters" if matters else ("does not" if not_at_all else "borderline"))


def false_grid_claims(kind: str, refine: bool, truth: dict) -> list[str]:
    """The grid's claims on a record that its refits contradict (module docstring)."""
    wrong = {"adequate": truth["truth"] == "matters", "too coarse": truth["truth"] == "does not",
             "fit better": truth["raises"] < DECISIVE_EVIDENCE, "undecided": False}[kind]
    return ([f"grid: {kind}"] if wrong else []) + (["refine"] if refine and truth["truth"] == "does not" else [])


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
    claim, refine = grid_claims(res)
    truth = grid_truth(res, rec)
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
    claims = {k: sum(r["grid"] == k for r in rows) for k in ("adequate", "undecided", "fit better", "too coarse")}
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
