"""Growth of one evaluation (assemble for new parameters + simulate) with the model's and the record's size.

One evaluation is what the identification pays per candidate.  Three sweeps from the benchmark case R1 (the seed's
clamped–clamped beam, 50 nodes, dt = 1e-4 s, 1 force), each varying one size with the others at R1's:

* nodes 50 → 800 (2 sensors, 1 s record);
* record length 1 → 60 s (50 nodes, 2 sensors);
* sensors 1 → 16 (50 nodes, 1 s).

Printed: median times (single-threaded BLAS, all in this one run) and the growth exponent of each sweep — the
least-squares slope of log t against log size over its upper half (where the dominant term shows).

Run: ``python benchmarks/bench_growth.py [--repeats R] [--json PATH]``.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

import ebb_model as em

from figures import add_json_argument, write_figures  # benchmarks/figures.py
from timing import median_time  # benchmarks/timing.py

ROOT = Path(__file__).resolve().parents[1]


def config(nodes: int = 50, sensors: int = 2) -> em.BeamConfig:
    """R1 with ``nodes`` interior points and ``sensors`` displacement sensors spread along the beam."""
    d = em.load_config(ROOT / "examples" / "seed_clamped.toml").to_dict()
    d["beam"]["nodes"] = nodes
    L = d["beam"]["length"]
    d["sensors"] = [{"name": f"y{i}", "x": L * (i + 1) / (sensors + 1), "kind": "displacement"}
                    for i in range(sensors)]
    return em.config_from_dict(d)


def evaluation(cfg: em.BeamConfig, u: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    p = {"EI": rng.uniform(8, 12), "rhoA": rng.uniform(0.9, 1.1), "N": rng.uniform(0, 100)}
    return em.simulate(em.fast_model(cfg, p), u).outputs


def exponent(sizes: list[float], times: list[float]) -> float:
    """Slope of log t against log size over the upper half of the sweep."""
    k = len(sizes) // 2
    return float(np.polyfit(np.log(sizes[k:]), np.log(times[k:]), 1)[0])


def sweep(name: str, sizes: list[int], make, repeats: int, rng: np.random.Generator) -> dict:
    """Median evaluation time per size (printed), returned as ``{"sizes", "ms", "exponent"}``."""
    times = []
    for s in sizes:
        cfg, u = make(s)
        evaluation(cfg, u, rng)                       # compile / warm caches
        times.append(median_time(lambda: evaluation(cfg, u, rng), repeats))
    print(f"{name:>14}: " + "  ".join(f"{s}: {1e3 * t:.3g} ms" for s, t in zip(sizes, times))
          + f"   exponent {exponent(sizes, times):.2f}")
    return {"sizes": sizes, "ms": [1e3 * t for t in times], "exponent": exponent(sizes, times)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    add_json_argument(ap)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    fs = 1e4
    with threadpool_limits(limits=1, user_api="blas"):
        nodes = sweep("nodes", [50, 100, 200, 400, 800],
              lambda n: (config(nodes=n), rng.standard_normal((int(fs), 1))), args.repeats, rng)
        record = sweep("record [s]", [1, 4, 15, 60],
              lambda s: (config(), rng.standard_normal((int(s * fs), 1))), max(3, args.repeats // 2), rng)
        sensors = sweep("sensors", [1, 2, 4, 8, 16],
              lambda m: (config(sensors=m), rng.standard_normal((int(fs), 1))), args.repeats, rng)
    write_figures(args.json, {"nodes": nodes, "record_s": record, "sensors": sensors})


if __name__ == "__main__":
    main()
