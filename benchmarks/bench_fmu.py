"""Cost of one communication step of the beam FMU through fmpy, next to pythonfmu's floor.

Case R1: ``examples/seed_clamped.toml`` (50 interior nodes, clamped-clamped,
dt = 1e-4 s, one force, two displacement sensors).  The floor is a trivial
pythonfmu FMU (one input copied to one output) built with pythonfmu's own
builder: whatever it costs is pythonfmu's and fmpy's per-call overhead.

Each communication step is the low-level ``fmpy.fmi2.FMU2Slave`` sequence
``setReal(u) -> getReal(y) -> doStep(t, dt)`` on one instance that is reused
(``reset()`` between repeats).  Reported: the median over repeats of the mean
time per step, in microseconds, and the ratio beam / floor.

Usage::

    python benchmarks/bench_fmu.py [--steps 20000] [--repeats 7] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from fmu_build import build_fmu  # noqa: E402

R1_CONFIG = ROOT / "examples" / "seed_clamped.toml"

_TRIVIAL_SLAVE = '''
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class Floor(Fmi2Slave):
    """One input copied to one output: pythonfmu's per-step floor."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.y = self.u
        return True
'''


def build_floor_fmu(workdir: Path) -> Path:
    """Build the trivial pythonfmu FMU with pythonfmu's own command line."""
    script = workdir / "floor_slave.py"
    script.write_text(_TRIVIAL_SLAVE, encoding="utf-8")
    subprocess.run([sys.executable, "-m", "pythonfmu", "build", "-f", str(script), "-d", str(workdir)],
                   check=True, capture_output=True, cwd=workdir)
    return workdir / "Floor.fmu"


def time_steps(fmu_path: Path, inputs: list[str], outputs: list[str], *, dt: float, steps: int,
               repeats: int) -> list[float]:
    """Mean µs per communication step for each repeat, one FMU instance reused.

    Parameters
    ----------
    fmu_path
        The FMU.
    inputs, outputs
        Variable names set and read every step.
    dt
        Communication step [s].
    steps
        Communication steps per repeat.
    repeats
        Number of timed repeats (after one untimed warm-up).
    """
    unzipdir = extract(str(fmu_path))
    md = read_model_description(unzipdir)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    u_vr = [vr[n] for n in inputs]
    y_vr = [vr[n] for n in outputs]
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="bench")
    u = np.random.default_rng(1).standard_normal((steps, len(u_vr))).tolist()
    results: list[float] = []
    fmu.instantiate()
    try:
        for rep in range(repeats + 1):
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
            set_real, get_real, do_step = fmu.setReal, fmu.getReal, fmu.doStep
            t = 0.0
            start = time.perf_counter()
            for k in range(steps):
                set_real(u_vr, u[k])
                get_real(y_vr)
                do_step(t, dt)
                t += dt
            elapsed = time.perf_counter() - start
            if rep > 0:
                results.append(elapsed / steps * 1e6)
            fmu.reset()
        fmu.terminate()
    finally:
        fmu.freeInstance()
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20000, help="communication steps per repeat")
    parser.add_argument("--repeats", type=int, default=7, help="timed repeats")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures to this JSON file")
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="bench_fmu_") as tmp:
        work = Path(tmp)
        beam = build_fmu(R1_CONFIG, work / "beam_r1.fmu")
        floor = build_floor_fmu(work)
        beam_us = time_steps(beam, ["F1"], ["y1", "y2"], dt=1e-4, steps=args.steps, repeats=args.repeats)
        floor_us = time_steps(floor, ["u"], ["y"], dt=1e-4, steps=args.steps, repeats=args.repeats)

    beam_med, floor_med = statistics.median(beam_us), statistics.median(floor_us)
    figures = {
        "case": "R1 (seed_clamped.toml: 50 interior nodes, clamped-clamped, dt 1e-4 s, 1 force, 2 sensors)",
        "loop": "fmpy FMU2Slave: setReal(u), getReal(y), doStep(t, dt); one instance, reset between repeats",
        "steps_per_repeat": args.steps,
        "repeats": args.repeats,
        "beam_us_per_step": beam_us,
        "floor_us_per_step": floor_us,
        "beam_median_us": beam_med,
        "floor_median_us": floor_med,
        "ratio": beam_med / floor_med,
        "target_us": 12.0,
    }
    print(f"beam FMU (R1)          : {beam_med:7.2f} us/step  (median of {args.repeats} x {args.steps} steps)")
    print(f"trivial pythonfmu FMU  : {floor_med:7.2f} us/step")
    print(f"ratio beam / floor     : {beam_med / floor_med:7.2f}")
    print(f"target <= 12 us/step   : {'met' if beam_med <= 12.0 else 'NOT met'}")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
