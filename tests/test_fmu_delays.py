"""The standalone C FMU carries the channels' converter delays (``delay`` in ``[[sensors]]``) as delay lines.

References: ``ebb_model.simulate`` of the config made causal (the native model, its outputs delayed after the run
by :func:`~ebb_model.acquisition.channel_delay.delay_outputs`, which may read the whole record) and the Python
route, the delay line realised as states (:func:`ebb_model.assemble.assemble_modal`) — both within ``RTOL_CORE``
(the two eigen-solvers' round-off, its budget in ``test_fmu_standalone.py``); the same FMU in the other FMI
version and the undelayed FMU shifted, to the last bit; the FMU's own finite differences for the derivatives.
"""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import fmpy
from fmpy.fmi2 import FMU2Model, FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi3 import FMU3Model
from fmpy.validation import validate_fmu

HOSTS = Path(__file__).resolve().parent / "fmu_hosts"
sys.path.insert(0, str(HOSTS))
from fmu_loops import compile_host, fmpy_outputs, host_run, memcheck_replay, started_slave  # noqa: E402

import ebb_model as em  # noqa: E402
from ebb_cli import main  # noqa: E402
from ebb_model.acquisition.bandlimited import causal_config  # noqa: E402
from ebb_model.acquisition.channel_delay import effective_delays, without_delays  # noqa: E402
from ebb_model.acquisition.delay_line import MIN_FRACTIONAL, delay_taps  # noqa: E402
from ebb_model.assemble import assemble_modal, field_config  # noqa: E402
from ebb_model.errors import ConfigError  # noqa: E402
from ebb_model.io.tomlio import dumps as toml_dumps  # noqa: E402
from fmu_build.standalone import build_standalone_fmu  # noqa: E402
from fmu_build.standalone.description import C_SOURCES  # noqa: E402

from test_bad_input import one_line_error  # noqa: E402
from test_bandlimited import config  # noqa: E402
from test_channel_delay import delayed  # noqa: E402

#: against the Python models: as test_fmu_standalone.RTOL_CORE (the two eigen-solvers' round-off)
RTOL_CORE = 1e-9

#: Sensor delays and the force channel's, in samples: whole delays after a force channel on time and after one
#: a sample late (the sensors' delays taken after it: 3 and 1), a fraction (37.4: 32 kernel taps, lags 22 … 53)
#: and a fraction with a lag-0 tap (MIN_FRACTIONAL + 0.5 = 15.5: lags 0 … 31) next to an undelayed sensor.  The
#: fractions on the band-limited force between samples (the builder makes it the causal cubic).
CASES = {"whole": ((3.0, 7.0), 0.0, "cubic"), "force": ((4.0, 2.0), 1.0, "cubic"),
         "fraction": ((37.4, 3.0), 0.0, "bandlimited"), "lag0": ((MIN_FRACTIONAL + 0.5, 0.0), 0.0, "bandlimited")}


def _config(name: str) -> em.BeamConfig:
    sensors, force, hold = CASES[name]
    return delayed(config(20, hold), sensors, force)


def _rel_err(y: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.max(np.abs(y - ref), axis=0) / np.max(np.abs(ref), axis=0)))


def _inputs(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal((n, 1))


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """Each case in FMI 2.0 and 3.0, and the whole case without its delays (FMI 2.0)."""
    d = tmp_path_factory.mktemp("delays")
    out = {name: {v: build_standalone_fmu(_config(name), d / f"{name}{v}.fmu", fmi=v) for v in (2, 3)}
           for name in CASES}
    out["undelayed"] = {2: build_standalone_fmu(without_delays(_config("whole")), d / "undelayed.fmu")}
    return out


# ------------------------------------------------------------------------------------------- co-simulation
@pytest.mark.parametrize("name", list(CASES))
def test_outputs_are_the_native_and_the_python_delayed_models(fmus, name):
    """A random force through fmpy, FMI 2.0 and 3.0: the native model (delayed after the run) and the Python
    route (the delay line as states) within RTOL_CORE — measured 2.0e-11 … 2.4e-11; the two FMI versions
    identical; the delays there (the undelayed model is far off)."""
    cfg = causal_config(_config(name))
    u = _inputs(500, 1)
    native = em.simulate(em.assemble(cfg), u).outputs
    python = em.simulate(assemble_modal(cfg), u).outputs
    y2, y3 = fmpy_outputs(fmus[name][2], u), fmpy_outputs(fmus[name][3], u)
    np.testing.assert_array_equal(y3, y2)
    assert _rel_err(y2, native) <= RTOL_CORE and _rel_err(y2, python) <= RTOL_CORE
    undelayed = em.simulate(em.assemble(without_delays(cfg)), u).outputs
    for i, d in enumerate(effective_delays(cfg)):
        assert (_rel_err(y2[:, [i]], undelayed[:, [i]]) > 0.1) if d else \
            (_rel_err(y2[:, [i]], undelayed[:, [i]]) <= RTOL_CORE), (name, i)


@pytest.mark.parametrize("scheme", ["exact", "theta"])
def test_every_sensor_kind_two_forces_a_filter_and_the_theta_scheme(tmp_path, scheme):
    """The mixed config (displacement, velocity, acceleration; two forces on one card 2 samples late; a point mass,
    an elastic end): the exact scheme with a fraction (20.25 samples, band-limited force) on an accelerometer
    through a 4th-order anti-alias filter (the dense form), the θ-scheme's dense nodal realisation with whole
    samples only (a fraction and a filter need the exact scheme).  FMI 3.0 and 2.0 respectively; measured 7.8e-12
    and 4.7e-13 against the native model."""
    from fmu_configs import mixed_config

    d = mixed_config()
    dt = d["time"]["dt"]
    d["time"] |= {"input": "bandlimited"} if scheme == "exact" else {"scheme": "theta", "input": "foh", "substeps": 3}
    for a in d["actuators"]:
        a["delay"] = 2 * dt
    for sensor, k in zip(d["sensors"], (7.0, 2.0, 20.25 if scheme == "exact" else 5.0)):
        sensor["delay"] = k * dt
    if scheme == "exact":                              # (the filter is integrated exactly with the beam)
        d["sensors"][2]["antialias"] = {"order": 4, "corner": 0.3 / dt}
    cfg = em.config_from_dict(d)
    u = np.random.default_rng(10).standard_normal((500, 2))
    y = fmpy_outputs(build_standalone_fmu(cfg, tmp_path / "mixed.fmu", fmi=3 if scheme == "exact" else 2), u)
    c = causal_config(cfg)
    assert _rel_err(y, em.simulate(em.assemble(c), u).outputs) <= RTOL_CORE
    assert _rel_err(y, em.simulate(assemble_modal(c), u).outputs) <= RTOL_CORE


def test_whole_delays_are_the_undelayed_fmu_shifted_to_the_last_bit(fmus):
    """3 and 7 whole samples: the undelayed FMU's outputs shifted, held at the first before the record (the
    weight 1 of one tap changes no bit; at the rest start every past sample is the first undelayed output)."""
    u = _inputs(300, 2)
    y, y0 = fmpy_outputs(fmus["whole"][2], u), fmpy_outputs(fmus["undelayed"][2], u)
    for i, q in enumerate((3, 7)):
        np.testing.assert_array_equal(y[q:, i], y0[:-q, i])
        np.testing.assert_array_equal(y[:q, i], np.full(q, y0[0, i]))


def test_a_step_of_several_samples_pushes_every_sample(fmus):
    """``doStep(3 dt)`` with the input held equals three steps of ``dt``: each sample enters the delay line."""
    cfg = _config("fraction")
    md = fmpy.read_model_description(str(fmus["fraction"][2]))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    dt = cfg.time.dt
    u = _inputs(40, 3)

    def run(n: int) -> np.ndarray:
        f = started_slave(md, fmpy.extract(str(fmus["fraction"][2])), f"n{n}")
        out = []
        for k in range(len(u)):
            f.setReal([vr["F1"]], list(u[k]))
            for j in range(3 // n):
                f.doStep((3 * k + j * n) * dt, n * dt)
            out.append(f.getReal([vr["s0"], vr["s1"]]))
        f.freeInstance()
        return np.array(out)

    np.testing.assert_array_equal(run(3), run(1))


def test_field_outputs_stay_undelayed(tmp_path):
    """``field=True`` on a config whose force channel is late: the sensors delayed, the deflection at the grid
    nodes (the beam's, no channel's) not."""
    cfg = _config("force")
    u = _inputs(300, 4)
    y = fmpy_outputs(build_standalone_fmu(cfg, tmp_path / "field.fmu", field=True), u)
    sensors = em.simulate(em.assemble(cfg), u).outputs
    field = em.simulate(em.assemble(field_config(without_delays(cfg))), u).outputs[:, 2:]
    moving = np.abs(field).max(axis=0) > 0.0                 # the clamped and pinned ends do not move
    assert np.all(y[:, 2:][:, ~moving] == 0.0)
    assert _rel_err(y[:, :2], sensors) <= RTOL_CORE and _rel_err(y[:, 2:][:, moving], field[:, moving]) <= RTOL_CORE


# ------------------------------------------------------------------------------------- the model description
@pytest.mark.parametrize("version", [2, 3])
def test_no_model_exchange_with_delays_and_validation_clean(fmus, version):
    for name in CASES:
        md = fmpy.read_model_description(str(fmus[name][version]))
        assert md.modelExchange is None and md.coSimulation is not None, name
        assert "No model exchange" in md.description and validate_fmu(str(fmus[name][version])) == [], name
    with zipfile.ZipFile(fmus["fraction"][version]) as zf:
        header = zf.read("sources/ebb_config.h").decode()
        assert "sources/ebb_delay.c" in zf.namelist()
    lags, weights = delay_taps(37.4)
    assert f"EBB_DELAY_LAG[] = {{{', '.join(map(str, lags))}, 3}};" in header
    assert f"EBB_DELAY_WEIGHT[] = {{{', '.join(map(repr, map(float, weights)))}, 1.0}};" in header
    assert "#define EBB_DELAY_LEN 53" in header
    md = fmpy.read_model_description(str(fmus["undelayed"][2]))
    assert md.modelExchange is not None                                         # without delays as before


def test_model_exchange_is_refused_with_a_logged_reason(fmus):
    """The binary itself, asked for model exchange (a host that ignores the model description): no instance,
    and a message naming the delayed sensors and why."""
    messages: list[str] = []
    md = fmpy.read_model_description(str(fmus["lag0"][2]))
    f = FMU2Model(guid=md.guid, unzipDirectory=fmpy.extract(str(fmus["lag0"][2])),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="me")
    logger = fmi2CallbackLoggerTYPE(lambda env, name, status, category, message: messages.append(message.decode()))
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = logger
    with pytest.raises(Exception, match="Failed to instantiate"):
        f.instantiate(callbacks=callbacks)
    assert any(m.startswith("fmi2Instantiate") and "sensor(s) s0 " in m and "co-simulation only" in m
               for m in messages), messages
    messages.clear()
    md = fmpy.read_model_description(str(fmus["whole"][3]))
    g = FMU3Model(guid=md.guid, unzipDirectory=fmpy.extract(str(fmus["whole"][3])),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="me3")
    with pytest.raises(Exception, match="Failed to instantiate"):
        g.instantiate(logMessage=lambda env, status, category, message: messages.append(message.decode()))
    assert any(m.startswith("fmi3InstantiateModelExchange") and "sensor(s) s0, s1 " in m for m in messages), \
        messages


# ------------------------------------------------------------------------------------------------- refused
REFUSED = {"ahead": (((4.0, 0.0), 1.0, "cubic"), "output s1 is 1 sample"),
           "short": (((2.5, 3.0), 0.0, "bandlimited"), "output s0 is 2.5 samples late")}


@pytest.mark.parametrize("name", list(REFUSED))
def test_a_delay_without_a_causal_line_is_refused(tmp_path, capsys, name):
    """A sensor ahead of the force's channel (it would read the force ahead) and a fraction of a sample shorter
    than MIN_FRACTIONAL (the kernel would read samples after it): ``build_standalone_fmu`` raises ConfigError
    and ``ebb build-fmu --standalone`` exits 2 with one line; nothing written, in either FMI version."""
    (sensors, force, hold), needle = REFUSED[name]
    cfg = delayed(config(20, hold), sensors, force)
    for version in (2, 3):
        with pytest.raises(ConfigError, match=needle):
            build_standalone_fmu(cfg, tmp_path / f"api{version}.fmu", fmi=version)
        path = tmp_path / "delayed.toml"
        path.write_text(toml_dumps(cfg.to_dict()))
        capsys.readouterr()
        assert main(["build-fmu", str(path), "--standalone", "--fmi", str(version),
                     "--out", str(tmp_path / f"cli{version}.fmu")]) == 2
        assert needle in one_line_error(capsys, "build-fmu")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["delayed.toml"]


# ------------------------------------------------------------------------------------------- saved states
@pytest.mark.parametrize("version", [2, 3])
def test_a_state_saved_mid_run_restores_the_delay_line(fmus, version):
    """Saved mid-run (the 53-sample line full of the record's past), the run continued, the state set again: the
    continuation identical to the last bit; serialised and set in a second instance run meanwhile under other
    parameters and another force, identical again.  The serialised state holds the lines (8 bytes a sample)."""
    cfg = _config("fraction")
    fmu = fmus["fraction"][version]
    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    ins, outs, dt = [vr["F1"]], [vr["s0"], vr["s1"]], cfg.time.dt
    u = _inputs(300, 5)

    def instance(name: str):
        return started_slave(md, fmpy.extract(str(fmu)), name, version)

    def run(f, k0: int, uu: np.ndarray) -> np.ndarray:
        y = []
        for k in range(k0, len(uu)):
            (f.setReal if version == 2 else f.setFloat64)(ins, list(uu[k]))
            y.append((f.getReal if version == 2 else f.getFloat64)(outs))
            f.doStep(k * dt, dt)
        return np.array(y)

    f = instance("first")
    first = run(f, 0, u[:150])
    get, put = (f.getFMUstate, f.setFMUstate) if version == 2 else (f.getFMUState, f.setFMUState)
    state = get()
    blob = (f.serializeFMUstate if version == 2 else f.serializeFMUState)(state)
    rest = run(f, 150, u)
    put(state)
    np.testing.assert_array_equal(run(f, 150, u), rest)
    assert _rel_err(np.vstack([first, rest]), em.simulate(em.assemble(causal_config(cfg)), u).outputs) <= RTOL_CORE
    g = instance("second")
    (g.setReal if version == 2 else g.setFloat64)([vr["EI"]], [20.0])
    run(g, 0, -u[:90])
    restored = (g.deSerializeFMUstate if version == 2 else g.deserializeFMUState)(blob)
    (g.setFMUstate if version == 2 else g.setFMUState)(restored)
    np.testing.assert_array_equal(run(g, 150, u), rest)
    if version == 2:
        mp = fmpy.read_model_description(str(fmus["undelayed"][2]))
        plain = FMU2Slave(guid=mp.guid, unzipDirectory=fmpy.extract(str(fmus["undelayed"][2])),
                          modelIdentifier=mp.coSimulation.modelIdentifier, instanceName="plain")
        plain.instantiate()
        assert len(blob) - len(plain.serializeFMUstate(plain.getFMUstate())) == 8 * 2 * 53   # two lines of 53
        plain.freeInstance()
    for inst in (f, g):
        inst.freeInstance()


def test_the_plain_c_masters_replay_and_differentiate(fmus, tmp_path):
    """The C masters with an empty environment (FMI 2.0 and 3.0): the outputs those of fmpy to the last bit, a
    serialised checkpoint replayed line for line; FMI 3.0's adjoint of an all-ones seed the directional
    derivatives' sums."""
    u = _inputs(200, 6)
    for version in (2, 3):
        proc = host_run(compile_host(tmp_path, fmi=version), fmus["lag0"][version], u, tmp_path / f"run{version}",
                        env={}, checkpoint=120)
        assert proc.returncode == 0, proc.stderr[-3000:]
        lines = proc.stdout.splitlines()
        rows = np.array([[float(x) for x in ln.split()] for ln in lines[:len(u)]])
        np.testing.assert_array_equal(rows, fmpy_outputs(fmus["lag0"][version], u))
        assert [ln[2:] for ln in lines if ln.startswith("R ")] == lines[120:len(u)]
        if version == 3:
            at = lines.index("J")
            adjoint = next(ln for ln in lines if ln.startswith("A "))
            J = np.array([[float(x) for x in ln.split()] for ln in lines[at + 1:lines.index(adjoint)]])
            assert np.abs(J[0, 0]) > 0.0 and J[0, 1] != 0.0
            np.testing.assert_allclose([float(x) for x in adjoint[2:].split()], J.sum(axis=1), rtol=1e-14)


# ------------------------------------------------------------------------------------------- derivatives
@pytest.mark.parametrize("name", ["lag0", "fraction"])
def test_derivatives_are_the_fmus_finite_differences(fmus, name):
    """Mid-run, ∂y/∂u by unit seeds (FMI 2.0 and 3.0 directional, FMI 3.0 adjoint) equals the outputs' change for
    a unit change of the input: a delayed output sees the current input through its lag-0 tap only — ``w₀ D``
    with the kernel's lag 0 (15.5 samples), exactly 0 without (37.4 and 3 samples).  And it is the D of the
    Python route's delay line (RTOL_CORE).  Tolerance: the outputs are linear in the input, so a unit change
    has only the round-off of the line's sum, 1e-12 of the outputs' scale."""
    cfg = causal_config(_config(name))
    lined, beam = assemble_modal(cfg), assemble_modal(without_delays(cfg))
    u = _inputs(120, 7)
    for version in (2, 3):
        md = fmpy.read_model_description(str(fmus[name][version]))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        ins, outs = [vr["F1"]], [vr["s0"], vr["s1"]]
        f = started_slave(md, fmpy.extract(str(fmus[name][version])), "d", version)
        set_, get = (f.setReal, f.getReal) if version == 2 else (f.setFloat64, f.getFloat64)
        for k in range(len(u)):
            set_(ins, list(u[k]))
            f.doStep(k * cfg.time.dt, cfg.time.dt)
        set_(ins, [0.3])
        y0 = np.array(get(outs))
        set_(ins, [1.3])
        fd = np.array(get(outs)) - y0
        J = np.array(f.getDirectionalDerivative(outs, ins, [1.0]))
        np.testing.assert_allclose(J, fd, rtol=0, atol=1e-12 * np.abs(y0).max())
        np.testing.assert_allclose(J, lined.D[:, 0], rtol=RTOL_CORE, atol=0)
        if name == "fraction":
            assert np.all(J == 0.0)
        else:                                     # w₀ of the undelayed feedthrough; s1 undelayed
            w0 = delay_taps(MIN_FRACTIONAL + 0.5)[1][0]
            np.testing.assert_allclose(J, [w0, 1.0] * beam.D[:, 0], rtol=RTOL_CORE, atol=0)
            assert J[0] != 0.0 and J[1] != 0.0
        if version == 3:
            seed = np.array([0.7, -1.3])
            adj = f.getAdjointDerivative(outs, ins, list(seed), nSensitivity=1)
            np.testing.assert_allclose(adj, [J @ seed], rtol=1e-14, atol=1e-300)
        f.freeInstance()


# ------------------------------------------------------------------------------------------- sanitizers
def test_the_delay_line_is_clean_under_address_and_undefined_behaviour_sanitizers(fmus, tmp_path):
    """The FMI 2.0 master and a delayed FMU's sources with ``-fsanitize=address,undefined``: 3-sample steps that
    wrap the 53-sample ring, a checkpoint saved, serialised and replayed; no report."""
    flags = ["-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=undefined"]
    (tmp_path / "probe.c").write_text("int main(void) { return 0; }\n")
    probe = subprocess.run(["gcc", *flags, "-o", str(tmp_path / "probe"), str(tmp_path / "probe.c")],
                           capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"gcc has no sanitizer runtime here: {probe.stderr[-300:]}")
    host = compile_host(tmp_path, flags=flags)
    work = tmp_path / "fraction"
    unzip = Path(fmpy.extract(str(fmus["fraction"][2]), unzipdir=str(work / "src")))
    md = fmpy.read_model_description(str(unzip))
    subprocess.run(["gcc", "-std=c99", "-pedantic", "-Werror", *flags, "-shared", "-fPIC", "-o",
                    str(unzip / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"), *C_SOURCES[2],
                    "-lm"], cwd=unzip / "sources", check=True, capture_output=True)
    with zipfile.ZipFile(work / "asan.fmu", "w") as zf:
        for f in sorted(unzip.rglob("*")):
            if f.is_file():
                zf.write(f, f.relative_to(unzip).as_posix())
    u = _inputs(80, 8)
    proc = host_run(host, work / "asan.fmu", u, work / "run", step=3 * float(md.defaultExperiment.stepSize),
                    env={"PATH": "/usr/bin:/bin"}, checkpoint=40)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    assert [ln[2:] for ln in lines[80:]] == lines[40:80]
    assert "runtime error" not in proc.stderr and "AddressSanitizer" not in proc.stderr, proc.stderr[-3000:]



@pytest.mark.parametrize("version", [2, 3])
def test_the_delay_line_is_clean_under_valgrind(fmus, version, tmp_path):
    """Each version's C master on the fractional case under valgrind's memcheck, full leak checking: a run with a
    serialised checkpoint replayed — no invalid access, no uninitialised value used, nothing leaked (the rings
    and the states that carry them freed)."""
    memcheck_replay(fmus["fraction"][version], _inputs(70, 9), tmp_path, checkpoint=30)
