"""Benchmark: default ``identify`` on the family of "first own records" — time, accuracy, and the truth's floor.

The family (``tests/first_records.py``): nine benches — a cantilever, pinned–pinned under tension,
clamped–clamped under compression, clamped–pinned; one accelerometer, velocity or displacement sensor, or two
of mixed kinds; random, chirp, multisine and hammer excitation; 1–5 % noise — recorded from the independent
truth (Hermite FE integrated exactly in time), each with the config a newcomer writes (nominal values 30–60 %
off, bounds ×0.25…×4).  Each run is :func:`identification.run.identify` with its defaults (in the calling
process, as ``ebb identify`` without ``--workers``), and again on ``--workers`` local processes (default 2: the
same candidates, plus the workers' start and the chunks' transfer).  Printed per case: the wall times, EI's and
ρA's errors, N's error over the Euler load scale ``EI π²/L²``, the fit residual in noise variances, and the
*floor*: what the truth's own parameters leave on the
config's grid (the generator's spline force against the model's cubic hold, the grid's modes above the band) —
the criterion of the test, ≤ 1.5 noise variances, is reachable where the floor is below it.  Targets: every case
at the floor with EI and ρA within 1 % and N within 2 %; median time (defaults) ≤ 3 s.

Usage: ``python benchmarks/bench_first_records.py [--workers 2] [--cases NAME ...]``.
"""
from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from first_records import CASES, FirstRecord, write_case  # noqa: E402  (tests/first_records.py)
from identification.native import NativeEvaluator  # noqa: E402
from identification.run import _arrays, identify, load_identification_config, read_data  # noqa: E402
from identification.parameters import parameter_space  # noqa: E402
from ebb_model.threads import one_blas_thread  # noqa: E402

from figures import add_json_argument, write_figures  # noqa: E402  (benchmarks/figures.py)


@one_blas_thread
def floor(case: FirstRecord, cfg_path: Path, rec_path: Path) -> float:
    """The truth's parameters on the config's model: the largest residual per sensor in noise variances (the
    generator's noise: ``noise ×`` each sensor's clean RMS).  With one BLAS thread, as ``identify`` computes:
    the modes it caches would otherwise differ in round-off (multi-threaded ``eigh``) from those the
    identification's workers compute, and the two runs' values by ~1e-10."""
    cfg = load_identification_config(cfg_path)
    exps = read_data(cfg, [rec_path])
    space = parameter_space(cfg)
    ev = NativeEvaluator(cfg, space, _arrays(cfg, exps), stabilising=False)
    y = ev.simulate(np.array([case.truth[k] for k in space.names])).outputs[0]
    clean_rms = np.sqrt(np.mean(y ** 2, axis=0))
    return float(np.max(np.mean((y - exps[0].outputs) ** 2, axis=0) / (case.noise * clean_rms) ** 2))


def run(case: FirstRecord, workers: int, work: Path) -> dict:
    """One case: record, floor, identification with defaults, and on ``workers`` processes; times and errors."""
    cfg, rec = write_case(case, work / case.name)
    fl = floor(case, cfg, rec)
    t0 = time.perf_counter()
    res = identify(cfg, [rec], work / case.name / "run", progress=False, export=False)
    total = time.perf_counter() - t0
    t0 = time.perf_counter()
    parallel = identify(cfg, [rec], work / case.name / "parallel", progress=False, export=False, workers=workers)
    total_parallel = time.perf_counter() - t0
    p1, p2 = res.identified["parameters"], parallel.identified["parameters"]
    apart = max(abs(p2[k] / p1[k] - 1.0) for k in p1)
    if apart:
        print(f"{case.name}: on {workers} workers the values differ by up to {apart:.1e} (relative)")
    ident = res.identified
    p = ident["parameters"]
    errs = {k: 100.0 * (p[k] / case.truth[k] - 1.0) for k in ("EI", "rhoA")}
    if "N" in p:
        errs["N"] = 100.0 * (p["N"] - case.truth["N"]) / case.euler_load
    gap = max(ident["fit_gap_ratio"].values())
    ok = gap <= 1.5 and abs(errs["EI"]) <= 1 and abs(errs["rhoA"]) <= 1 and abs(errs.get("N", 0.0)) <= 2
    return dict(case=case.name, total=total, total_parallel=total_parallel, errors=errs, gap=gap, floor=fl, ok=ok,
                source=ident["from"], parallel_apart=apart)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--cases", nargs="*", default=None)
    add_json_argument(ap)
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp())
    rows = []
    try:
        for case in CASES:
            if args.cases and case.name not in args.cases:
                continue
            r = run(case, args.workers, work)
            rows.append(r)
            errors = ", ".join(f"{k} {e:+.3f} %" for k, e in r["errors"].items())
            print(f"{r['case']:<44} {r['total']:5.1f} s ({r['total_parallel']:4.1f} s on {args.workers})  {errors}"
                  + f";  fit {r['gap']:.2f} (floor {r['floor']:.2f}) noise variances;  "
                  + ("right" if r["ok"] else "WRONG") + f"  ({r['source']})", flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    right = sum(r["ok"] for r in rows)
    med = statistics.median(r["total"] for r in rows)
    med_parallel = statistics.median(r["total_parallel"] for r in rows)
    print(f"{right} of {len(rows)} right; median {med:.1f} s, largest {max(r['total'] for r in rows):.1f} s "
          f"(defaults: the calling process; target: median <= 3 s); on {args.workers} workers median "
          f"{med_parallel:.1f} s; largest floor {max(r['floor'] for r in rows):.2f}")
    write_figures(args.json, {"cases": len(rows), "right": right, "median_s": med,
                              "largest_s": max(r["total"] for r in rows), "workers": args.workers,
                              "median_parallel_s": med_parallel,
                              "largest_parallel_s": max(r["total_parallel"] for r in rows),
                              "parallel_apart": max(r["parallel_apart"] for r in rows),
                              "largest_floor": max(r["floor"] for r in rows),
                              "largest_gap": max(r["gap"] for r in rows),
                              "largest_error_percent": max(abs(e) for r in rows for e in r["errors"].values()),
                              "rows": rows})


if __name__ == "__main__":
    main()
