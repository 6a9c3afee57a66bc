"""The standalone C FMU (``fmu_build.standalone``): no Python at run time, same model as ``ebb_model``.

References: ``ebb_model.simulate`` of the same config and parameters (and ``ebb simulate --param``), the
pythonfmu FMU, the plain C master run with an empty environment, libcosim, and for model exchange the exact
solution of the same modal ODE (matrix exponential).  The agreement with the Python model is limited by the
round-off of the two eigen-solvers (LAPACK there, Cholesky + Jacobi here): measured 2e-11 … 7e-11 on these
records; two LAPACK drivers in Python itself differ by about as much (see docs/fmu.md, "Standalone FMU").
"""
from __future__ import annotations

import ctypes
import json
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla

import fmpy
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

HOSTS = Path(__file__).resolve().parent / "fmu_hosts"
sys.path.insert(0, str(HOSTS))
from fmu_configs import ROOT, SEED_TOML, mixed_config  # noqa: E402
from fmu_loops import compile_host, fmpy_outputs, host_run, started_slave  # noqa: E402

from ebb_model import assemble, config_from_dict, load_config, simulate  # noqa: E402
from ebb_cli import main  # noqa: E402
from ebb_model.exact.exact_modal import modal_matrices  # noqa: E402
from fmu_build import build_fmu  # noqa: E402
from fmu_build.standalone import build_standalone_fmu  # noqa: E402
from fmu_build.standalone.description import C_SOURCES  # noqa: E402

LOOPS = HOSTS / "fmu_loops.py"
#: against the Python model: the C core solves the pencil assembled with the parameter set's own values
#: (EI·B₄ − N·D₂ …) with its own eigen-solver, the Python core its family's unit pencil (ebb_model.modal.mode_family)
#: scaled — and on a beam under N without attachments (the seed) continued in U by a Chebyshev panel
#: (ebb_model.modal.mode_continuation), whose first mode's ω² is 2.9e-10 off a 40-digit solution of the Richardson pair
#: (the C core's 1e-14): a phase that grows with the record, 3e-10 of the outputs over 500 samples, 6e-10 over
#: 1,000 (this file's records), 2.1e-9 over 3,000.  Where both solve directly (the mixed config) the C route's own
#: round-off is left, measured as the spread of the outputs when every stiffness and mass is scaled by a few ulps:
#: 2.1e-10 on the seed; two such roundings differ by up to twice that — measured 1.8e-10 (a diagnosed model)
RTOL_CORE = 1e-9
RTOL_SAME = 1e-12      # the same binary under different masters


def _rel_err(y: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.max(np.abs(y - ref), axis=0) / np.max(np.abs(ref), axis=0)))


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    d = tmp_path_factory.mktemp("cfmus")
    return {"seed": build_standalone_fmu(SEED_TOML, d / "seed.fmu"),
            "mixed": build_standalone_fmu(config_from_dict(mixed_config()), d / "mixed.fmu")}


@pytest.fixture(scope="module")
def configs():
    return {"seed": load_config(SEED_TOML), "mixed": config_from_dict(mixed_config())}


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    return compile_host(tmp_path_factory.mktemp("host"))


def _state_matrix(f, nx: int) -> np.ndarray:
    """The model-exchange system matrix, column by column from unit states through ``fmi2GetDerivatives``
    (frees the instance ``f``)."""
    ptr = ctypes.POINTER(ctypes.c_double)
    A = np.zeros((nx, nx))
    for j in range(nx):
        x = np.zeros(nx)
        x[j] = 1.0
        dx = np.zeros(nx)
        f.setContinuousStates(x.ctypes.data_as(ptr), nx)
        f.getDerivatives(dx.ctypes.data_as(ptr), nx)
        A[:, j] = dx
    f.freeInstance()
    return A


def _inputs(cfg, n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal((n, len(cfg.actuators)))


# ---------------------------------------------------------------------------------------------- the archive
@pytest.mark.parametrize("name", ["seed", "mixed"])
def test_validate_fmu_reports_nothing(fmus, name):
    assert validate_fmu(str(fmus[name])) == []


def test_archive_has_both_interfaces_sources_and_no_python(fmus, tmp_path):
    md = fmpy.read_model_description(str(fmus["seed"]))
    assert md.modelExchange.modelIdentifier == md.coSimulation.modelIdentifier
    assert md.numberOfContinuousStates == 2 * 50            # (q, q') of the 50 Richardson modes
    with zipfile.ZipFile(fmus["seed"]) as zf:
        names = set(zf.namelist())
        texts = {n: zf.read(n) for n in names}
    ident = md.coSimulation.modelIdentifier
    assert {f"binaries/linux64/{ident}.so", "sources/buildDescription.xml", "sources/ebb_config.h",
            "sources/ebb_model.c", "sources/ebb_fd.c", "sources/ebb_theta.c", "sources/ebb_linalg.c",
            "sources/ebb_instance.c", "sources/ebb_derivatives.c", "sources/ebb_state.c", "sources/ebb_fmi2.c",
            "sources/ebb_beam.h", "sources/ebb_instance.h"} <= names
    assert "sources/ebb_fmi3.c" not in names and "sources/ebb_fmi3.h" not in names
    assert not any(n.endswith(".py") for n in names)
    # no absolute path of the repository or the interpreter in any file, binary included
    for needle in (str(ROOT).encode(), sys.prefix.encode(), b"/work/"):
        assert not [n for n, t in texts.items() if needle in t], needle
    # the generated header holds the structure, not assembled matrices: a handful of numbers
    header = texts["sources/ebb_config.h"].decode()
    numbers = [v for v in re.findall(r"(?<![\w.])-?\d+\.\d+(?:e[-+]?\d+)?", header) if float(v) != 0.0]
    assert len(numbers) < 40, numbers
    # readelf: nothing but the C library and libm
    so = tmp_path / "beam.so"
    so.write_bytes(texts[f"binaries/linux64/{ident}.so"])
    dyn = subprocess.run(["readelf", "-d", str(so)], capture_output=True, text=True, check=True).stdout
    needed = set(re.findall(r"\(NEEDED\).*\[(.+?)\]", dyn))
    assert needed and needed <= {"libm.so.6", "libc.so.6"}, needed
    assert not re.search(r"python|numpy|numba", dyn, re.I)
    exported = subprocess.run(["nm", "-D", "--defined-only", str(so)], capture_output=True, text=True,
                              check=True).stdout.split()
    assert "fmi2DoStep" in exported and "fmi2GetDerivatives" in exported and "ebb_model_build" not in exported


def test_sources_compile_on_their_own(fmus, tmp_path):
    """What a user on another platform does: compile ``sources/`` (C99 + libm) and run it."""
    with zipfile.ZipFile(fmus["mixed"]) as zf:
        zf.extractall(tmp_path / "fmu")
    src = tmp_path / "fmu" / "sources"
    files = re.findall(r'SourceFile name="([^"]+)"', (src / "buildDescription.xml").read_text())
    lib = tmp_path / "fmu" / "binaries" / "linux64"
    ident = fmpy.read_model_description(str(tmp_path / "fmu")).coSimulation.modelIdentifier
    (lib / f"{ident}.so").unlink()
    subprocess.run(["gcc", "-std=c99", "-pedantic", "-Wall", "-Werror", "-O1", "-shared", "-fPIC", "-o",
                    str(lib / f"{ident}.so"), *files, "-lm"], cwd=src, check=True, capture_output=True)
    cfg = config_from_dict(mixed_config())
    u = _inputs(cfg, 200, 3)
    y = _fmpy_dir(tmp_path / "fmu", u)
    assert _rel_err(y, simulate(assemble(cfg), u).outputs) < RTOL_CORE


def _fmpy_dir(unzipdir: Path, u: np.ndarray) -> np.ndarray:
    """``fmpy_outputs`` for an already extracted FMU."""
    from fmpy.fmi2 import FMU2Slave

    md = fmpy.read_model_description(str(unzipdir))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    ins = [vr[v.name] for v in md.modelVariables if v.causality == "input"]
    outs = [vr[v.name] for v in md.modelVariables if v.causality == "output"]
    f = FMU2Slave(guid=md.guid, unzipDirectory=str(unzipdir), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="own")
    f.instantiate()
    f.setupExperiment(startTime=0.0)
    f.enterInitializationMode()
    f.exitInitializationMode()
    dt = float(md.defaultExperiment.stepSize)
    y = np.empty((len(u), len(outs)))
    for k in range(len(u)):
        f.setReal(ins, u[k].tolist())
        y[k] = f.getReal(outs)
        f.doStep(k * dt, dt)
    f.terminate()
    f.freeInstance()
    return y


# ------------------------------------------------------------------------------------------- co-simulation
@pytest.mark.parametrize("name", ["seed", "mixed"])
def test_cosim_through_fmpy_equals_core(fmus, configs, name):
    """Displacement (seed, mixed), velocity and acceleration (mixed: elastic end, point mass, damping)."""
    cfg = configs[name]
    u = _inputs(cfg, 1000, 1)
    y = fmpy_outputs(fmus[name], u)
    assert _rel_err(y, simulate(assemble(cfg), u).outputs) <= RTOL_CORE


def test_cosim_equals_pythonfmu_fmu(fmus, configs, tmp_path):
    u = _inputs(configs["seed"], 600, 5)
    np.save(tmp_path / "u.npy", u)
    python_fmu = build_fmu(SEED_TOML, tmp_path / "py.fmu")
    proc = subprocess.run([sys.executable, str(LOOPS), "fmpy", str(python_fmu), str(tmp_path / "u.npy"),
                           str(tmp_path / "y.npy")], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert _rel_err(fmpy_outputs(fmus["seed"], u), np.load(tmp_path / "y.npy")) <= RTOL_CORE


def test_parameters_set_through_the_host_as_ebb_simulate_param(fmus, configs, tmp_path, capsys):
    cfg = configs["seed"]
    params = {"EI": 14.0, "N": 20.0, "c": 0.3, "rhoA": 1.1}
    u = _inputs(cfg, 500, 7)
    y = fmpy_outputs(fmus["seed"], u, params=params)
    nominal = fmpy_outputs(fmus["seed"], u)
    assert _rel_err(y, nominal) > 0.1                        # the parameters do change the model
    inp = tmp_path / "in.csv"
    np.savetxt(inp, np.column_stack([np.arange(len(u)) * cfg.time.dt, u]), delimiter=",", header="time,F1",
               comments="", fmt="%.17g")
    args = ["simulate", str(SEED_TOML), "--input", str(inp), "--out", str(tmp_path / "out.csv")]
    assert main(args + [a for k, v in params.items() for a in ("--param", f"{k}={v!r}")]) == 0
    ref = np.loadtxt(tmp_path / "out.csv", delimiter=",", skiprows=1)[:, 1:]
    assert _rel_err(y, ref) <= RTOL_CORE


def test_step_of_several_samples_holds_the_input(fmus, configs):
    """``doStep(h = 3 dt)`` equals three steps of ``dt`` with the input held."""

    md = fmpy.read_model_description(str(fmus["mixed"]))
    unzip = fmpy.extract(str(fmus["mixed"]))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    dt = configs["mixed"].time.dt
    u = _inputs(configs["mixed"], 20, 8)

    def run(n: int) -> np.ndarray:
        f = started_slave(md, unzip, f"n{n}")
        out = []
        for k in range(len(u)):
            f.setReal([vr["F1"], vr["F2"]], u[k].tolist())
            for j in range(3 // n):
                f.doStep((3 * k + j * n) * dt, n * dt)
            out.append(f.getReal([vr["d1"], vr["v1"], vr["a1"]]))
        f.freeInstance()
        return np.array(out)

    assert _rel_err(run(3), run(1)) <= RTOL_SAME


def test_plain_c_host_with_an_empty_environment(fmus, configs, host, tmp_path):
    for name in ("seed", "mixed"):
        cfg = configs[name]
        u = _inputs(cfg, 800, 21)
        params = {"EI": 11.0, "N": 30.0} if name == "seed" else {}
        proc = host_run(host, fmus[name], u, tmp_path / name, params=params, env={})
        assert proc.returncode == 0, proc.stderr[-2000:]
        y = np.loadtxt(proc.stdout.splitlines(), ndmin=2)
        assert _rel_err(y, simulate(assemble(cfg, params), u).outputs) <= RTOL_CORE
        assert _rel_err(y, fmpy_outputs(fmus[name], u, params=params)) <= RTOL_SAME


@pytest.mark.parametrize("name", ["seed", "mixed"])
def test_libcosim_equals_fmpy(fmus, configs, tmp_path, name):
    u = _inputs(configs[name], 600, 4)
    np.save(tmp_path / "u.npy", u)
    proc = subprocess.run([sys.executable, str(LOOPS), "cosim", str(fmus[name]), str(tmp_path / "u.npy"),
                           str(tmp_path / "y.npy")], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    y = np.load(tmp_path / "y.npy")
    assert _rel_err(y, fmpy_outputs(fmus[name], u, protocol="after")) <= RTOL_SAME


@pytest.mark.parametrize("name", ["seed", "mixed"])
def test_ecos_equals_fmpy(fmus, configs, tmp_path, name):
    """A second independent importer: ecos (ecospy from PyPI, its own C++ FMI 2.0 master), same loop."""
    u = _inputs(configs[name], 600, 5)
    params = {"EI": 11.0, "N": 30.0} if name == "seed" else {}
    np.save(tmp_path / "u.npy", u)
    cmd = [sys.executable, str(LOOPS), "ecos", str(fmus[name]), str(tmp_path / "u.npy"), str(tmp_path / "y.npy")]
    proc = subprocess.run(cmd + [f"--param={k}={v}" for k, v in params.items()], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    y = np.load(tmp_path / "y.npy")
    assert _rel_err(y, fmpy_outputs(fmus[name], u, params=params, protocol="after")) <= RTOL_SAME


# ---------------------------------------------------------------------------------------------- errors
def test_errors_are_fmi2error_naming_the_cause(fmus, host, tmp_path):
    u = np.zeros((5, 1))
    bad_step = host_run(host, fmus["seed"], u, tmp_path / "a", step=1.5e-4, env={})
    assert bad_step.returncode == 3 and "fmi2DoStep failed with status 3" in bad_step.stderr
    assert "multiple of the sample time" in bad_step.stderr
    for params, name in (({"EI": -1.0}, "EI"), ({"rhoA": float("nan")}, "rhoA"), ({"c": -2.0}, "c"),
                         ({"N": -2000.0}, "N"),               # N: compression beyond the buckling load
                         ({"EI": 1e300}, "EI"), ({"rhoA": 1e-300}, "rhoA")):   # the API's magnitude limits
        proc = host_run(host, fmus["seed"], u, tmp_path / name, params=params, env={})
        assert proc.returncode == 3, proc.stderr
        assert "fmi2ExitInitializationMode failed with status 3" in proc.stderr
        assert f" {name} " in proc.stderr, proc.stderr
    nan_input = np.array([[0.0], [np.nan], [0.0]])
    proc = host_run(host, fmus["seed"], nan_input, tmp_path / "nan", env={})
    assert proc.returncode == 3 and "fmi2SetReal failed with status 3" in proc.stderr
    assert "F1" in proc.stderr and "not a finite number" in proc.stderr


def test_the_c_model_accepts_the_magnitudes_the_api_accepts():
    from ebb_model.acquisition.antialias import MAX_ORDER
    from ebb_model.parameter_values import MAX_MAGNITUDE, MIN_POSITIVE
    from fmu_build.standalone.builder import SOURCE_DIR

    header = (SOURCE_DIR / "ebb_beam.h").read_text()
    defined = dict(re.findall(r"#define (EBB_MAX_MAGNITUDE|EBB_MIN_POSITIVE|EBB_MAX_FILTER) (\S+)", header))
    assert float(defined["EBB_MAX_MAGNITUDE"]) == MAX_MAGNITUDE and float(defined["EBB_MIN_POSITIVE"]) == MIN_POSITIVE
    assert int(defined["EBB_MAX_FILTER"]) == MAX_ORDER       # the C model's buffers hold the highest filter order


def test_errors_through_fmpy(fmus):
    with pytest.raises(FMICallException):
        fmpy_outputs(fmus["seed"], np.zeros((3, 1)), params={"EI": 0.0})
    with pytest.raises(FMICallException):
        fmpy_outputs(fmus["seed"], np.array([[1.0], [np.inf]]))


# -------------------------------------------------------------------------------------------- model exchange
def _continuous_reference(cfg, u: np.ndarray, dt: float, n: int) -> np.ndarray:
    """Outputs of the semi-discrete modal ODE under a constant force, exact (matrix exponential)."""
    mm = modal_matrices(cfg, cfg.parameter_values())
    k = mm.frequencies2.size
    A = np.block([[np.zeros((k, k)), np.eye(k)], [-np.diag(mm.frequencies2), -mm.Cm]])
    B = np.vstack([np.zeros_like(mm.Fm), mm.Fm])
    aug = np.zeros((2 * k + 1, 2 * k + 1))
    aug[:2 * k, :2 * k] = A * dt
    aug[:2 * k, 2 * k] = B @ u * dt
    E = sla.expm(aug)
    x, ys = np.zeros(2 * k), []
    for _ in range(n + 1):
        ys.append(mm.C @ x + mm.D @ u)
        x = E[:2 * k, :2 * k] @ x + E[:2 * k, 2 * k]
    return np.array(ys)


def test_model_exchange_through_cvode_converges_to_the_continuous_reference(fmus, configs):
    """fmpy's CVode on the FMU's ODE: the error is of the order of the tolerance and shrinks with it.

    A force step (constant input): fmpy's ME loop holds each input sample over an output interval and lets
    CVode run past it, which would blur a comparison with a varying input by the host's own hold error.
    """
    cfg = configs["mixed"]
    dt, n = cfg.time.dt, 600
    force = np.array([1.0, -0.5])
    ref = _continuous_reference(cfg, force, dt, n)
    t = np.arange(n + 1) * dt
    signal = np.zeros(n + 1, dtype=[("time", float), ("F1", float), ("F2", float)])
    signal["time"], signal["F1"], signal["F2"] = t, force[0], force[1]
    errors = {}
    for rtol in (1e-6, 1e-9):
        res = simulate_fmu(str(fmus["mixed"]), fmi_type="ModelExchange", solver="CVode", relative_tolerance=rtol,
                           stop_time=t[-1], output_interval=dt, input=signal, output=["d1", "v1", "a1"])
        y = np.column_stack([res["d1"], res["v1"], res["a1"]])
        idx = np.round(res["time"] / dt).astype(int)
        errors[rtol] = _rel_err(y, ref[idx])
    assert errors[1e-6] < 1e-3 and errors[1e-9] < 1e-6, errors
    assert errors[1e-9] < errors[1e-6] / 30, errors


def test_model_exchange_derivatives_are_the_modal_system(fmus, configs):
    """``fmi2GetDerivatives`` at unit states: the columns of ``[[0, I], [-Λ, -C_m]]`` of the Python model."""
    cfg = configs["mixed"]
    f, md = _me_instance(fmus["mixed"])
    nx = md.numberOfContinuousStates
    A = _state_matrix(f, nx)
    mm = modal_matrices(cfg, cfg.parameter_values())
    k = nx // 2
    np.testing.assert_allclose(-np.diag(A[k:, :k]), mm.frequencies2, rtol=1e-9)
    # (modes are defined up to their sign: C_m up to a symmetric sign flip of rows and columns)
    np.testing.assert_allclose(np.abs(A[k:, k:]), np.abs(mm.Cm), atol=1e-9 * np.abs(mm.Cm).max())
    np.testing.assert_array_equal(A[:k, k:], np.eye(k))


# ------------------------------------------------------------------------- checkpoints and linearisation
def _cs_instance(fmu: Path, name: str = "cs"):
    from fmpy.fmi2 import FMU2Slave

    md = fmpy.read_model_description(str(fmu))
    f = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    f.instantiate()
    f.setupExperiment(startTime=0.0)
    f.enterInitializationMode()
    f.exitInitializationMode()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    return f, md, vr


def _run(f, ins, outs, u: np.ndarray, k0: int, dt: float) -> np.ndarray:
    y = []
    for k in range(k0, len(u)):
        f.setReal(ins, list(u[k]))
        y.append(f.getReal(outs))
        f.doStep(k * dt, dt)
    return np.array(y)


def test_the_model_description_declares_state_and_derivatives(fmus):
    md = fmpy.read_model_description(str(fmus["mixed"]))
    for iface in (md.coSimulation, md.modelExchange):
        assert iface.canGetAndSetFMUstate and iface.canSerializeFMUstate and iface.providesDirectionalDerivative


def test_a_state_saved_mid_run_continues_bit_identically(fmus, configs):
    """fmpy: ``fmi2GetFMUstate`` mid-run, the run continued, then the state set again (and serialised to bytes,
    deserialised, set in a second instance with other parameters meanwhile): the continuation is identical to
    the last bit."""
    cfg = configs["mixed"]
    dt = cfg.time.dt
    u = _inputs(cfg, 400, 31)
    f, md, vr = _cs_instance(fmus["mixed"])
    ins, outs = [vr[n] for n in cfg.input_names], [vr[n] for n in cfg.output_names]
    first = _run(f, ins, outs, u[:200], 0, dt)
    state = f.getFMUstate()
    blob = f.serializeFMUstate(state)
    rest = _run(f, ins, outs, u, 200, dt)
    f.setFMUstate(state)
    np.testing.assert_array_equal(_run(f, ins, outs, u, 200, dt), rest)
    f.freeFMUstate(state)
    g, _, _ = _cs_instance(fmus["mixed"], "second")
    g.setReal([vr["EI"]], [20.0])                     # another model meanwhile: the state brings its own back
    _run(g, ins, outs, u[:50], 0, dt)
    restored = g.deSerializeFMUstate(blob)
    g.setFMUstate(restored)
    np.testing.assert_array_equal(_run(g, ins, outs, u, 200, dt), rest)
    g.freeFMUstate(restored)
    assert _rel_err(np.vstack([first, rest]), simulate(assemble(cfg), u).outputs) <= RTOL_CORE
    for inst in (f, g):
        inst.terminate()
        inst.freeInstance()


def test_a_foreign_or_truncated_state_is_refused(fmus):
    f, _, _ = _cs_instance(fmus["mixed"])
    blob = f.serializeFMUstate(f.getFMUstate())
    with pytest.raises(FMICallException):
        f.deSerializeFMUstate(blob[:-8])
    with pytest.raises(FMICallException):
        f.deSerializeFMUstate(b"x" + blob[1:])
    g, _, _ = _cs_instance(fmus["seed"])
    with pytest.raises(FMICallException):            # another FMU's bytes (its GUID)
        g.deSerializeFMUstate(blob)
    f.freeInstance()
    g.freeInstance()


def test_the_plain_c_host_checkpoints_and_restores(fmus, configs, host, tmp_path):
    """The independent C master saves and serialises the state before point 300, runs on, deserialises and
    replays: the replayed lines are the original ones, character for character (%.17g)."""
    u = _inputs(configs["mixed"], 600, 33)
    proc = host_run(host, fmus["mixed"], u, tmp_path, env={}, checkpoint=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.splitlines()
    original, replay = lines[:600], [ln[2:] for ln in lines[600:]]
    assert len(replay) == 300 and replay == original[300:]


def test_directional_derivatives_are_the_fmus_own_finite_differences(fmus, configs):
    """Co-simulation: ∂y/∂u at a communication point (the realisation's D) equals the difference of the FMU's
    outputs for a changed input — exactly, the outputs being linear in the input (one unit step, round-off
    only).  Model exchange: ∂ẋ/∂x and ∂ẋ/∂u are the modal ODE's matrices, read column by column through
    ``fmi2GetDerivatives``."""
    cfg = configs["mixed"]
    f, md, vr = _cs_instance(fmus["mixed"])
    ins, outs = [vr[n] for n in cfg.input_names], [vr[n] for n in cfg.output_names]
    u = _inputs(cfg, 120, 35)
    _run(f, ins, outs, u, 0, cfg.time.dt)             # somewhere mid-run, not at rest
    u0 = np.array([0.3, -0.2])
    f.setReal(ins, list(u0))
    y0 = np.array(f.getReal(outs))
    J = np.column_stack([f.getDirectionalDerivative(outs, [i], [1.0]) for i in ins])
    for j, i in enumerate(ins):
        du = u0.copy()
        du[j] += 1.0
        f.setReal(ins, list(du))
        np.testing.assert_allclose(np.array(f.getReal(outs)) - y0, J[:, j], rtol=1e-9,
                                   atol=1e-12 * np.abs(J).max())
    assert np.abs(J[2, 0]) > 1.0                      # the accelerometer's feedthrough is there
    f.freeInstance()

    g, md = _me_instance(fmus["mixed"])
    nx = md.numberOfContinuousStates
    ders = [d.variable.valueReference for d in md.derivatives]      # in the order of the state vector
    states = [d.variable.derivative.valueReference for d in md.derivatives]
    Jx = np.column_stack([g.getDirectionalDerivative(ders, [s], [1.0]) for s in states])
    Ju = np.column_stack([g.getDirectionalDerivative(ders, [vr[n]], [1.0]) for n in cfg.input_names])
    Fm = modal_matrices(cfg, cfg.parameter_values()).Fm      # (modes up to their sign)
    k = nx // 2
    np.testing.assert_array_equal(Ju[:k], 0.0)
    np.testing.assert_allclose(np.abs(Ju[k:]), np.abs(Fm), rtol=1e-9, atol=1e-12 * np.abs(Fm).max())
    A = _state_matrix(g, nx)                          # (frees the instance)
    np.testing.assert_allclose(Jx, A, rtol=1e-12, atol=1e-12 * np.abs(A).max())


# -------------------------------------------------------------------------------------------- command line
def test_cli_build_standalone_and_its_bad_input(tmp_path, capsys):
    out = tmp_path / "beam.fmu"
    assert main(["build-fmu", str(SEED_TOML), "--standalone", "--out", str(out)]) == 0
    assert validate_fmu(str(out)) == []
    unstable = tmp_path / "unstable.toml"                      # compression beyond the buckling load
    unstable.write_text(SEED_TOML.read_text().replace("value = 50.0, bounds = [-100.0",
                                                      "value = -2000.0, bounds = [-3000.0"))
    for config, target, needle in ((unstable, tmp_path / "u.fmu", "N = -2000"),
                                   (SEED_TOML, tmp_path / "missing" / "x.fmu", "does not exist")):
        capsys.readouterr()
        assert main(["build-fmu", str(config), "--standalone", "--out", str(target)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("ebb build-fmu: error:") and needle in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["beam.fmu", "unstable.toml"]


def test_cli_export_writes_standalone_fmus(tmp_path, capsys):
    cfg = load_config(SEED_TOML)
    result = tmp_path / "result"
    result.mkdir()
    rhoA = cfg.parameters["rhoA"].value          # the config's third unknown, at its nominal value
    points = [{"parameters": {"EI": 12.0, "rhoA": rhoA, "N": 40.0}},
              {"parameters": {"EI": 9.0, "rhoA": rhoA, "N": 70.0}}]
    (result / "pareto.json").write_text(json.dumps({"config": cfg.to_dict(), "points": points,
                                                    "parameter_names": ["EI", "rhoA", "N"], "config_name": "seed"}))
    assert main(["export", str(result), "--points", "1", "--target", "standalone"]) == 0
    fmu = result / "export" / "point_1_standalone.fmu"
    assert fmu.is_file() and not (result / "export" / "point_1.fmu").exists()
    u = _inputs(cfg, 300, 11)
    ref = simulate(assemble(cfg, {"EI": 9.0, "N": 70.0}), u).outputs
    assert _rel_err(fmpy_outputs(fmu, u), ref) <= RTOL_CORE    # the point's values are the start values


def test_field_outputs_are_the_deflection_at_every_node(tmp_path):
    """``field=True``: ``w[0] … w[n+1]`` as displacement outputs at the grid nodes (as the pythonfmu FMU's)."""
    from ebb_model.assemble import field_config

    cfg = config_from_dict(mixed_config())
    fmu = build_standalone_fmu(cfg, tmp_path / "field.fmu", field=True)
    assert validate_fmu(str(fmu)) == []
    names = [v.name for v in fmpy.read_model_description(str(fmu)).modelVariables if v.causality == "output"]
    assert names == ["d1", "v1", "a1"] + [f"w[{i}]" for i in range(cfg.beam.nodes + 2)]
    u = _inputs(cfg, 300, 12)
    y = fmpy_outputs(fmu, u)
    ref = simulate(assemble(field_config(cfg)), u).outputs
    assert np.all(y[:, 3] == 0.0)                               # the pinned end does not move
    assert _rel_err(np.delete(y, 3, axis=1), np.delete(ref, 3, axis=1)) <= RTOL_CORE


def _me_instance(fmu: Path):
    from fmpy.fmi2 import FMU2Model

    md = fmpy.read_model_description(str(fmu))
    f = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                  modelIdentifier=md.modelExchange.modelIdentifier, instanceName="me")
    f.instantiate()
    f.setupExperiment(startTime=0.0)
    f.enterInitializationMode()
    f.exitInitializationMode()
    f.enterContinuousTimeMode()
    return f, md


def test_model_exchange_with_a_host_solver_and_a_continuous_input(fmus, configs):
    """A host's own solver (scipy's Radau) integrates the FMU's ODE under a continuous two-tone input; the
    outputs agree with the same ODE of the Python model solved to a tight tolerance, within the host's."""
    from scipy.integrate import solve_ivp

    cfg = configs["mixed"]
    f, md = _me_instance(fmus["mixed"])
    vr = {v.name: v.valueReference for v in md.modelVariables}
    ins, outs = [vr["F1"], vr["F2"]], [vr["d1"], vr["v1"], vr["a1"]]
    nx = md.numberOfContinuousStates
    ptr = ctypes.POINTER(ctypes.c_double)

    def u(t: float) -> list[float]:
        ramp = min(t / 0.01, 1.0)
        return [ramp * np.sin(2 * np.pi * 15 * t), 0.5 * ramp * np.cos(2 * np.pi * 40 * t)]

    def rhs(t: float, x: np.ndarray) -> np.ndarray:
        f.setTime(t)
        f.setReal(ins, u(t))
        x = np.ascontiguousarray(x)
        f.setContinuousStates(x.ctypes.data_as(ptr), nx)
        dx = np.empty(nx)
        f.getDerivatives(dx.ctypes.data_as(ptr), nx)
        return dx

    jac = np.column_stack([rhs(0.0, e) for e in np.eye(nx)])   # u(0) = 0: the columns of A
    t_out = np.arange(401) * cfg.time.dt
    sol = solve_ivp(rhs, (0.0, t_out[-1]), np.zeros(nx), method="Radau", t_eval=t_out, rtol=1e-8,
                    atol=1e-14, jac=jac)
    assert sol.success
    y = []
    for t, x in zip(t_out, sol.y.T):
        rhs(t, x)
        y.append(f.getReal(outs))
    f.freeInstance()

    mm = modal_matrices(cfg, cfg.parameter_values())
    k = mm.frequencies2.size
    A = np.block([[np.zeros((k, k)), np.eye(k)], [-np.diag(mm.frequencies2), -mm.Cm]])
    B = np.vstack([np.zeros_like(mm.Fm), mm.Fm])
    ref = solve_ivp(lambda t, x: A @ x + B @ u(t), (0.0, t_out[-1]), np.zeros(2 * k), method="Radau",
                    t_eval=t_out, rtol=1e-12, atol=1e-18, jac=A)
    y_ref = np.array([mm.C @ x + mm.D @ u(t) for t, x in zip(t_out, ref.y.T)])
    assert _rel_err(np.array(y), y_ref) < 1e-7                 # measured 5.5e-10 (rtol 1e-8)


def test_diagnosed_model_exports_a_standalone_fmu(tmp_path):
    """``export_corrected(..., targets=[..., "standalone"])`` (``ebb diagnose --target standalone``): the
    corrected beam in C."""
    from diagnosis.corrected.export import export_corrected
    from diagnosis.effects import AugmentedModel

    cfg = load_config(SEED_TOML)
    params = cfg.parameter_values() | {"EI": 10.5, "c": 0.2}
    files = export_corrected(AugmentedModel(cfg, params), tmp_path / "corrected", {"effect": "test"},
                             targets=["statespace", "standalone"])
    fmu = tmp_path / "corrected" / "corrected_standalone.fmu"
    assert fmu in files
    carries = json.loads((tmp_path / "corrected" / "corrected.json").read_text())["files"]
    assert "corrected_standalone.fmu" in carries
    u = _inputs(cfg, 300, 13)
    assert _rel_err(fmpy_outputs(fmu, u), simulate(assemble(cfg, params), u).outputs) <= RTOL_CORE


def test_failed_build_leaves_no_file(tmp_path, monkeypatch):
    import fmu_build.standalone.builder as sb
    from ebb_model.errors import FmuError

    monkeypatch.setattr(sb, "CFLAGS", sb.CFLAGS + ("-Werror=this-flag-does-not-exist",))
    with pytest.raises(FmuError, match="compiling the standalone FMU failed"):
        build_standalone_fmu(SEED_TOML, tmp_path / "x.fmu")
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------------- the seed's θ-scheme
def _theta_configs() -> dict[str, dict]:
    from fmu_configs import substep_config

    mixed = mixed_config()
    mixed["time"] |= {"scheme": "theta", "input": "foh", "substeps": 3}
    return {"substep": substep_config(), "mixed_theta": mixed}


@pytest.mark.parametrize("name", ["substep", "mixed_theta"])
def test_theta_scheme_equals_core(tmp_path, name):
    """``[time] scheme = "theta"``: sub-steps, straight-line force between samples, all sensor kinds."""
    from ebb_model.simulate import fast_model

    cfg = config_from_dict(_theta_configs()[name])
    fmu = build_standalone_fmu(cfg, tmp_path / "theta.fmu")
    assert validate_fmu(str(fmu)) == []
    u = _inputs(cfg, 1000, 2)
    y = fmpy_outputs(fmu, u)
    assert _rel_err(y, simulate(assemble(cfg), u).outputs) <= RTOL_CORE          # dense nodal realisation
    assert _rel_err(y, simulate(fast_model(cfg), u).outputs) <= RTOL_CORE        # what `ebb simulate` runs
    params = {"EI": 40.0, "c": 0.1} if name == "substep" else {"EI": 15.0, "N": 5.0}
    assert _rel_err(fmpy_outputs(fmu, u, params=params), simulate(assemble(cfg, params), u).outputs) <= RTOL_CORE


def test_theta_scheme_explicit_limit_names_theta(tmp_path, host):
    d = load_config(SEED_TOML).to_dict()
    d["time"] |= {"scheme": "theta", "theta": 0.0, "substeps": 4}
    fmu = build_standalone_fmu(config_from_dict(d), tmp_path / "explicit.fmu")
    proc = host_run(host, fmu, np.zeros((3, 1)), tmp_path / "run", params={"EI": 100.0}, env={})
    assert proc.returncode == 3 and "fmi2ExitInitializationMode failed with status 3" in proc.stderr
    assert "theta = 0 < 1/4" in proc.stderr and "EI = 100" in proc.stderr, proc.stderr


def test_theta_model_exchange_is_the_nodal_system(tmp_path):
    """Model exchange of a θ config: states are the nodal unknowns, ``q'' = M⁻¹(F u − C q' − K q)``."""
    from ebb_model.space.discretisation import discretise

    cfg = config_from_dict(_theta_configs()["mixed_theta"])
    f, md = _me_instance(build_standalone_fmu(cfg, tmp_path / "me.fmu"))
    nx = md.numberOfContinuousStates
    assert [v.name for v in md.modelVariables if v.causality == "local"][:2] == ["nodes.q[1]", "nodes.q[2]"]
    A = _state_matrix(f, nx)
    beam = discretise(cfg)
    k = nx // 2
    ref = np.linalg.solve(beam.M, np.hstack([beam.K, beam.C]))
    np.testing.assert_allclose(-A[k:], ref, atol=1e-10 * np.abs(ref).max())
    np.testing.assert_array_equal(A[:k, k:], np.eye(k))


def test_free_free_beam_takes_the_direct_eigenproblem(tmp_path):
    """A free–free beam's K is singular (rigid-body modes).  The C model then solves ``K ψ = ω² M ψ``, and so
    does the Python model (LAPACK's Cholesky of the refined grid's numerically singular K need not fail: the
    inverted problem put mode 3's ω² 2e-4 off before the Python model checked for it).  1e-9: the rigid modes'
    ω² are round-off (±1e-7) in both."""
    cfg = config_from_dict({
        "beam": {"length": 1.0, "nodes": 24, "left": "free", "right": "free"}, "time": {"dt": 2e-4},
        "parameters": {"EI": 10.0, "rhoA": 1.0, "c": 0.1, "eta": 1e-5},
        "actuators": [{"name": "F", "x": 0.2}],
        "sensors": [{"name": "a", "x": 0.9, "kind": "acceleration"}, {"name": "d", "x": 0.5},
                    {"name": "v", "x": 0.7, "kind": "velocity"}]})
    u = _inputs(cfg, 500, 1)
    y = fmpy_outputs(build_standalone_fmu(cfg, tmp_path / "ff.fmu"), u)
    assert _rel_err(y, simulate(assemble(cfg), u).outputs) <= 1e-9


def test_c_code_is_clean_under_address_and_undefined_behaviour_sanitizers(fmus, tmp_path):
    """The C master and the FMU's sources compiled with ``-fsanitize=address,undefined``: co-simulation with a
    3-sample step, parameters that make the damping non-proportional, and the θ-scheme, each with a checkpoint
    saved, serialised, deserialised and replayed; no report."""
    flags = ["-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=undefined"]
    host = tmp_path / "host_asan"
    probe = subprocess.run(["gcc", *flags, "-o", str(host), str(HOSTS / "fmi2_host.c"), "-ldl"],
                           capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"gcc has no sanitizer runtime here: {probe.stderr[-300:]}")
    theta = build_standalone_fmu(config_from_dict(_theta_configs()["substep"]), tmp_path / "theta.fmu")
    for name, fmu, params in (("seed", fmus["seed"], {"rhoI": 1e-3, "c": 0.5}), ("mixed", fmus["mixed"], {}),
                              ("theta", theta, {"EI": 45.0})):
        work = tmp_path / name
        unzip = Path(fmpy.extract(str(fmu), unzipdir=str(work / "src")))
        md = fmpy.read_model_description(str(unzip))
        subprocess.run(["gcc", "-std=c99", *flags, "-shared", "-fPIC", "-o",
                        str(unzip / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"),
                        *C_SOURCES[2], "-lm"], cwd=unzip / "sources", check=True,
                       capture_output=True)
        with zipfile.ZipFile(work / "asan.fmu", "w") as zf:
            for f in sorted(unzip.rglob("*")):
                if f.is_file():
                    zf.write(f, f.relative_to(unzip).as_posix())
        n_in = sum(v.causality == "input" for v in md.modelVariables)
        u = np.random.default_rng(3).standard_normal((60, n_in))
        step = 3 * float(md.defaultExperiment.stepSize)
        proc = host_run(host, work / "asan.fmu", u, work / "run", params=params, step=step,
                        env={"PATH": "/usr/bin:/bin"}, checkpoint=30)
        assert proc.returncode == 0, proc.stderr[-3000:]
        lines = proc.stdout.splitlines()
        assert [ln[2:] for ln in lines[60:]] == lines[30:60]
        assert "runtime error" not in proc.stderr and "AddressSanitizer" not in proc.stderr, proc.stderr[-3000:]


def test_two_standalone_fmus_and_a_pythonfmu_one_side_by_side(fmus, configs, tmp_path):
    """Both instances alive and stepped alternately in one process; then the C FMU next to the pythonfmu FMU."""
    u = _inputs(configs["seed"], 300, 9)
    np.save(tmp_path / "u.npy", u)
    python_fmu = build_fmu(config_from_dict(mixed_config()), tmp_path / "py_mixed.fmu")
    for other, name in ((fmus["mixed"], "c"), (python_fmu, "py")):
        a, b = tmp_path / f"a_{name}.npy", tmp_path / f"b_{name}.npy"
        proc = subprocess.run([sys.executable, str(LOOPS), "two", str(fmus["seed"]), str(other),
                               str(tmp_path / "u.npy"), str(a), str(b)], capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert _rel_err(np.load(a), simulate(assemble(configs["seed"]), u).outputs) <= RTOL_CORE
        assert _rel_err(np.load(b), simulate(assemble(configs["mixed"]), np.hstack([u, u])).outputs) <= RTOL_CORE


def test_a_master_that_accumulates_float_time(fmus):
    """As for the pythonfmu FMU (``tests/test_fmu_hosts.py``): time accumulated in floating point, 2000 steps of
    1e-4 s, then the master's 5.7e-15 s remainder to its stop time — taken as no step; outputs equal the
    integer-time loop's to the last digit, and after the remainder those after the last full step."""
    u = np.random.default_rng(5).standard_normal((2000, 1))
    y = fmpy_outputs(fmus["seed"], u, protocol="accumulating")
    assert _rel_err(y[:-1], fmpy_outputs(fmus["seed"], u)) <= RTOL_SAME
    assert np.array_equal(y[-1], fmpy_outputs(fmus["seed"], u, protocol="after")[-1])


def test_model_exchange_through_fmpys_simulate_fmu_with_the_force_held(fmus, configs):
    """fmpy's ``simulate_fmu`` as a model-exchange master: the sampled force given as steps
    (:func:`fmu_build.held_input.held_input`, each sample an event) reproduces the model with the force held
    (``time.input = "zoh"``).  Measured on 600 samples at relative tolerance 1e-8: 3.8e-7 of the peak; the bound is
    5e-6 — CVode's local tolerance does not bound its global error, which is measured here, with room for the
    machine's rounding.  Given as plain samples (fmpy interpolates them linearly, no events) it was 3.4 % off and
    failed at 1e-8."""
    from fmu_build.held_input import at_samples, held_input

    cfg = configs["seed"]
    d = cfg.to_dict()
    d["time"]["input"] = "zoh"
    u = np.random.default_rng(3).standard_normal((600, 1))
    ref = simulate(assemble(config_from_dict(d)), u).outputs
    dt = cfg.time.dt
    res = simulate_fmu(str(fmus["seed"]), fmi_type="ModelExchange", input=held_input(u, dt, cfg.input_names),
                       stop_time=(len(u) - 1) * dt, output_interval=dt, relative_tolerance=1e-8)
    y = at_samples(res, cfg.output_names)
    assert y.shape == ref.shape
    assert _rel_err(y, ref) <= 5e-6, _rel_err(y, ref)
