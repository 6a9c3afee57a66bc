"""Drive a beam FMU from different masters, for the FMU tests.

Usable as a module (the tests import it) and as a script, so that every
master can run in a fresh interpreter::

    python fmu_loops.py fmpy  FMU INPUTS.npy OUT.npy [--after] [--param NAME=VALUE ...]
    python fmu_loops.py cosim FMU INPUTS.npy OUT.npy [--param NAME=VALUE ...]
    python fmu_loops.py ecos  FMU INPUTS.npy OUT.npy [--param NAME=VALUE ...]
    python fmu_loops.py ssp   SSD FMU INPUTS.npy OUT.npy [STEP] (libcosim on an SSP's system)
    python fmu_loops.py two   FMU_A FMU_B INPUTS.npy OUT_A.npy OUT_B.npy
    python fmu_loops.py lifecycle FMU CYCLES          (prints JSON: RSS growth)

Protocols (zero-order hold, ``u`` of shape (n, n_inputs)):

* ``before`` -- at ``t_k``: set ``u_k``, read ``y_k``, step.  ``y_k = C x_k + D u_k``,
  the rows of ``ebb_model.simulate``.
* ``after`` -- at ``t_k``: set ``u_k``, step, read: ``C x_{k+1} + D u_k``.  This
  is what libcosim's observers record after each step.
* ``accumulating`` -- ``before``, with the time accumulated in floating point (``t += dt``, as OMSimulator
  does) and passed as the communication point; at the end the master steps from its accumulated time to its stop
  time ``n dt`` (5.7e-15 s for 2000 steps of 1e-4 s) and reads the outputs once more (one row more).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

HERE = Path(__file__).resolve().parent
HOST_SOURCE = {2: HERE / "fmi2_host.c", 3: HERE / "fmi3_host.c"}


def _names(md, causality: str) -> list[str]:
    return [v.name for v in md.modelVariables if v.causality == causality]


class _Fmi3AsFmi2:
    """fmpy's ``FMU3Slave`` behind the ``FMU2Slave`` calls :func:`fmpy_outputs` makes (an array read whole)."""

    def __init__(self, md, unzipdir: str, sizes: Mapping[int, int]) -> None:
        from fmpy.fmi3 import FMU3Slave

        self.f = FMU3Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier,
                           instanceName="fmpy3")
        self.sizes, self.start = sizes, 0.0

    def instantiate(self) -> None:
        self.f.instantiate()

    def setupExperiment(self, startTime: float) -> None:
        self.start = startTime

    def enterInitializationMode(self) -> None:
        self.f.enterInitializationMode(startTime=self.start)

    def exitInitializationMode(self) -> None:
        self.f.exitInitializationMode()

    def setReal(self, vr: Sequence[int], values: Sequence[float]) -> None:
        self.f.setFloat64(vr, values)

    def getReal(self, vr: Sequence[int]) -> list[float]:
        return self.f.getFloat64(vr, nValues=sum(self.sizes.get(v, 1) for v in vr))

    def doStep(self, t: float, h: float) -> None:
        self.f.doStep(t, h)

    def terminate(self) -> None:
        self.f.terminate()

    def freeInstance(self) -> None:
        self.f.freeInstance()


def fmpy_outputs(fmu: str | os.PathLike, u: np.ndarray, *, params: Mapping[str, float] | None = None,
                 protocol: str = "before", outputs: Sequence[str] | None = None) -> np.ndarray:
    """Outputs of the FMU through fmpy's low-level ``FMU2Slave`` API (``FMU3Slave`` for an FMI 3.0 FMU, its array
    outputs read whole: one column per element).

    Parameters
    ----------
    fmu
        The ``.fmu`` file.
    u
        Inputs, one row per communication point, columns in input order.
    params
        Parameter values set before initialisation.
    protocol
        ``"before"``, ``"after"`` or ``"accumulating"`` (see the module docstring).
    outputs
        Names of the outputs to read (default: every output).
    """
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    unzipdir = extract(str(fmu))
    md = read_model_description(unzipdir)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    in_vr = [vr[n] for n in _names(md, "input")]
    out_vr = [vr[n] for n in (outputs or _names(md, "output"))]
    dt = md.defaultExperiment.stepSize
    dt = float(dt)
    u = np.asarray(u, dtype=float).reshape(len(u), -1)
    sizes = {v.valueReference: int(v.dimensions[0].start) for v in md.modelVariables if v.dimensions}
    y = np.empty((len(u), sum(sizes.get(v, 1) for v in out_vr)))
    fmu_ = _Fmi3AsFmi2(md, unzipdir, sizes) if md.fmiVersion.startswith("3") else \
        FMU2Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="fmpy")
    fmu_.instantiate()
    try:
        fmu_.setupExperiment(startTime=0.0)
        for name, value in (params or {}).items():
            fmu_.setReal([vr[name]], [value])
        fmu_.enterInitializationMode()
        fmu_.exitInitializationMode()
        t = 0.0
        for k in range(len(u)):
            fmu_.setReal(in_vr, u[k].tolist())
            if protocol == "before":
                y[k] = fmu_.getReal(out_vr)
                fmu_.doStep(k * dt, dt)
            elif protocol == "accumulating":
                y[k] = fmu_.getReal(out_vr)
                fmu_.doStep(t, dt)
                t += dt
            else:
                fmu_.doStep(k * dt, dt)
                y[k] = fmu_.getReal(out_vr)
        if protocol == "accumulating":
            # the master's stop time, len(u) * dt, is not where its accumulated time arrived: it steps the rest
            if len(u) * dt > t:
                fmu_.doStep(t, len(u) * dt - t)
            y = np.vstack([y, fmu_.getReal(out_vr)])
        fmu_.terminate()
    finally:
        fmu_.freeInstance()
    return y


def _libcosim_steps(execution, index: int, in_vr: list[int], out_vr: list[int], u: np.ndarray) -> np.ndarray:
    """Step a libcosim execution once per row of ``u`` (the inputs overridden), the outputs read after each step."""
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver

    manipulator = CosimManipulator.create_override()
    execution.add_manipulator(manipulator)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    u = np.asarray(u, dtype=float).reshape(len(u), -1)
    y = np.empty((len(u), len(out_vr)))
    for k in range(len(u)):
        manipulator.slave_real_values(index, in_vr, u[k].tolist())
        if not execution.step():
            raise RuntimeError(f"libcosim step {k} failed")
        y[k] = observer.last_real_values(index, out_vr)
    return y


def cosim_outputs(fmu: str | os.PathLike, u: np.ndarray, *,
                  params: Mapping[str, float] | None = None) -> np.ndarray:
    """Outputs recorded by libcosim (the OSP C++ master) after each step ("after" protocol)."""
    from fmpy import read_model_description
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimSlave import CosimLocalSlave

    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    in_vr = [vr[n] for n in _names(md, "input")]
    out_vr = [vr[n] for n in _names(md, "output")]
    dt_ns = round(float(md.defaultExperiment.stepSize) * 1e9)
    execution = CosimExecution.from_step_size(dt_ns)
    slave = CosimLocalSlave(fmu_path=str(fmu), instance_name="beam")
    index = execution.add_local_slave(slave)
    for name, value in (params or {}).items():
        execution.real_initial_value(index, vr[name], value)
    return _libcosim_steps(execution, index, in_vr, out_vr, u)


def ssp_outputs(ssd: str | os.PathLike, fmu: str | os.PathLike, u: np.ndarray, step: float | None = None
                ) -> np.ndarray:
    """Outputs recorded by libcosim after each step ("after" protocol) of the system an SSP's ``ssd`` file
    describes (its parameter set bound by the package, nothing set here); ``fmu`` is the package's FMU (for the
    value references).  Without ``step`` the execution is made as a user makes it, from the file alone (its
    default experiment's base step)."""
    from fmpy import read_model_description
    from libcosimpy.CosimExecution import CosimExecution

    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    in_vr = [vr[n] for n in _names(md, "input")]
    out_vr = [vr[n] for n in _names(md, "output")]
    execution = (CosimExecution.from_ssp_file(str(ssd)) if step is None
                 else CosimExecution.from_ssp_file(str(ssd), round(step * 1e9)))
    index = execution.slave_index_from_instance_name("beam")
    return _libcosim_steps(execution, index, in_vr, out_vr, u)


def ecos_outputs(fmu: str | os.PathLike, u: np.ndarray, *,
                 params: Mapping[str, float] | None = None) -> np.ndarray:
    """Outputs read after each step ("after" protocol) in ecos (ecospy: a second C++ co-simulation master).

    ecospy's library needs oneTBB (``libtbb.so.12``); the ``tbb`` wheel puts it in the environment's ``lib``,
    which is not on the loader's path, so it is loaded (globally) first.
    """
    import ctypes
    import sys

    from fmpy import read_model_description

    ctypes.CDLL(os.path.join(sys.prefix, "lib", "libtbb.so.12"), mode=ctypes.RTLD_GLOBAL)
    from ecospy import EcosSimulation, EcosSimulationStructure

    md = read_model_description(str(fmu))
    ins, outs = _names(md, "input"), _names(md, "output")
    structure = EcosSimulationStructure()
    structure.add_model("beam", str(fmu))
    if params:
        structure.add_parameter_set("p", {f"beam::{k}": float(v) for k, v in params.items()})
    u = np.asarray(u, dtype=float).reshape(len(u), -1)
    y = np.empty((len(u), len(outs)))
    with EcosSimulation(structure=structure, step_size=float(md.defaultExperiment.stepSize)) as sim:
        sim.init(parameter_set="p" if params else None)
        for k in range(len(u)):
            for name, value in zip(ins, u[k]):
                sim.set_real(f"beam::{name}", float(value))
            sim.step()
            y[k] = [sim.get_real(f"beam::{name}") for name in outs]
    return y


def compile_host(out_dir: Path, fmi: int = 2, flags: Sequence[str] = ("-O2",)) -> Path:
    """Compile the plain C master of FMI version ``fmi`` with gcc (FMI 3.0's against the standard's headers as
    fmpy ships them)."""
    import fmpy

    exe = Path(out_dir) / f"fmi{fmi}_host"
    headers = ["-I", str(Path(fmpy.__file__).parent / "c-code")] if fmi == 3 else []
    subprocess.run(["gcc", *flags, "-Wall", *headers, "-o", str(exe), str(HOST_SOURCE[fmi]), "-ldl"], check=True,
                   capture_output=True, text=True)
    return exe


def host_run(exe: Path, fmu: str | os.PathLike, u: np.ndarray, work: Path, *,
             params: Mapping[str, float] | None = None, step: float | None = None,
             env: Mapping[str, str] | None = None, wrapper: Sequence[str] = (),
             timeout: float = 120, checkpoint: int | None = None) -> subprocess.CompletedProcess:
    """Run the C master on an extracted copy of ``fmu`` ("before" protocol); an FMI 3.0 FMU needs the FMI 3.0
    master (its array outputs are read whole, written ``VRxN``).

    ``wrapper`` prefixes the command (e.g. ``["valgrind"]``); ``checkpoint`` K: the state is saved and serialised
    before point K and, after the run, restored and the points from K run again (lines prefixed ``R``).
    """
    from fmpy import extract, read_model_description

    unzipdir = Path(extract(str(fmu), unzipdir=str(Path(work) / "unzipped")))
    md = read_model_description(str(unzipdir))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    three = md.fmiVersion.startswith("3")
    in_vr = [str(vr[n]) for n in _names(md, "input")]
    out_vr = [f"{v.valueReference}x{int(v.dimensions[0].start)}" if three and v.dimensions else str(v.valueReference)
              for v in md.modelVariables if v.causality == "output"]
    u = np.asarray(u, dtype=float).reshape(len(u), -1)
    inputs = Path(work) / "inputs.txt"
    np.savetxt(inputs, u, fmt="%.17g")
    library = (unzipdir / "binaries" / ("x86_64-linux" if three else "linux64")
               / f"{md.coSimulation.modelIdentifier}.so")
    resources = str(unzipdir / "resources") + os.sep if three else (unzipdir / "resources").as_uri()
    cmd = [*wrapper, str(exe), str(library), md.guid, resources,
           repr(float(step if step is not None else md.defaultExperiment.stepSize)), str(len(u)), str(inputs),
           ",".join(in_vr) or "-", ",".join(out_vr) or "-"]
    cmd += [f"{vr[k]}={v!r}" for k, v in (params or {}).items()]
    cmd += [f"@{checkpoint}"] if checkpoint is not None else []
    # no Python variables at all; OpenBLAS's kernel choice (OPENBLAS_CORETYPE, set on some processors) is passed
    # on, so that the host's process and fmpy's reference use the same BLAS kernel: without it the two differ by
    # 1e-11 relative (measured on a Haswell-pinned machine), the kernels' rounding, not the FMU's
    clean_env = {"PATH": "/usr/bin:/bin", **{k: v for k, v in os.environ.items() if k.startswith("OPENBLAS_")}} \
        if env is None else dict(env)
    return subprocess.run(cmd, capture_output=True, text=True, env=clean_env, timeout=timeout)


def memcheck_replay(fmu: str | os.PathLike, u: np.ndarray, work: Path, checkpoint: int) -> list[str]:
    """The C master of the FMU's version (``-O1 -g``) under valgrind's memcheck with full leak checking, a
    checkpoint serialised before point ``checkpoint`` and replayed: returns the run's output lines after asserting
    0 errors, exit 0 and the replay equal to the run from the checkpoint on (``pytest.skip`` without valgrind)."""
    import shutil

    import pytest
    from fmpy import read_model_description

    if shutil.which("valgrind") is None:
        pytest.skip("valgrind is not installed")
    fmi = 3 if read_model_description(str(fmu)).fmiVersion.startswith("3") else 2
    proc = host_run(compile_host(Path(work), fmi=fmi, flags=("-O1", "-g")), fmu, u, Path(work) / "run",
                    checkpoint=checkpoint, timeout=600,
                    wrapper=["valgrind", "--leak-check=full", "--errors-for-leak-kinds=definite,indirect",
                             "--error-exitcode=99", "--num-callers=30"])
    assert "ERROR SUMMARY: 0 errors" in proc.stderr, proc.stderr[-3000:]
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    assert [ln[2:] for ln in lines if ln.startswith("R ")] == lines[checkpoint:len(u)]
    return lines


def started_slave(md, unzipdir: str, name: str, version: int = 2):
    """An fmpy slave of the extracted FMU (``FMU2Slave`` or ``FMU3Slave``) instantiated and through its
    initialisation at time 0, its parameters at their start values."""
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    cls = FMU2Slave if version == 2 else FMU3Slave
    f = cls(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=name)
    f.instantiate()
    if version == 2:
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
    else:
        f.enterInitializationMode(startTime=0.0)
    f.exitInitializationMode()
    return f


def lifecycle(fmu: str | os.PathLike, cycles: int) -> dict[str, float]:
    """RSS growth over ``cycles`` load/instantiate/reset/free cycles (after 100 warm-up cycles).

    Each cycle loads the FMU's library (fmpy's ``FMU2Slave``), instantiates,
    resets and frees the instance (which unloads the library).  The warm-up
    lets allocator arenas and import caches settle.
    """
    import psutil
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    unzipdir = extract(str(fmu))
    md = read_model_description(unzipdir)

    def cycle() -> None:
        f = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="cycle")
        f.instantiate()
        try:
            f.reset()
        finally:
            f.freeInstance()

    proc = psutil.Process()
    for _ in range(100):
        cycle()
    rss0 = proc.memory_info().rss
    for _ in range(cycles):
        cycle()
    return {"cycles": cycles, "rss_growth_mb": (proc.memory_info().rss - rss0) / 2**20,
            "sys_path_entries": len(sys.path)}


def _params(items: Sequence[str]) -> dict[str, float]:
    out = {}
    for item in items:
        name, value = item.split("=", 1)
        out[name] = float(value)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("fmpy")
    a.add_argument("fmu")
    a.add_argument("inputs")
    a.add_argument("out")
    a.add_argument("--after", action="store_true")
    a.add_argument("--param", action="append", default=[])
    b = sub.add_parser("cosim")
    b.add_argument("fmu")
    b.add_argument("inputs")
    b.add_argument("out")
    b.add_argument("--param", action="append", default=[])
    e = sub.add_parser("ecos")
    e.add_argument("fmu")
    e.add_argument("inputs")
    e.add_argument("out")
    e.add_argument("--param", action="append", default=[])
    c = sub.add_parser("two")
    c.add_argument("fmu_a")
    c.add_argument("fmu_b")
    c.add_argument("inputs")
    c.add_argument("out_a")
    c.add_argument("out_b")
    s_ = sub.add_parser("ssp")
    s_.add_argument("ssd")
    s_.add_argument("fmu")
    s_.add_argument("inputs")
    s_.add_argument("out")
    s_.add_argument("step", type=float, nargs="?")
    d = sub.add_parser("lifecycle")
    d.add_argument("fmu")
    d.add_argument("cycles", type=int)
    args = p.parse_args(argv)
    if args.cmd == "fmpy":
        y = fmpy_outputs(args.fmu, np.load(args.inputs), params=_params(args.param),
                         protocol="after" if args.after else "before")
        np.save(args.out, y)
    elif args.cmd == "cosim":
        np.save(args.out, cosim_outputs(args.fmu, np.load(args.inputs), params=_params(args.param)))
    elif args.cmd == "ssp":
        np.save(args.out, ssp_outputs(args.ssd, args.fmu, np.load(args.inputs), args.step))
    elif args.cmd == "ecos":
        np.save(args.out, ecos_outputs(args.fmu, np.load(args.inputs), params=_params(args.param)))
    elif args.cmd == "two":
        u = np.load(args.inputs)
        _two_side_by_side(args.fmu_a, args.fmu_b, u, args.out_a, args.out_b)
    else:
        print(json.dumps(lifecycle(args.fmu, args.cycles)))
    return 0


def _two_side_by_side(fmu_a: str, fmu_b: str, u: np.ndarray, out_a: str, out_b: str) -> None:
    """Step two FMUs alternately, both instances alive at once, in one process."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    slaves = []
    for path in (fmu_a, fmu_b):
        unzipdir = extract(path)
        md = read_model_description(unzipdir)
        vr = {v.name: v.valueReference for v in md.modelVariables}
        f = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName=Path(path).stem)
        f.instantiate()
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        f.exitInitializationMode()
        slaves.append((f, [vr[n] for n in _names(md, "input")], [vr[n] for n in _names(md, "output")],
                       float(md.defaultExperiment.stepSize)))
    results = [np.empty((len(u), len(s[2]))) for s in slaves]
    try:
        for k in range(len(u)):
            for (f, in_vr, out_vr, dt), y in zip(slaves, results):
                f.setReal(in_vr, [float(u[k, 0])] * len(in_vr))
                y[k] = f.getReal(out_vr)
                f.doStep(k * dt, dt)
    finally:
        for f, *_ in slaves:
            f.terminate()
            f.freeInstance()
    np.save(out_a, results[0])
    np.save(out_b, results[1])


if __name__ == "__main__":
    raise SystemExit(main())
