"""Seed case (1): an undamped beam identified with and without the stabilising objective.

Talic et al. identify an axially loaded Euler–Bernoulli beam with one
performance objective (the output error of one sensor) and a second,
*stabilising* objective: the maximum growth factor ``max|z|`` of the
θ-scheme's dispersion relation.  This example reproduces their point on
simulation data of an **undamped** beam:

* the data come from an independent discretisation (cubic-Hermite FE +
  Newmark, :mod:`fe_data`) of the truth EI = 10, rhoA = 1, N = 50, c = 0,
  with 0.5 % noise — no inverse crime;
* the model is the finite-difference beam with an explicit-leaning time
  scheme, θ = 1/12 (conditionally stable); at dt = 1e-4 s a large part of the
  search box violates the Bistritz bounds;
* run A fits the output error only (``stabilising=False``); run B adds the
  growth-factor objective.

Because the truth is undamped, the best output-error fit has no damping:
every mode of the identified model sits on the unit circle (growth factor 1,
*marginal*).  Such a model has no stability margin: nothing decays, and with
θ < 1/4 a slightly larger dt or a stiffer parameter set beyond the Bistritz
bound makes it grow.  With the stabilising objective every front point is
strictly stable (growth factor below one, all modes decaying); the price is
fit and bias — the knee is softer and damped (c at its bound), so the
stabilising objective acts as a regulariser, not as a better estimator.

"Marginal" here means ``max|z| > 1 - 1e-6`` per time step (slowest decay
time above ``1e-4 s / 1e-6 = 100 s``, over 300 times the record length);
"unstable" means ``max|z| > 1`` on the grid or a spectral radius of Φ above
one for the finite beam.

Run: ``python examples/seed_undamped.py [--quick] [--out DIR]``.
Writes the data, both result directories and ``summary.json`` into DIR
(default: a new temporary directory, printed at the end).
"""
from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np

import ebb_model as em
from ebb_model.parameter_values import resolve_parameters
from identification.parameters import parameter_space
from identification.run import identify, load_identification_config

from fe_data import example_main, fe_measurements, half_sine_pulse, write_csv

HERE = Path(__file__).resolve().parent
CONFIG = HERE / "seed_undamped.toml"
TRUTH = {"EI": 10.0, "rhoA": 1.0, "c": 0.0, "eta": 0.0, "N": 50.0}
NOISE = 0.005          # noise std / signal std
MARGINAL = 1e-6        # growth factor above 1 - MARGINAL per step counts as marginal
SETTINGS = {"full": {"samples": 3000, "pop": 40, "generations": 60},
            "quick": {"samples": 1500, "pop": 24, "generations": 40}}


def classify(cfg: em.BeamConfig, params: dict[str, float]) -> dict[str, Any]:
    """Growth factor, decay rate, spectral radius, Bistritz margin and verdict of one parameter set."""
    full = resolve_parameters(cfg, params)
    g = em.max_growth_factor(cfg, full)
    tau = cfg.time.dt / cfg.time.substeps
    rho = em.fast_model(cfg, full).spectral_radius()
    ei_max = em.stability_bounds(cfg, full)["EI"][1]
    if g > 1.0 + 1e-12 or rho > 1.0 + 1e-9:
        verdict = "unstable"
    elif g > 1.0 - MARGINAL:
        verdict = "marginal"
    else:
        verdict = "stable"
    return {"growth_factor": g, "decay_rate": -math.log(g) / tau if g < 1 else 0.0, "spectral_radius": rho,
            "EI_bistritz_max": ei_max, "verdict": verdict}


def unstable_fraction(cfg: em.BeamConfig, n: int = 2000, seed: int = 0) -> float:
    """Share of the search box (uniform samples) whose growth factor exceeds one."""
    sp = parameter_space(cfg)
    rng = np.random.default_rng(seed)
    X = sp.lower + rng.random((n, sp.dim)) * (sp.upper - sp.lower)
    bad = [em.max_growth_factor(cfg, dict(zip(sp.names, map(float, x)))) > 1.0 for x in X]
    return float(np.mean(bad))


def run_case(out: Path, *, quick: bool, seed: int, pop: int | None, generations: int | None,
             export: bool) -> dict[str, Any]:
    """Generate the data, run both identifications, classify their fronts; return the summary."""
    s = SETTINGS["quick" if quick else "full"]
    pop = pop or s["pop"]
    generations = generations or s["generations"]
    cfg = load_identification_config(CONFIG)
    dt = cfg.time.dt
    u = half_sine_pulse(s["samples"], dt, width=0.005)
    y = fe_measurements(cfg, TRUTH, u[:, None], noise=NOISE, seed=seed)
    data = write_csv(out / "data.csv", dt, {"F1": u, "y1": y[:, 0]})
    summary: dict[str, Any] = {
        "truth": TRUTH, "dt": dt, "theta": cfg.time.theta,
        "dt_max_truth": em.analyse_stability(cfg, TRUTH).dt_max,
        "unstable_box_fraction": unstable_fraction(cfg), "marginal_threshold": MARGINAL,
        "pop": pop, "generations": generations, "runs": {},
    }
    for name, stab in (("without_stability", False), ("with_stability", True)):
        # without the stabilising objective the front is the output-error optimum: polish it by
        # least squares (what the GA converges to); with it, the trade-off itself is the result
        t0 = time.perf_counter()
        identify(cfg, [data], out / name, pop=pop, generations=generations, seed=seed, stabilising=stab,
                 polish=0 if stab else 1, progress=False, export=export)
        doc = json.loads((out / name / "pareto.json").read_text())
        run: dict[str, Any] = {"seconds": time.perf_counter() - t0, "evaluations": doc["n_evaluations"],
                               "knee": doc["knee"], "points": []}
        for pt in doc["points"]:
            run["points"].append({"index": pt["index"], "knee": pt["knee"], "parameters": pt["parameters"],
                                  "nrmse_y1": pt["objectives"]["nrmse_y1"]} | classify(cfg, pt["parameters"]))
        for q in doc["polished"]:
            run["polished"] = {"parameters": q["parameters"], "nrmse_y1": q["objectives"]["nrmse_y1"],
                               "evaluations": q["n_evaluations"]} | classify(cfg, q["parameters"])
        summary["runs"][name] = run
    return summary


def _row(label: str, pt: dict[str, Any]) -> str:
    p = pt["parameters"]
    return (f"{label:<30} {p['EI']:7.3f} {p['rhoA']:6.3f} {p['N']:7.2f} {p['c']:7.4f} {pt['nrmse_y1']:8.4f} "
            f"{pt['growth_factor']:.9f} {pt['decay_rate']:8.3f} {pt['EI_bistritz_max']:7.2f}  {pt['verdict']}")


def report(summary: dict[str, Any]) -> str:
    """The printed tables."""
    lines = [
        f"truth: EI={TRUTH['EI']}, rhoA={TRUTH['rhoA']}, N={TRUTH['N']}, c={TRUTH['c']} (undamped); "
        f"theta={summary['theta']:.4f}, dt={summary['dt']:g} s = "
        f"{100 * summary['dt'] / summary['dt_max_truth']:.0f} % of the explicit limit at the truth",
        f"{100 * summary['unstable_box_fraction']:.0f} % of the search box is unstable at this dt "
        f"(max growth factor > 1); 'marginal' = growth factor > 1 - {MARGINAL:g} per step",
        "",
        f"{'point':<30} {'EI':>7} {'rhoA':>6} {'N':>7} {'c':>7} {'nrmse':>8} {'growth f.':>11} "
        f"{'decay/s':>8} {'EI_max':>7}  verdict",
    ]
    for name, run in summary["runs"].items():
        pts = run["points"]
        best = min(range(len(pts)), key=lambda i: pts[i]["nrmse_y1"])
        safest = min(range(len(pts)), key=lambda i: pts[i]["growth_factor"])
        short = name.split("_")[0]
        for i in sorted({best, run["knee"], safest}):
            what = [w for w, j in (("best fit", best), ("knee", run["knee"]), ("most stable", safest)) if j == i]
            lines.append(_row(f"{short}: {'only point' if len(what) == 3 else ', '.join(what)}", pts[i]))
        if "polished" in run:
            lines.append(_row(f"{short}: polished optimum", run["polished"]))
        every = pts + ([run["polished"]] if "polished" in run else [])
        n_bad = sum(pt["verdict"] != "stable" for pt in every)
        lines.append(f"  -> {name}: {len(pts)} front point(s)" + (" + polished optimum" if "polished" in run else "")
                     + f", {n_bad} of {len(every)} marginal or unstable; {run['evaluations']} evaluations, "
                     f"{run['seconds']:.1f} s")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    return example_main(__doc__, "seed-undamped", run_case, report, argv)

if __name__ == "__main__":
    sys.exit(main())
