"""Benchmark of model accuracy and cost: the exact scheme against the seed's θ-scheme, in one run.

Record (the model-accuracy issue's case): clamped–pinned steel strip 0.8 m × 40 × 4 mm under 300 N tension,
viscous + Kelvin–Voigt damping (ζ 0.4–1.6 % in band), one force, two accelerometers, 4 kHz, 5–300 Hz
multisine, 1 s, 1 % noise.  Truth: Hermite FE (96 elements) integrated exactly in time under a cubic spline
through the force samples; its own mesh convergence (48 and 64 elements) is printed first.

Printed:

* residual at the true parameters, mean squared error per sensor in noise variances (target <= 1.5 with
  the defaults), for the exact scheme and the θ-scheme at several grids and sub-steps;
* the broadband records (a random force to 0.2 fs and 0.4 fs through two accelerometers, periodic; truth the
  finite elements' steady state bin by bin): the cubic against the band-limited force between samples;
* cost of one evaluation (assemble + simulate 20,000 samples) of benchmark case R1 (seed config, 50 nodes)
  with each scheme, medians, and their ratio (target <= 3); the exact scheme with the band-limited input.

Run: ``python benchmarks/bench_accuracy.py [--repeats R] [--json PATH]``.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

import ebb_model as em
from ebb_model.reference.exact_fe import exact_fe_response, periodic_fe_response
from ebb_model.reference.excitation import band_limited_input
from ebb_model.reference.hermite_fe import hermite_beam

from figures import add_json_argument, write_figures  # benchmarks/figures.py
from timing import median_time  # benchmarks/timing.py

ROOT = Path(__file__).resolve().parents[1]
L, DT = 0.8, 1 / 4000
PARAMS = dict(EI=210e9 * 0.04 * 0.004 ** 3 / 12, rhoA=7850 * 0.04 * 0.004, c=4.0, eta=5e-6, N=300.0)
ACTUATOR, SENSORS = 0.44, ((0.24, "acceleration"), (0.6, "acceleration"))


#: The lightly damped record of tests/test_exact_scheme.py ("clamped-pinned-light"): ζ 2.1 % at mode 1 down to
#: 0.2 % at mode 5 (137 Hz), 2 kHz, 2–150 Hz (fs/13), two accelerometers, 1.5 s.
LIGHT = dict(length=1.0, dt=5e-4, params=dict(EI=10.0, rhoA=1.0, c=2.0, eta=2e-6, N=20.0), actuator=0.55,
             sensors=((0.35, "acceleration"), (0.8, "acceleration")), band=(2.0, 150.0), samples=3000)
STRIP = dict(length=L, dt=DT, params=PARAMS, actuator=ACTUATOR, sensors=SENSORS, band=(5.0, 300.0), samples=4000)


def config(nodes: int, scheme: str, substeps: int = 1, case: dict = STRIP, input_hold: str | None = None
           ) -> em.BeamConfig:
    time = {"dt": case["dt"], "scheme": scheme, "substeps": substeps} | ({"input": input_hold} if input_hold else {})
    return em.config_from_dict({
        "beam": {"length": case["length"], "nodes": nodes, "left": "clamped", "right": "pinned"},
        "time": time,
        "parameters": {k: {"value": v} for k, v in case["params"].items()},
        "actuators": [{"name": "F1", "x": case["actuator"]}],
        "sensors": [{"name": f"a{i}", "x": x, "kind": k} for i, (x, k) in enumerate(case["sensors"])],
    })


def truth(u: np.ndarray, n_elements: int, case: dict = STRIP) -> np.ndarray:
    beam = hermite_beam(case["length"], n_elements, left=(np.inf, np.inf), right=(np.inf, 0.0), **case["params"])
    return exact_fe_response(beam, u, case["dt"], [case["actuator"]], case["sensors"])


#: Periods of the broadband records simulated; the last is compared (the slowest mode, ζω = 1.1 /s, keeps e^{-8}
#: of its start after five).
PERIODS = 6


def periodic_truth(u: np.ndarray, n_elements: int, case: dict = LIGHT) -> np.ndarray:
    beam = hermite_beam(case["length"], n_elements, left=(np.inf, np.inf), right=(np.inf, 0.0), **case["params"])
    return periodic_fe_response(beam, u[:, 0], case["dt"], case["actuator"], case["sensors"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=21)
    add_json_argument(ap)
    args = ap.parse_args()
    rows: list[dict] = []         # residual at the true parameters [noise variances] per record and model
    with threadpool_limits(limits=1, user_api="blas"):
        u = band_limited_input(4000, DT, 5.0, 300.0, seed=4)
        y = truth(u, 96)
        noise_var = (0.01 * y.std(axis=0)) ** 2

        def res(yy: np.ndarray, record: str = "strip", model: str = "", nv: np.ndarray = noise_var,
                ref: np.ndarray = y) -> str:
            v = np.mean((yy - ref) ** 2, axis=0) / nv
            rows.append({"record": record, "model": model, "noise_variances": v.tolist(), "largest": float(v.max())})
            return " / ".join(f"{x:9.3f}" for x in v)

        print("Steel strip (the issue's case).  Truth convergence (noise variances): 48 elements",
              res(truth(u, 48), model="truth 48 elements"), "| 64 elements",
              res(truth(u, 64), model="truth 64 elements"),
              "(time: exact for the spline force)")
        print("Residual at the true parameters, noise variances per accelerometer (target <= 1.5):")
        for nodes in (30, 60, 120, 240):
            y_c = em.simulate(em.fast_model(config(nodes, "exact")), u).outputs
            print(f"  exact  {nodes:4d} nodes (cubic input)  {res(y_c, model=f'exact {nodes} nodes cubic')}")
            y_f = em.simulate(em.fast_model(config(nodes, "exact", input_hold="foh")), u).outputs
            print(f"  exact  {nodes:4d} nodes (foh input)    {res(y_f, model=f'exact {nodes} nodes foh')}")
            for sub in (1, 4, 16):
                y_t = em.simulate(em.fast_model(config(nodes, "theta", sub)), u).outputs
                print(f"  theta  {nodes:4d} nodes, {sub:2d} sub-steps  "
                      f"{res(y_t, model=f'theta {nodes} nodes {sub} substeps')}")
        ul = band_limited_input(LIGHT["samples"], LIGHT["dt"], *LIGHT["band"], seed=4)
        yl = truth(ul, 96, LIGHT)
        nvl = (0.01 * yl.std(axis=0)) ** 2
        print("Lightly damped record (zeta 0.2 % at 137 Hz, band to fs/13), residual at the true parameters:")
        for nodes in (30, 60, 120):
            for hold in ("cubic", "foh"):
                yy = em.simulate(em.fast_model(config(nodes, "exact", case=LIGHT, input_hold=hold)), ul).outputs
                r = res(yy, "light", f"exact {nodes} nodes {hold}", nvl, yl)
                print(f"  exact  {nodes:4d} nodes ({hold} input) {r}")
        print("Broadband records (the light beam, a random force to 0.2 fs and to 0.4 fs, periodic; truth: the "
              "finite elements' steady state bin by bin, 128 elements), residual at the true parameters:")
        for top in (0.2, 0.4):
            record = f"broadband{round(100 * top)}"     # percent of fs (no dot: the figures' paths split on it)
            ub = band_limited_input(LIGHT["samples"], LIGHT["dt"], 2.0, top / LIGHT["dt"], seed=4, fade=0.0)
            yb = periodic_truth(ub, 128)
            nvb = (0.01 * yb.std(axis=0)) ** 2
            print(f"  {record}: truth 96 elements {res(periodic_truth(ub, 96), record, 'truth 96 elements', nvb, yb)}")
            for nodes in (60, 200):
                for hold in ("cubic", "bandlimited"):
                    model = em.fast_model(config(nodes, "exact", case=LIGHT, input_hold=hold))
                    yy = em.simulate(model, np.tile(ub, (PERIODS, 1))).outputs[-ub.shape[0]:]
                    r = res(yy, record, f"exact {nodes} nodes {hold}", nvb, yb)
                    print(f"  exact  {nodes:4d} nodes ({hold} input) {r}")
        seed = em.load_config(ROOT / "examples" / "seed_clamped.toml")
        d = seed.to_dict()
        d["time"]["scheme"] = "theta"
        seed_theta = em.config_from_dict(d)
        d["time"]["scheme"] = "exact"
        seed_exact = em.config_from_dict(d)
        d["time"]["input"] = "bandlimited"
        seed_band = em.config_from_dict(d)
        u1 = np.random.default_rng(0).standard_normal((20000, 1))
        for c in (seed_theta, seed_exact, seed_band):
            em.simulate(em.fast_model(c), u1)               # compile and warm up
        t_theta = median_time(lambda: em.simulate(em.fast_model(seed_theta), u1), args.repeats)
        t_exact = median_time(lambda: em.simulate(em.fast_model(seed_exact), u1), args.repeats)
        t_band = median_time(lambda: em.simulate(em.fast_model(seed_band), u1), args.repeats)
    print(f"R1 evaluation (assemble + simulate 20,000 samples), medians of {args.repeats}:")
    print(f"  theta scheme: {t_theta * 1e3:7.3f} ms")
    print(f"  exact scheme: {t_exact * 1e3:7.3f} ms")
    print(f"  ratio exact / theta: {t_exact / t_theta:5.2f} x   (target <= 3)")
    print(f"  exact scheme, band-limited input: {t_band * 1e3:7.3f} ms ({t_band / t_exact:4.2f} x the cubic's)")
    write_figures(args.json, {"residuals": rows, "r1_theta_ms": t_theta * 1e3, "r1_exact_ms": t_exact * 1e3,
                              "r1_ratio": t_exact / t_theta, "r1_bandlimited_ms": t_band * 1e3,
                              "r1_bandlimited_ratio": t_band / t_exact})


if __name__ == "__main__":
    main()
