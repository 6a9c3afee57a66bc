"""Cost of one communication step of the beam FMU through fmpy, next to pythonfmu's floor; and of its start.
The same FMU built in FMI 3.0 (pythonfmu3) beside it, step and start, in the same run, next to pythonfmu3's floor
(the same trivial FMU built with pythonfmu3): the beam's own share of a step is its time above its package's floor.

Case R1: ``examples/seed_clamped.toml`` (50 interior nodes, clamped-clamped,
dt = 1e-4 s, one force, two displacement sensors).  The floor is a trivial
pythonfmu FMU (one input copied to one output) built with pythonfmu's own
builder: whatever it costs is pythonfmu's and fmpy's per-call overhead.

Each communication step is the low-level ``fmpy.fmi2.FMU2Slave`` sequence
``setReal(u) -> getReal(y) -> doStep(t, dt)`` on one instance that is reused
(``reset()`` between repeats).  Reported: the median over repeats of the mean
time per step, in microseconds, and the ratio beam / floor.

The start: a new Python process (fmpy imported) extracts the FMU, instantiates it, initialises it and takes one
step — what a host pays on every simulation start; the median over ``--starts`` processes, timed inside the
process from after fmpy's import.  Beside it the same FMU without what it carries to start at once — its
compiled core (the ``__pycache__`` files) and its model at its own values (``resources/ebb_model.npz``), removed
before zipping it again: what the start cost before the FMU carried them (fmu_build/kernels.py).

Usage::

    python benchmarks/bench_fmu.py [--steps 20000] [--repeats 7] [--starts 7] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from fmu_build import build_fmu  # noqa: E402
from fmu_build.slave_template import MODEL_FILE  # noqa: E402

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


_TRIVIAL_SLAVE3 = '''
from pythonfmu3 import Fmi3Causality, Fmi3Slave, Fmi3Variability, Float64
from pythonfmu3.fmi3slave import Fmi3StepResult


class Floor3(Fmi3Slave):
    """One input copied to one output: pythonfmu3's per-step floor (with the independent variable FMI 3.0 asks
    for, which pythonfmu3 does not add)."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.time = 0.0
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        self.register_variable(Float64("u", causality=Fmi3Causality.input))
        self.register_variable(Float64("y", causality=Fmi3Causality.output))

    def do_step(self, current_time, step_size):
        self.y = self.u
        return Fmi3StepResult()
'''


def build_floor_fmu(workdir: Path, fmi: int = 2) -> Path:
    """Build the trivial pythonfmu FMU (``fmi=3``: the pythonfmu3 one) with the package's own command line."""
    script = workdir / f"floor_slave{fmi}.py"
    script.write_text(_TRIVIAL_SLAVE if fmi == 2 else _TRIVIAL_SLAVE3, encoding="utf-8")
    package = "pythonfmu" if fmi == 2 else "pythonfmu3"
    subprocess.run([sys.executable, "-m", package, "build", "-f", str(script), "-d", str(workdir)],
                   check=True, capture_output=True, cwd=workdir)
    return workdir / ("Floor.fmu" if fmi == 2 else "Floor3.fmu")


def time_steps(fmu_path: Path, inputs: list[str], outputs: list[str], *, dt: float, steps: int,
               repeats: int) -> list[float]:
    """Mean µs per communication step for each repeat, one FMU instance reused (fmpy's ``FMU2Slave``: ``setReal``,
    ``getReal``, ``doStep``; for an FMI 3.0 FMU its ``FMU3Slave``: ``setFloat64``, ``getFloat64``, ``doStep``).

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
    three = md.fmiVersion.startswith("3")
    fmu = (FMU3Slave if three else FMU2Slave)(guid=md.guid, unzipDirectory=unzipdir,
                                               modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    u = np.random.default_rng(1).standard_normal((steps, len(u_vr))).tolist()
    results: list[float] = []
    fmu.instantiate()
    try:
        for rep in range(repeats + 1):
            if three:
                fmu.enterInitializationMode(startTime=0.0)
            else:
                fmu.setupExperiment(startTime=0.0)
                fmu.enterInitializationMode()
            fmu.exitInitializationMode()
            set_real, get_real, do_step = ((fmu.setFloat64, fmu.getFloat64, fmu.doStep) if three
                                           else (fmu.setReal, fmu.getReal, fmu.doStep))
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


#: One host start in a new process: extract, instantiate, initialise, one step; the seconds from after fmpy's
#: import to the first step's outputs.
_START = """
import sys, time
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
t0 = time.perf_counter()
d = extract(sys.argv[1])
md = read_model_description(d)
three = md.fmiVersion.startswith("3")
f = (FMU3Slave if three else FMU2Slave)(guid=md.guid, unzipDirectory=d,
                                         modelIdentifier=md.coSimulation.modelIdentifier, instanceName="s")
f.instantiate()
if three:
    f.enterInitializationMode(startTime=0.0)
else:
    f.setupExperiment(startTime=0.0)
    f.enterInitializationMode()
f.exitInitializationMode()
u = [v.valueReference for v in md.modelVariables if v.causality == "input"]
y = [v.valueReference for v in md.modelVariables if v.causality == "output"]
(f.setFloat64 if three else f.setReal)(u[:1], [1.0])
f.doStep(0.0, float(md.defaultExperiment.stepSize))
(f.getFloat64 if three else f.getReal)(y)
print(time.perf_counter() - t0)
f.terminate()
f.freeInstance()
"""


def without_carried_core(fmu_path: Path, out: Path) -> Path:
    """The FMU ``fmu_path`` without its ``__pycache__`` files (no compiled kernels, no byte code) and its carried
    model, as ``out``."""
    with zipfile.ZipFile(fmu_path) as src, zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as dst:
        for item in src.infolist():
            if "/__pycache__/" not in item.filename and item.filename != f"resources/{MODEL_FILE}":
                dst.writestr(item, src.read(item))
    return out


def time_starts(fmu_path: Path, starts: int) -> list[float]:
    """Seconds from extraction to the first step's outputs, each in a new process."""
    times = []
    for _ in range(starts):
        run = subprocess.run([sys.executable, "-c", _START, str(fmu_path)], check=True, capture_output=True,
                             text=True)
        times.append(float(run.stdout.split()[-1]))
    return times


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20000, help="communication steps per repeat")
    parser.add_argument("--repeats", type=int, default=7, help="timed repeats")
    parser.add_argument("--starts", type=int, default=7, help="new processes timed for the start")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures to this JSON file")
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="bench_fmu_") as tmp:
        work = Path(tmp)
        beam = build_fmu(R1_CONFIG, work / "beam_r1.fmu")
        beam3 = build_fmu(R1_CONFIG, work / "beam_r1_fmi3.fmu", fmi=3)
        floor = build_floor_fmu(work)
        floor3 = build_floor_fmu(work, fmi=3)
        beam_us = time_steps(beam, ["F1"], ["y1", "y2"], dt=1e-4, steps=args.steps, repeats=args.repeats)
        beam3_us = time_steps(beam3, ["F1"], ["y1", "y2"], dt=1e-4, steps=args.steps, repeats=args.repeats)
        floor_us = time_steps(floor, ["u"], ["y"], dt=1e-4, steps=args.steps, repeats=args.repeats)
        floor3_us = time_steps(floor3, ["u"], ["y"], dt=1e-4, steps=args.steps, repeats=args.repeats)
        start_s = time_starts(beam, args.starts)
        start3_s = time_starts(beam3, args.starts)
        bare_s = time_starts(without_carried_core(beam, work / "beam_r1_bare.fmu"), args.starts)

    beam_med, floor_med = statistics.median(beam_us), statistics.median(floor_us)
    beam3_med, floor3_med = statistics.median(beam3_us), statistics.median(floor3_us)
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
        "start": "new process: extract, instantiate, initialise, one step (after fmpy's import)",
        "start_s": start_s,
        "start_median_s": statistics.median(start_s),
        "bare_start_s": bare_s,
        "bare_start_median_s": statistics.median(bare_s),
        "start_target_s": 0.5,
        "fmi3_loop": "the same FMU built in FMI 3.0 (pythonfmu3): fmpy FMU3Slave setFloat64, getFloat64, doStep",
        "beam_fmi3_us_per_step": beam3_us,
        "beam_fmi3_median_us": beam3_med,
        "fmi3_over_fmi2": beam3_med / beam_med,
        "floor_fmi3_us_per_step": floor3_us,
        "floor_fmi3_median_us": floor3_med,
        # the beam's own share of a step (above its package's trivial FMU), per version
        "own_fmi2_us": beam_med - floor_med,
        "own_fmi3_us": beam3_med - floor3_med,
        "start_fmi3_s": start3_s,
        "start_fmi3_median_s": statistics.median(start3_s),
    }
    print(f"beam FMU (R1)          : {beam_med:7.2f} us/step  (median of {args.repeats} x {args.steps} steps)")
    print(f"trivial pythonfmu FMU  : {floor_med:7.2f} us/step")
    print(f"ratio beam / floor     : {beam_med / floor_med:7.2f}")
    print(f"target <= 12 us/step   : {'met' if beam_med <= 12.0 else 'NOT met'}")
    start_med, bare_med = statistics.median(start_s), statistics.median(bare_s)
    print(f"start, new process     : {start_med:7.3f} s  (median of {args.starts}; extract to first step)")
    print(f"  without its compiled core: {bare_med:7.3f} s")
    print(f"target <= 0.5 s        : {'met' if start_med <= 0.5 else 'NOT met'}")
    print(f"the same in FMI 3.0    : {beam3_med:7.2f} us/step ({beam3_med / beam_med:.2f} of FMI 2.0's), start "
          f"{statistics.median(start3_s):.3f} s")
    print(f"trivial pythonfmu3 FMU : {floor3_med:7.2f} us/step; the beam's own share: FMI 2.0 "
          f"{beam_med - floor_med:.2f} us, FMI 3.0 {beam3_med - floor3_med:.2f} us")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
