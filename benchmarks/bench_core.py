"""Benchmark of the model core (issue: fast simulation).

Reference case R1: 50 interior nodes (clamped–clamped seed case), 20,000 samples,
1 force, 2 sensors.  One *evaluation* = assemble the model for a new parameter
set + simulate it — what the identification does per candidate.

Printed (medians over repeats, all measured in this one run):

* fast path (modal realisation + compiled recursion), split into assembly and simulation;
* ``scipy.signal.dlsim`` on the same (Φ, Γ, C, D) (assembly excluded — only its simulation);
* the ratio dlsim / fast;
* growth exponents when the number of samples doubles and when the number of nodes doubles:
  ``log2(t(2x) / t(x))``.

Run: ``python benchmarks/bench_core.py [--repeats R]``.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import scipy.signal as ss
from threadpoolctl import threadpool_limits

import ebb_model as em

from timing import median_time  # benchmarks/timing.py

ROOT = Path(__file__).resolve().parents[1]


def config(nodes: int) -> em.BeamConfig:
    d = em.load_config(ROOT / "examples" / "seed_clamped.toml").to_dict()
    d["beam"]["nodes"] = nodes
    return em.config_from_dict(d)


def evaluation(cfg: em.BeamConfig, u: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    p = {"EI": rng.uniform(8, 12), "rhoA": rng.uniform(0.9, 1.1), "N": rng.uniform(0, 100)}
    return em.simulate(em.fast_model(cfg, p), u).outputs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=31)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    with threadpool_limits(limits=1, user_api="blas"):
        cfg = config(50)
        u = rng.standard_normal((20_000, 1))
        evaluation(cfg, u, rng)  # compile / warm caches
        t_fast = median_time(lambda: evaluation(cfg, u, rng), args.repeats)
        t_asm = median_time(lambda: em.fast_model(cfg, {"EI": rng.uniform(8, 12)}), args.repeats)
        fm = em.fast_model(cfg)
        t_sim = median_time(lambda: em.simulate(fm, u), args.repeats)
        sys = em.assemble(cfg)
        t_dlsim = median_time(lambda: ss.dlsim((sys.A, sys.B, sys.C, sys.D, sys.dt), u),
                              max(5, args.repeats // 4))
        y_fast = em.simulate(fm, u).outputs
        _, y_dl, _ = ss.dlsim((sys.A, sys.B, sys.C, sys.D, sys.dt), u)
        rel = np.linalg.norm(y_fast - y_dl) / np.linalg.norm(y_dl)

        u2 = rng.standard_normal((40_000, 1))
        t_fast_2s = median_time(lambda: evaluation(cfg, u2, rng), args.repeats)
        cfg2 = config(100)
        evaluation(cfg2, u, rng)
        t_fast_2n = median_time(lambda: evaluation(cfg2, u, rng), args.repeats)

    print("R1: 50 interior nodes, 20,000 samples, 1 force, 2 sensors (medians)")
    print(f"  fast evaluation (assemble + simulate): {t_fast * 1e3:8.3f} ms")
    print(f"    of which assembly (modal form):      {t_asm * 1e3:8.3f} ms")
    print(f"    of which compiled modal recursion:   {t_sim * 1e3:8.3f} ms")
    print(f"  scipy.signal.dlsim, same matrices:     {t_dlsim * 1e3:8.3f} ms")
    print(f"  ratio dlsim / fast evaluation:         {t_dlsim / t_fast:8.1f} x   (target >= 40)")
    print(f"  relative difference fast vs dlsim:     {rel:8.2e}")
    print(f"  samples x2 (40,000): {t_fast_2s * 1e3:8.3f} ms -> growth exponent "
          f"{math.log2(t_fast_2s / t_fast):.2f} (target <= 1.1)")
    print(f"  nodes x2 (100):      {t_fast_2n * 1e3:8.3f} ms -> growth exponent "
          f"{math.log2(t_fast_2n / t_fast):.2f} (target <= 1.5)")


if __name__ == "__main__":
    main()
