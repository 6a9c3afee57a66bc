"""Speed-up of a batch of diagnoses on a Dask LocalCluster (``ebb diagnose … --each --dask local:K``).

Four records of the blind family's displacement bench (``tests/test_diagnosis_blind.py``: no effect, a foundation,
Kelvin–Voigt damping, an actuator lag; generated first, not timed) are diagnosed one task each by
:func:`diagnosis.batch.diagnose_each` on local clusters of 1, 2 and 4 single-threaded workers.  Each wall time
includes starting and closing the cluster (what a user waits for); the speed-up is against one worker, and the
share of the ideal divides it by min(K, cores).  The verdicts are checked against the withheld effects.

Run as ``python benchmarks/bench_diagnose_batch.py [--workers 1 2 4] [--json PATH]``.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import test_diagnosis_blind as blind  # noqa: E402
from ebb_model.reference.withheld import WithheldEffect  # noqa: E402

from diagnosis.batch import diagnose_each  # noqa: E402
from figures import add_json_argument, write_figures  # noqa: E402  benchmarks/figures.py

RECORDS = {"none": None, "foundation": WithheldEffect("foundation", {"kf": 200.0}),
           "kelvin_voigt": WithheldEffect("kelvin_voigt", {"eta": 6e-5}),
           "actuator_lag": WithheldEffect("actuator_lag", {"tau": 5e-4})}


def main() -> None:
    """Generate the records, time the batch on each cluster size, print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2, 4])
    add_json_argument(ap)
    args = ap.parse_args()
    rows = []
    cores = os.cpu_count() or 1
    cfg = blind.bench_config()
    with tempfile.TemporaryDirectory() as tmp:
        files = []
        for name, effect in RECORDS.items():
            d = Path(tmp) / name
            d.mkdir()
            path = blind._write(d, cfg, effect, seed=5 if effect is None else 3)
            files.append(path.rename(Path(tmp) / f"{name}.npz"))
        times = {}
        print(f"{len(files)} records, {cores} cores")
        print(f"{'Dask workers':>12}{'wall [s]':>10}{'speed-up':>10}{'of ideal':>10}  verdicts")
        for k in args.workers:
            t0 = time.perf_counter()
            docs = diagnose_each(cfg, files, Path(tmp) / f"out{k}", dask=f"local:{k}", plots=False, export=False)
            times[k] = time.perf_counter() - t0
            right = [doc["verdict"] == name for name, doc in zip(RECORDS, docs)]
            base = times.get(1, times[args.workers[0]])
            speed = base / times[k]
            print(f"{k:>12}{times[k]:>10.1f}{speed:>10.2f}{speed / min(k, cores):>10.2f}  "
                  f"{sum(right)}/{len(right)} right", flush=True)
            rows.append({"workers": k, "seconds": times[k], "speedup": speed, "of_ideal": speed / min(k, cores),
                         "right": sum(right), "records": len(right)})
    write_figures(args.json, {"cores": cores, "records": len(RECORDS), "rows": rows,
                              **{f"workers_{r['workers']}_s": r["seconds"] for r in rows},
                              **{f"speedup_{r['workers']}": r["speedup"] for r in rows}})


if __name__ == "__main__":
    main()
