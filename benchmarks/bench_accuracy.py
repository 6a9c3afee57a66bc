"""Benchmark of model accuracy and cost: the exact scheme against the seed's θ-scheme, in one run.

Record (the model-accuracy issue's case): clamped–pinned steel strip 0.8 m × 40 × 4 mm under 300 N tension,
viscous + Kelvin–Voigt damping (ζ 0.4–1.6 % in band), one force, two accelerometers, 4 kHz, 5–300 Hz
multisine, 1 s, 1 % noise.  Truth: Hermite FE (96 elements) integrated exactly in time on 16 sub-steps per
sample under a cubic spline through the force samples; its own convergence (48 elements, 8 sub-steps) is
printed first.

Printed:

* residual at the true parameters, mean squared error per sensor in noise variances (target <= 1.5 with
  the defaults), for the exact scheme and the θ-scheme at several grids and sub-steps;
* cost of one evaluation (assemble + simulate 20,000 samples) of benchmark case R1 (seed config, 50 nodes)
  with each scheme, medians, and their ratio (target <= 3).

Run: ``python benchmarks/bench_accuracy.py [--repeats R]``.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

import ebb_model as em
from ebb_model.reference.exact_fe import exact_fe_response
from ebb_model.reference.excitation import band_limited_input
from ebb_model.reference.hermite_fe import hermite_beam

from timing import median_time  # benchmarks/timing.py

ROOT = Path(__file__).resolve().parents[1]
L, DT = 0.8, 1 / 4000
PARAMS = dict(EI=210e9 * 0.04 * 0.004 ** 3 / 12, rhoA=7850 * 0.04 * 0.004, c=4.0, eta=5e-6, N=300.0)
ACTUATOR, SENSORS = 0.44, ((0.24, "acceleration"), (0.6, "acceleration"))


def config(nodes: int, scheme: str, substeps: int = 1) -> em.BeamConfig:
    return em.config_from_dict({
        "beam": {"length": L, "nodes": nodes, "left": "clamped", "right": "pinned"},
        "time": {"dt": DT, "scheme": scheme, "substeps": substeps},
        "parameters": {k: {"value": v} for k, v in PARAMS.items()},
        "actuators": [{"name": "F1", "x": ACTUATOR}],
        "sensors": [{"name": f"a{i}", "x": x, "kind": k} for i, (x, k) in enumerate(SENSORS)],
    })


def truth(u: np.ndarray, n_elements: int, substeps: int) -> np.ndarray:
    beam = hermite_beam(L, n_elements, left=(np.inf, np.inf), right=(np.inf, 0.0), **PARAMS)
    return exact_fe_response(beam, u, DT, [ACTUATOR], SENSORS, substeps=substeps)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=21)
    args = ap.parse_args()
    with threadpool_limits(limits=1, user_api="blas"):
        u = band_limited_input(4000, DT, 5.0, 300.0, seed=4)
        y = truth(u, 96, 16)
        noise_var = (0.01 * y.std(axis=0)) ** 2

        def res(yy: np.ndarray) -> str:
            return " / ".join(f"{v:9.3f}" for v in np.mean((yy - y) ** 2, axis=0) / noise_var)

        print("Truth convergence (noise variances): 48 elements", res(truth(u, 48, 16)),
              "| 8 sub-steps", res(truth(u, 96, 8)))
        print("Residual at the true parameters, noise variances per accelerometer (target <= 1.5):")
        for nodes in (30, 60, 120, 240):
            print(f"  exact  {nodes:4d} nodes              {res(em.simulate(em.fast_model(config(nodes, 'exact')), u).outputs)}")
            for sub in (1, 4, 16):
                y_t = em.simulate(em.fast_model(config(nodes, "theta", sub)), u).outputs
                print(f"  theta  {nodes:4d} nodes, {sub:2d} sub-steps {res(y_t)}")
        seed = em.load_config(ROOT / "examples" / "seed_clamped.toml")
        d = seed.to_dict()
        d["time"]["scheme"] = "theta"
        seed_theta = em.config_from_dict(d)
        d["time"]["scheme"] = "exact"
        seed_exact = em.config_from_dict(d)
        u1 = np.random.default_rng(0).standard_normal((20000, 1))
        for c in (seed_theta, seed_exact):
            em.simulate(em.fast_model(c), u1)               # compile and warm up
        t_theta = median_time(lambda: em.simulate(em.fast_model(seed_theta), u1), args.repeats)
        t_exact = median_time(lambda: em.simulate(em.fast_model(seed_exact), u1), args.repeats)
    print(f"R1 evaluation (assemble + simulate 20,000 samples), medians of {args.repeats}:")
    print(f"  theta scheme: {t_theta * 1e3:7.3f} ms")
    print(f"  exact scheme: {t_exact * 1e3:7.3f} ms")
    print(f"  ratio exact / theta: {t_exact / t_theta:5.2f} x   (target <= 3)")


if __name__ == "__main__":
    main()
