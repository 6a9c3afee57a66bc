"""The standalone C FMU in FMI 3.0 (``build_standalone_fmu(..., fmi=3)``, ``ebb build-fmu --standalone --fmi 3``).

References: ``ebb_model.simulate`` of the same config and parameters (within ``RTOL_CORE``, whose budget is
written in ``test_fmu_standalone.py``); the FMI 2.0 build of the same config — the same C instance
(``ebb_instance.c``) behind the other standard's calls, so the two are compared to the last bit; and for the
derivatives the FMU's own finite differences (outputs and state derivatives are linear in the knowns: a unit
difference is exact up to round-off).  Everything runs through fmpy's FMI 3.0 classes.
"""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest

import fmpy
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Model, FMU3Slave
from fmpy.validation import validate_fmu

HOSTS = Path(__file__).resolve().parent / "fmu_hosts"
sys.path.insert(0, str(HOSTS))
from fmu_configs import SEED_TOML, mixed_config  # noqa: E402
from fmu_loops import compile_host, fmpy_outputs, host_run, memcheck_replay  # noqa: E402

from ebb_cli import main  # noqa: E402
from ebb_model import assemble, config_from_dict, load_config, simulate  # noqa: E402
from ebb_model.assemble import field_config  # noqa: E402
from ebb_model.errors import FmuError  # noqa: E402
from fmu_build.standalone import build_standalone_fmu  # noqa: E402
from fmu_build.standalone.description import C_SOURCES  # noqa: E402

#: against the Python model: as test_fmu_standalone.RTOL_CORE (the two eigen-solvers' round-off, its budget there)
RTOL_CORE = 1e-9


def _rel_err(y: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.max(np.abs(y - ref), axis=0) / np.max(np.abs(ref), axis=0)))


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The seed (with its deflection field) and the mixed config (every sensor kind, filters, a point mass), each
    in FMI 3.0 and FMI 2.0."""
    d = tmp_path_factory.mktemp("fmi3")
    cfgs = {"seed": load_config(SEED_TOML), "mixed": config_from_dict(mixed_config())}
    out = {}
    for name, cfg in cfgs.items():
        field = name == "seed"
        out[name] = {v: build_standalone_fmu(cfg, d / f"{name}{v}.fmu", field=field, fmi=v) for v in (2, 3)}
    return cfgs, out


def _inputs(cfg, n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal((n, len(cfg.actuators)))


def _slave(fmu: Path, name: str = "cs"):
    md = fmpy.read_model_description(str(fmu))
    f = FMU3Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    f.instantiate()
    f.enterInitializationMode(startTime=0.0)
    f.exitInitializationMode()
    return f, md, {v.name: v.valueReference for v in md.modelVariables}


def _run(f, ins, outs, u: np.ndarray, k0: int, dt: float, n_values: int | None = None) -> np.ndarray:
    y = []
    for k in range(k0, len(u)):
        f.setFloat64(ins, list(u[k]))
        y.append(f.getFloat64(outs, nValues=n_values))
        f.doStep(k * dt, dt)
    return np.array(y)


# ---------------------------------------------------------------------------------------------- the archive
@pytest.mark.parametrize("name", ["seed", "mixed"])
def test_validate_fmu_reports_nothing(built, name):
    assert validate_fmu(str(built[1][name][3])) == []


def test_archive_is_fmi3_with_the_field_as_one_array(built, tmp_path):
    cfgs, fmus = built
    md = fmpy.read_model_description(str(fmus["seed"][3]))
    assert md.fmiVersion == "3.0" and md.modelExchange.modelIdentifier == md.coSimulation.modelIdentifier
    for iface in (md.coSimulation, md.modelExchange):          # (fmpy's names for FMI 3.0's attributes)
        assert iface.canGetAndSetFMUstate and iface.canSerializeFMUstate
    with zipfile.ZipFile(fmus["seed"][3]) as zf:                # (fmpy keeps no FMI 3.0 derivative flags)
        root = ElementTree.fromstring(zf.read("modelDescription.xml"))
    for tag in ("CoSimulation", "ModelExchange"):
        iface = root.find(tag)
        assert iface is not None
        assert iface.get("providesDirectionalDerivatives") == iface.get("providesAdjointDerivatives") == "true"
    by_name = {v.name: v for v in md.modelVariables}
    n_field = len(field_config(cfgs["seed"]).sensors) - len(cfgs["seed"].sensors)
    assert [int(d.start) for d in by_name["w"].dimensions] == [n_field] and n_field == 52
    assert not any(n.startswith("w[") for n in by_name)            # one array, not 52 scalars
    assert by_name["time"].causality == "independent"
    ident = md.coSimulation.modelIdentifier
    with zipfile.ZipFile(fmus["seed"][3]) as zf:
        names = set(zf.namelist())
        build = zf.read("sources/buildDescription.xml").decode()
        so = tmp_path / "beam.so"
        so.write_bytes(zf.read(f"binaries/x86_64-linux/{ident}.so"))
    assert {"sources/ebb_fmi3.c", "sources/ebb_fmi3.h", "sources/ebb_instance.c", "sources/ebb_config.h"} <= names
    assert "sources/ebb_fmi2.c" not in names and 'fmiVersion="3.0"' in build
    exported = subprocess.run(["nm", "-D", "--defined-only", str(so)], capture_output=True, text=True,
                              check=True).stdout.split()
    assert {"fmi3DoStep", "fmi3GetAdjointDerivative", "fmi3GetContinuousStateDerivatives"} <= set(exported)
    assert "fmi2DoStep" not in exported and "ebb_model_build" not in exported


# ------------------------------------------------------------------------------------------- co-simulation
@pytest.mark.parametrize("name", ["seed", "mixed"])
def test_cosim_equals_core_and_fmi2_to_the_last_bit(built, name):
    cfgs, fmus = built
    cfg = cfgs[name]
    u = _inputs(cfg, 600, 1)
    f, md, vr = _slave(fmus[name][3])
    ins, outs = [vr[n] for n in cfg.input_names], [vr[n] for n in cfg.output_names]
    y3 = _run(f, ins, outs, u, 0, cfg.time.dt)
    assert f.getFloat64([vr["time"]]) == [pytest.approx(len(u) * cfg.time.dt, rel=1e-12)]
    f.freeInstance()
    y2 = fmpy_outputs(fmus[name][2], u, outputs=cfg.output_names)
    np.testing.assert_array_equal(y3, y2)
    assert _rel_err(y3, simulate(assemble(cfg), u).outputs) <= RTOL_CORE


def test_the_field_is_one_array_read_in_one_call(built):
    """``w`` through one ``fmi3GetFloat64`` call with its 52 values: the FMI 2.0 FMU's 52 scalars ``w[i]``, to the
    last bit, and the core's deflection at the grid nodes."""
    cfgs, fmus = built
    cfg = cfgs["seed"]
    u = _inputs(cfg, 300, 2)
    f, md, vr = _slave(fmus["seed"][3])
    n = int(next(v for v in md.modelVariables if v.name == "w").dimensions[0].start)
    w3 = _run(f, [vr["F1"]], [vr["w"]], u, 0, cfg.time.dt, n_values=n)
    with pytest.raises(FMICallException):                  # the array's element count is checked
        f.getFloat64([vr["w"]], nValues=n - 1)
    f.freeInstance()
    names2 = [v.name for v in fmpy.read_model_description(str(fmus["seed"][2])).modelVariables
              if v.causality == "output"][len(cfg.sensors):]
    np.testing.assert_array_equal(w3, fmpy_outputs(fmus["seed"][2], u, outputs=names2))
    ref = simulate(assemble(field_config(cfg)), u).outputs[:, len(cfg.sensors):]
    assert np.max(np.abs(w3 - ref)) <= RTOL_CORE * np.max(np.abs(ref))


def test_fmpys_simulate_fmu_gives_fmi2s_result(built):
    """fmpy's own FMI 3.0 simulation loop (it reads the outputs after each step, before the next input: the
    "after" protocol of fmu_loops) equals its FMI 2.0 loop on the FMI 2.0 build, to the last bit."""
    cfgs, fmus = built
    cfg = cfgs["mixed"]
    u = _inputs(cfg, 400, 3)
    dt = cfg.time.dt
    t = np.arange(len(u)) * dt
    signal = np.array([tuple([ti, *ui]) for ti, ui in zip(t, u)],
                      dtype=[("time", float)] + [(n, float) for n in cfg.input_names])
    kw = dict(fmi_type="CoSimulation", input=signal, output=list(cfg.output_names), step_size=dt,
              output_interval=dt, start_time=0.0, stop_time=t[-1])
    r3, r2 = simulate_fmu(str(fmus["mixed"][3]), **kw), simulate_fmu(str(fmus["mixed"][2]), **kw)
    y3 = np.column_stack([r3[n] for n in cfg.output_names])
    np.testing.assert_array_equal(y3, np.column_stack([r2[n] for n in cfg.output_names]))
    after = fmpy_outputs(fmus["mixed"][2], u, protocol="after", outputs=cfg.output_names)
    np.testing.assert_array_equal(y3[1:], after[:len(y3) - 1])


# ----------------------------------------------------------------------------------- an independent master
def _host_lines(proc: subprocess.CompletedProcess, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The C master's rows, its replay ("R "), its directional derivatives ("J", one row per input) and adjoint."""
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    rows = np.array([[float(x) for x in ln.split()] for ln in lines[:n]])
    replay = np.array([[float(x) for x in ln[2:].split()] for ln in lines if ln.startswith("R ")])
    at = lines.index("J")
    adjoint = next(ln for ln in lines if ln.startswith("A "))
    J = np.array([[float(x) for x in ln.split()] for ln in lines[at + 1:lines.index(adjoint)]])
    return rows, replay, J, np.array([float(x) for x in adjoint[2:].split()])


@pytest.mark.parametrize("name", ["seed", "mixed"])
def test_a_plain_c_fmi3_master_equals_fmpy(built, name, tmp_path):
    """The C master written against the standard's FMI 3.0 headers, with an empty environment: every output
    element (the field array read whole) equal to fmpy's FMI 3.0 loop to the last bit (%.17g); a checkpoint
    serialised before point 150 and replayed, identical; the adjoint of an all-ones seed the directional
    derivatives' column sums."""
    cfgs, fmus = built
    cfg = cfgs[name]
    u = _inputs(cfg, 300, 7)
    proc = host_run(compile_host(tmp_path, fmi=3), fmus[name][3], u, tmp_path / "run", env={}, checkpoint=150)
    rows, replay, J, adjoint = _host_lines(proc, len(u))
    f, md, vr = _slave(fmus[name][3])
    outs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    n_values = sum(int(v.dimensions[0].start) if v.dimensions else 1 for v in md.modelVariables
                   if v.causality == "output")
    np.testing.assert_array_equal(rows, _run(f, [vr[n] for n in cfg.input_names], outs, u, 0, cfg.time.dt,
                                             n_values=n_values))
    f.freeInstance()
    np.testing.assert_array_equal(replay, rows[150:])
    assert J.shape == (len(cfg.input_names), n_values) and np.abs(J).max() > 0
    np.testing.assert_allclose(adjoint, J.sum(axis=1), rtol=0, atol=1e-12 * np.abs(J).sum())


def test_fmi3_c_code_is_clean_under_address_and_undefined_behaviour_sanitizers(built, tmp_path):
    """The FMI 3.0 master and the FMU's FMI 3.0 sources compiled with ``-fsanitize=address,undefined``: a run
    with the field array, a 3-sample step, a checkpoint replayed, and the derivatives; no report."""
    flags = ["-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=undefined"]
    (tmp_path / "probe.c").write_text("int main(void) { return 0; }\n")
    probe = subprocess.run(["gcc", *flags, "-o", str(tmp_path / "probe"), str(tmp_path / "probe.c")],
                           capture_output=True, text=True)
    if probe.returncode != 0:             # only the runtime's absence skips; the master's own errors fail
        pytest.skip(f"gcc has no sanitizer runtime here: {probe.stderr[-300:]}")
    host = compile_host(tmp_path, fmi=3, flags=flags)
    cfgs, fmus = built
    for name in ("seed", "mixed"):
        work = tmp_path / name
        unzip = Path(fmpy.extract(str(fmus[name][3]), unzipdir=str(work / "src")))
        md = fmpy.read_model_description(str(unzip))
        subprocess.run(["gcc", "-std=c99", *flags, "-shared", "-fPIC", "-o",
                        str(unzip / "binaries" / "x86_64-linux" / f"{md.coSimulation.modelIdentifier}.so"),
                        *C_SOURCES[3], "-lm"], cwd=unzip / "sources", check=True, capture_output=True)
        with zipfile.ZipFile(work / "asan.fmu", "w") as zf:
            for f in sorted(unzip.rglob("*")):
                if f.is_file():
                    zf.write(f, f.relative_to(unzip).as_posix())
        u = np.random.default_rng(3).standard_normal((60, len(cfgs[name].input_names)))
        step = 3 * float(md.defaultExperiment.stepSize)
        proc = host_run(host, work / "asan.fmu", u, work / "run", step=step, env={"PATH": "/usr/bin:/bin"},
                        checkpoint=30)
        rows, replay, J, adjoint = _host_lines(proc, len(u))
        np.testing.assert_array_equal(replay, rows[30:])
        assert "runtime error" not in proc.stderr and "AddressSanitizer" not in proc.stderr, proc.stderr[-3000:]


# ------------------------------------------------------------------------------------------- derivatives
def test_directional_and_adjoint_derivatives_are_finite_differences(built):
    """Co-simulation: ∂y/∂u (outputs, the field array included) by unit seeds equals the outputs' difference for
    a changed input; the adjoint of a random seed is Jᵀ·seed.  Model exchange: ∂(ẋ, y)/∂(x, u) by unit seeds
    equals the derivatives' and outputs' differences for changed states and inputs, and the adjoint again
    Jᵀ·seed.  Tolerances: the maps are linear, so a unit difference has only round-off, 1e-12 of the largest
    entry; directional against adjoint differs by the summation order only."""
    cfgs, fmus = built
    rng = np.random.default_rng(4)
    cfg = cfgs["mixed"]
    f, md, vr = _slave(fmus["mixed"][3])
    ins, outs = [vr[n] for n in cfg.input_names], [vr[n] for n in cfg.output_names]
    _run(f, ins, outs, _inputs(cfg, 80, 5), 0, cfg.time.dt)      # mid-run, not at rest
    u0 = np.array([0.3, -0.2])
    f.setFloat64(ins, list(u0))
    y0 = np.array(f.getFloat64(outs))
    J = np.column_stack([f.getDirectionalDerivative(outs, [i], [1.0]) for i in ins])
    fd = []
    for j in range(len(ins)):
        du = u0.copy()
        du[j] += 1.0
        f.setFloat64(ins, list(du))
        fd.append(np.array(f.getFloat64(outs)) - y0)
    scale = np.abs(J).max()
    np.testing.assert_allclose(J, np.column_stack(fd), rtol=0, atol=1e-12 * scale)
    assert np.abs(J[2, 0]) > 1.0                    # the accelerometer's feedthrough is there
    seed = rng.standard_normal(len(outs))
    adj = f.getAdjointDerivative(outs, ins, list(seed), nSensitivity=len(ins))
    np.testing.assert_allclose(adj, J.T @ seed, rtol=0, atol=1e-12 * scale * np.abs(seed).sum())
    f.freeInstance()

    md = fmpy.read_model_description(str(fmus["mixed"][3]))
    g = FMU3Model(guid=md.guid, unzipDirectory=fmpy.extract(str(fmus["mixed"][3])),
                  modelIdentifier=md.modelExchange.modelIdentifier, instanceName="me")
    g.instantiate()
    g.enterInitializationMode(startTime=0.0)
    g.exitInitializationMode()
    g.enterContinuousTimeMode()
    ders = [d.variable.valueReference for d in md.derivatives]
    states = [d.variable.derivative.valueReference for d in md.derivatives]
    nx = len(states)
    x0, u0 = rng.standard_normal(nx), rng.standard_normal(len(ins))
    unknowns, knowns = ders + outs, states + ins

    def evaluate(x: np.ndarray, u: np.ndarray) -> np.ndarray:
        g.setFloat64(states, list(x))
        g.setFloat64(ins, list(u))
        return np.array(g.getFloat64(ders) + g.getFloat64(outs))

    base = evaluate(x0, u0)
    J = np.column_stack([g.getDirectionalDerivative(unknowns, [k], [1.0], nSensitivity=len(unknowns))
                         for k in knowns])
    fd = []
    for j in range(nx + len(ins)):
        e = np.zeros(nx + len(ins))
        e[j] = 1.0
        fd.append(evaluate(x0 + e[:nx], u0 + e[nx:]) - base)
    scale = np.abs(J).max()
    np.testing.assert_allclose(J, np.column_stack(fd), rtol=0, atol=1e-12 * scale)
    seed = rng.standard_normal(len(unknowns))
    adj = g.getAdjointDerivative(unknowns, knowns, list(seed), nSensitivity=len(knowns))
    np.testing.assert_allclose(adj, J.T @ seed, rtol=0, atol=1e-12 * scale * np.abs(seed).sum())
    g.freeInstance()


# ------------------------------------------------------------------------------------------- saved states
def test_a_state_saved_and_serialised_continues_bit_identically(built):
    cfgs, fmus = built
    cfg = cfgs["mixed"]
    dt = cfg.time.dt
    u = _inputs(cfg, 300, 6)
    f, md, vr = _slave(fmus["mixed"][3])
    ins, outs = [vr[n] for n in cfg.input_names], [vr[n] for n in cfg.output_names]
    _run(f, ins, outs, u[:150], 0, dt)
    state = f.getFMUState()
    blob = f.serializeFMUState(state)
    rest = _run(f, ins, outs, u, 150, dt)
    f.setFMUState(state)
    np.testing.assert_array_equal(_run(f, ins, outs, u, 150, dt), rest)
    f.freeFMUState(state)
    g, _, _ = _slave(fmus["mixed"][3], "second")
    g.setFloat64([vr["EI"]], [20.0])                  # another model meanwhile: the state brings its own back
    _run(g, ins, outs, u[:40], 0, dt)
    restored = g.deserializeFMUState(blob)
    g.setFMUState(restored)
    np.testing.assert_array_equal(_run(g, ins, outs, u, 150, dt), rest)
    with pytest.raises(FMICallException):                    # truncated bytes are refused
        g.deserializeFMUState(blob[:-8])
    for inst in (f, g):
        inst.terminate()
        inst.freeInstance()


# ------------------------------------------------------------------------------------------------- errors
def test_errors_are_fmi3error_with_a_message_naming_the_cause(built):
    cfgs, fmus = built
    messages: list[str] = []

    def log(env, status, category, message):
        messages.append(message.decode())

    fmu = fmus["seed"][3]
    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzip = fmpy.extract(str(fmu))
    f = FMU3Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="bad")
    f.instantiate(logMessage=log)
    f.enterInitializationMode(startTime=0.0)
    f.exitInitializationMode()
    dt = cfgs["seed"].time.dt
    cases = [(lambda: f.doStep(0.0, 1.5 * dt), "fmi3DoStep: communication step size"),
             (lambda: f.setFloat64([vr["y1"]], [1.0]), "fmi3SetFloat64: variable y1"),
             (lambda: f.setFloat64([vr["F1"]], [float("nan")]), "input F1 = nan is not a finite number"),
             (lambda: f.getFloat64([vr["w"]], nValues=3), "3 values given for variables of 52 element(s)"),
             (lambda: f.getBoolean([vr["EI"]]), "this FMU has no Boolean variables")]
    for call, needle in cases:
        messages.clear()
        with pytest.raises(FMICallException):
            call()
        assert any(needle in m for m in messages), (needle, messages)
    f.setFloat64([vr["N"]], [-5000.0])               # beyond buckling: the model is refused when next used
    messages.clear()
    with pytest.raises(FMICallException):
        f.doStep(0.0, dt)
    assert any(m.startswith("fmi3DoStep") and "N = -5000" in m and "buckling" in m for m in messages), messages
    f.freeInstance()
    g = FMU3Slave(guid="{not-this-one}", unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="token")
    messages.clear()
    with pytest.raises(Exception, match="Failed to instantiate"):      # (fmpy's own exception here)
        g.instantiate(logMessage=log)
    assert any("instantiation token" in m for m in messages), messages


def test_cli_builds_fmi3_and_refuses_what_it_cannot(tmp_path):
    out = tmp_path / "beam3.fmu"
    assert main(["build-fmu", str(SEED_TOML), "--standalone", "--fmi", "3", "--field", "--out", str(out)]) == 0
    assert fmpy.read_model_description(str(out)).fmiVersion == "3.0" and validate_fmu(str(out)) == []
    with pytest.raises(SystemExit) as exc:
        main(["build-fmu", str(SEED_TOML), "--standalone", "--fmi", "4", "--out", str(tmp_path / "x.fmu")])
    assert exc.value.code == 2 and not (tmp_path / "x.fmu").exists()
    with pytest.raises(FmuError, match="FMI 2 or 3"):           # the API: a typed error, nothing written
        build_standalone_fmu(SEED_TOML, tmp_path / "y.fmu", fmi=4)
    assert not (tmp_path / "y.fmu").exists()


def test_the_diagnosed_model_exports_in_fmi3(tmp_path):
    """``ebb diagnose --target standalone_fmi3`` (``export_corrected(..., targets=["standalone_fmi3"])``): the
    corrected beam as an FMI 3.0 FMU, its outputs those of the core under the corrected parameters."""
    from diagnosis.corrected.export import export_corrected
    from diagnosis.effects import AugmentedModel

    cfg = load_config(SEED_TOML)
    params = cfg.parameter_values() | {"EI": 10.5, "c": 0.2}
    files = export_corrected(AugmentedModel(cfg, params), tmp_path / "corrected", {"effect": "test"},
                             targets=["standalone_fmi3"])
    fmu = tmp_path / "corrected" / "corrected_standalone_fmi3.fmu"
    assert fmu in files and fmpy.read_model_description(str(fmu)).fmiVersion == "3.0"
    u = _inputs(cfg, 300, 13)
    assert _rel_err(fmpy_outputs(fmu, u), simulate(assemble(cfg, params), u).outputs) <= RTOL_CORE


@pytest.mark.parametrize("version", [2, 3])
def test_the_c_fmu_is_clean_under_valgrind(built, version, tmp_path):
    """Each version's C master (FMI 2.0's, FMI 3.0's) on the mixed config's FMU under valgrind's memcheck with
    full leak checking: a run with a serialised checkpoint replayed (and, FMI 3.0, the derivatives) — no invalid
    access, no uninitialised value used, nothing leaked (``--errors-for-leak-kinds=definite,indirect``)."""
    cfgs, fmus = built
    memcheck_replay(fmus["mixed"][version], _inputs(cfgs["mixed"], 40, 8), tmp_path, checkpoint=20)
