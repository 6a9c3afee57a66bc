"""µs per communication step through fmpy: the standalone C FMU against the pythonfmu FMU, same run.

Case R1: ``examples/seed_clamped.toml`` (50 interior nodes, clamped-clamped, dt = 1e-4 s, one force, two
displacement sensors; scheme exact with the cubic input).  Both FMUs are driven by the same loop as
``bench_fmu.py`` (fmpy's ``FMU2Slave``: ``setReal(u) -> getReal(y) -> doStep(t, dt)`` on one instance,
``reset()`` between repeats).  Reported: medians over repeats of the mean µs per step, and their ratio.
Besides, for the standalone FMU: the model's own cost per sample (one ``doStep`` over all samples, so
fmpy's per-call overhead drops out) and the time of ``fmi2ExitInitializationMode`` (assembly on two grids,
eigen-solutions, exact discretisation).  And the identification's FMU backend
(:class:`identification.fmu_backend.FmuEvaluator`, one instance reused with ``reset()``) on each FMU: candidate
evaluations per second (EI, ρA, N drawn inside R1's bounds, 2,000-sample record), same run.
And FMI 3.0 against FMI 2.0 (issue 75): the standalone FMU built for each version from R1; a step as a C master
pays it (``csrc/step_timer.c``: set, get, step through each standard's API, no interpreter between), the same loop
through fmpy's ``FMU3Slave`` and ``FMU2Slave`` (what a Python host pays, fmpy's wrappers included), and the
model's own cost per sample in each; the versions' runs interleaved, repeat by repeat.

Usage::

    python benchmarks/bench_fmu_standalone.py [--steps 20000] [--repeats 7] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

ROOT = Path(__file__).resolve().parents[1]
for p in (ROOT, ROOT / "benchmarks"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

from bench_fmu import R1_CONFIG, time_steps  # noqa: E402
from fmu_build import build_fmu  # noqa: E402
from fmu_build.standalone import build_standalone_fmu  # noqa: E402


def inner_costs(fmu_path: Path, *, samples: int, repeats: int) -> tuple[list[float], list[float]]:
    """µs per sample inside one ``doStep(t, samples * dt)``, and ms of ``ExitInitializationMode`` (FMI 2.0 or 3.0,
    as the FMU is)."""
    unzipdir = extract(str(fmu_path))
    md = read_model_description(unzipdir)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    dt = float(md.defaultExperiment.stepSize)
    three = md.fmiVersion.startswith("3")
    fmu = (FMU3Slave if three else FMU2Slave)(guid=md.guid, unzipDirectory=unzipdir,
                                               modelIdentifier=md.coSimulation.modelIdentifier, instanceName="inner")
    per_sample, init_ms = [], []
    fmu.instantiate()
    try:
        for rep in range(repeats + 1):
            if three:
                fmu.enterInitializationMode(startTime=0.0)
            else:
                fmu.setupExperiment(startTime=0.0)
                fmu.enterInitializationMode()
            start = time.perf_counter()
            fmu.exitInitializationMode()
            init = time.perf_counter() - start
            (fmu.setFloat64 if three else fmu.setReal)([vr["F1"]], [1.0])
            start = time.perf_counter()
            fmu.doStep(0.0, samples * dt)
            elapsed = time.perf_counter() - start
            if rep > 0:
                per_sample.append(elapsed / samples * 1e6)
                init_ms.append(init * 1e3)
            fmu.reset()
        fmu.terminate()
    finally:
        fmu.freeInstance()
    return per_sample, init_ms


def c_master_step(work: Path, fmu_path: Path, *, steps: int) -> float:
    """ns per co-simulation step (set the input, get both outputs, one step) of R1's FMU from a C master."""
    import fmpy
    import subprocess

    exe = work / "step_timer"
    if not exe.exists():
        subprocess.run(["gcc", "-O2", "-I", str(Path(fmpy.__file__).parent / "c-code"), "-o", str(exe),
                        str(Path(__file__).resolve().parent / "csrc" / "step_timer.c"), "-ldl", "-lm"], check=True)
    unzipdir = Path(extract(str(fmu_path)))
    md = read_model_description(str(unzipdir))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    version = md.fmiVersion[0]
    library = unzipdir / "binaries" / ("x86_64-linux" if version == "3" else "linux64") / \
        f"{md.coSimulation.modelIdentifier}.so"
    out = subprocess.run([str(exe), version, str(library), md.guid, "1e-4", str(steps), "1", str(vr["F1"]),
                          f"{vr['y1']},{vr['y2']}"], capture_output=True, text=True, check=True).stdout
    return float(out.split()[0])


def fmi_versions(work: Path, *, steps: int, repeats: int) -> dict[str, float]:
    """The standalone FMU of R1 in FMI 2.0 and 3.0: medians of a C master's step (ns), of the fmpy loop (µs per
    step) and of the model's own cost (µs per sample), the versions interleaved repeat by repeat, and their ratios
    (3.0 over 2.0)."""
    fmus = {v: build_standalone_fmu(R1_CONFIG, work / f"r1_fmi{v}.fmu", fmi=v) for v in (2, 3)}
    c_step: dict[int, list[float]] = {2: [], 3: []}
    loop: dict[int, list[float]] = {2: [], 3: []}
    inner: dict[int, list[float]] = {2: [], 3: []}
    for _ in range(repeats):
        for v in (2, 3):
            c_step[v].append(c_master_step(work, fmus[v], steps=steps))
            inner[v] += inner_costs(fmus[v], samples=steps, repeats=1)[0]
        loop[2] += time_steps(fmus[2], ["F1"], ["y1", "y2"], dt=1e-4, steps=steps, repeats=1)
        loop[3] += time_steps(fmus[3], ["F1"], ["y1", "y2"], dt=1e-4, steps=steps, repeats=1)
    med = {f"{kind}_fmi{v}": statistics.median(d[v]) for kind, d in (("c_step", c_step), ("loop", loop),
                                                                     ("inner", inner)) for v in (2, 3)}
    return med | {f"{kind}_ratio_fmi3_over_fmi2": med[f"{kind}_fmi3"] / med[f"{kind}_fmi2"]
                  for kind in ("c_step", "loop", "inner")}


def backend_rates(fmus: dict[str, Path], *, candidates: int, samples: int, repeats: int) -> dict[str, list[float]]:
    """Candidate evaluations per second of the identification's FMU backend on each FMU (same candidates)."""
    import numpy as np

    from ebb_model import assemble, simulate
    from identification.fmu_backend import FmuEvaluator
    from identification.native import experiments_from_arrays
    from identification.parameters import parameter_space
    from identification.run import load_identification_config

    cfg = load_identification_config(R1_CONFIG)
    space = parameter_space(cfg)
    rng = np.random.default_rng(0)
    u = rng.standard_normal((samples, len(cfg.actuators)))
    exps = experiments_from_arrays([("bench", u, simulate(assemble(cfg), u).outputs)])
    lo, hi = np.asarray(space.nominal) * 0.8, np.asarray(space.nominal) * 1.2
    X = lo + rng.random((candidates, space.dim)) * (hi - lo)
    rates: dict[str, list[float]] = {}
    for label, path in fmus.items():
        ev = FmuEvaluator(str(path), cfg, space, exps)
        ev.evaluate(X[:1])                                  # extract, instantiate, warm up
        rates[label] = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            ev.evaluate(X)
            rates[label].append(candidates / (time.perf_counter() - t0))
        ev.close()
    return rates


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20000, help="communication steps per repeat")
    parser.add_argument("--repeats", type=int, default=7, help="timed repeats")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures to this JSON file")
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="bench_cfmu_") as tmp:
        work = Path(tmp)
        standalone = build_standalone_fmu(R1_CONFIG, work / "r1_standalone.fmu")
        python = build_fmu(R1_CONFIG, work / "r1_pythonfmu.fmu")
        c_us = time_steps(standalone, ["F1"], ["y1", "y2"], dt=1e-4, steps=args.steps, repeats=args.repeats)
        py_us = time_steps(python, ["F1"], ["y1", "y2"], dt=1e-4, steps=args.steps, repeats=args.repeats)
        inner_us, init_ms = inner_costs(standalone, samples=args.steps, repeats=args.repeats)
        rates = backend_rates({"standalone": standalone, "pythonfmu": python}, candidates=20, samples=2000,
                              repeats=max(3, args.repeats // 2))
        versions = fmi_versions(work, steps=args.steps, repeats=args.repeats)

    c_med, py_med = statistics.median(c_us), statistics.median(py_us)
    figures = {
        "case": "R1 (seed_clamped.toml: 50 interior nodes, clamped-clamped, dt 1e-4 s, 1 force, 2 sensors)",
        "loop": "fmpy FMU2Slave: setReal(u), getReal(y), doStep(t, dt); one instance, reset between repeats",
        "steps_per_repeat": args.steps,
        "repeats": args.repeats,
        "standalone_us_per_step": c_us,
        "pythonfmu_us_per_step": py_us,
        "standalone_median_us": c_med,
        "pythonfmu_median_us": py_med,
        "ratio_pythonfmu_over_standalone": py_med / c_med,
        "standalone_inner_us_per_sample": statistics.median(inner_us),
        "standalone_init_ms": statistics.median(init_ms),
        "backend_evaluations_per_s": {k: statistics.median(v) for k, v in rates.items()},
        "fmi_versions": versions,
    }
    print(f"standalone C FMU (R1)   : {c_med:7.2f} us/step  (median of {args.repeats} x {args.steps} steps)")
    print(f"pythonfmu FMU (R1)      : {py_med:7.2f} us/step")
    print(f"ratio pythonfmu / C     : {py_med / c_med:7.2f}")
    print(f"C model alone           : {statistics.median(inner_us):7.3f} us/sample (one doStep of {args.steps} "
          "samples)")
    print(f"C initialisation        : {statistics.median(init_ms):7.2f} ms (fmi2ExitInitializationMode)")
    r_c, r_py = (statistics.median(rates[k]) for k in ("standalone", "pythonfmu"))
    print(f"identification FMU backend: {r_c:7.1f} evaluations/s standalone, {r_py:7.1f} pythonfmu "
          f"(ratio {r_c / r_py:5.2f}; 2,000 samples per evaluation)")
    print(f"FMI 3.0 / FMI 2.0 (standalone, R1): a C master's step {versions['c_step_fmi3']:.1f} / "
          f"{versions['c_step_fmi2']:.1f} ns (ratio {versions['c_step_ratio_fmi3_over_fmi2']:.3f}); the model alone "
          f"{versions['inner_fmi3']:.3f} / {versions['inner_fmi2']:.3f} us/sample "
          f"(ratio {versions['inner_ratio_fmi3_over_fmi2']:.3f}); fmpy's loop {versions['loop_fmi3']:.2f} / "
          f"{versions['loop_fmi2']:.2f} us/step (ratio {versions['loop_ratio_fmi3_over_fmi2']:.3f}: fmpy's FMI 3.0 "
          "wrappers)")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
