"""The Python (pythonfmu3) FMU in FMI 3.0 (``build_fmu(..., fmi=3)``, ``ebb build-fmu --fmi 3``).

References: the FMI 2.0 Python FMU of the same config (the same slave behind the other standard's calls:
compared to the last bit) and ``ebb_model.simulate`` (within ``RTOL``, as ``test_fmu_fmpy.py``).  Everything
runs real FMUs through fmpy's FMI 3.0 classes, and once through the plain C FMI 3.0 master (no Python in its
process: the FMU's loader, ``loader3.c``, brings the build interpreter).
"""
from __future__ import annotations

import math
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import fmpy
import pythonfmu3  # noqa: F401 - a dependency: a broken install must fail, not skip
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

HOSTS = Path(__file__).resolve().parent / "fmu_hosts"
sys.path.insert(0, str(HOSTS))
from fmu_configs import SEED_TOML, mixed_config  # noqa: E402
from fmu_loops import compile_host, fmpy_outputs, host_run  # noqa: E402

from ebb_cli import main  # noqa: E402
from ebb_model import assemble, config_from_dict, load_config, simulate  # noqa: E402
from ebb_model.assemble import field_config  # noqa: E402
from ebb_model.errors import FmuError  # noqa: E402
from fmu_build import build_fmu  # noqa: E402

#: against the core, as test_fmu_fmpy.RTOL
RTOL = 1e-10


def _rel_err(y: np.ndarray, ref: np.ndarray) -> float:
    """Largest error of any column relative to that column's largest magnitude (columns of zeros: absolute)."""
    scale = np.max(np.abs(ref), axis=0)
    return float(np.max(np.max(np.abs(y - ref), axis=0) / np.where(scale > 0, scale, 1.0)))


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The seed with its deflection field and the mixed config (every sensor kind, a point mass, a spring, a weak
    segment, an elastic end), each as the FMI 3.0 and the FMI 2.0 Python FMU."""
    d = tmp_path_factory.mktemp("py3")
    cfgs = {"seed": load_config(SEED_TOML), "mixed": config_from_dict(mixed_config())}
    fmus = {name: {v: build_fmu(cfg, d / f"{name}{v}.fmu", field=name == "seed", fmi=v) for v in (2, 3)}
            for name, cfg in cfgs.items()}
    return cfgs, fmus


class Slave:
    """One fmpy ``FMU3Slave`` instance recording the FMU's log messages (status, category, text)."""

    def __init__(self, fmu: Path, token: str | None = None) -> None:
        self.md = fmpy.read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.dt = float(self.md.defaultExperiment.stepSize)
        self.messages: list[tuple[int, str, str]] = []
        self.f = FMU3Slave(guid=token or self.md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                           modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="py3")
        self.f.instantiate(logMessage=lambda env, status, category, message: self.messages.append(
            (status, category.decode(), message.decode())))

    def init(self, **params: float) -> None:
        self.f.enterInitializationMode(startTime=0.0)
        for name, value in params.items():
            self.f.setFloat64([self.vr[name]], [value])
        self.f.exitInitializationMode()

    def errors(self) -> list[str]:
        return [m for s, c, m in self.messages if s == 3 and c == "logStatusError"]


@pytest.fixture
def slave(built):
    made: list[Slave] = []

    def make(name: str) -> Slave:
        made.append(Slave(built[1][name][3]))
        return made[-1]

    yield make
    for s in made:
        s.f.freeInstance()


# ---------------------------------------------------------------------------------------------- the archive
def test_built_valid_and_fmi3_with_the_fmi2_fmus_variables(built):
    cfgs, fmus = built
    for name in ("seed", "mixed"):
        assert validate_fmu(str(fmus[name][3])) == []
        md3, md2 = (fmpy.read_model_description(str(fmus[name][v])) for v in (3, 2))
        assert md3.fmiVersion == "3.0" and md3.coSimulation.canHandleVariableCommunicationStepSize
        v3 = {v.name: v for v in md3.modelVariables}
        v2 = {v.name: v for v in md2.modelVariables}
        assert v3.pop("time").causality == "independent"
        field2 = [n for n in v2 if n.startswith("w[")]
        assert (len(field2), "w" in v3) == ((52, True) if name == "seed" else (0, False))
        for n in field2:
            assert (v2.pop(n).causality, v2.get("w")) == ("output", None)
        if field2:                                             # one array of 52 elements, not 52 scalars
            w = v3.pop("w")
            assert [int(d.start) for d in w.dimensions] == [52] and (w.causality, w.unit) == ("output", "m")
        assert v3.keys() == v2.keys()
        for n, a in v3.items():
            b = v2[n]
            assert (a.causality, a.variability, a.unit, a.description) == \
                (b.causality, b.variability, b.unit, b.description), n
            assert (a.start is None) == (b.start is None) and (a.start is None or float(a.start) == float(b.start)), n
        assert {n: float(v.start) for n, v in v3.items() if v.causality == "parameter"} == \
            cfgs[name].parameter_values()
        deps3 = {u.variable.name: sorted(d.name for d in u.dependencies or []) for u in md3.outputs}
        deps2 = {u.variable.name: sorted(d.name for d in u.dependencies or []) for u in md2.outputs}
        assert {k: v for k, v in deps3.items() if k != "w"} == {k: v for k, v in deps2.items() if k in deps3}
        mid = md3.coSimulation.modelIdentifier
        with zipfile.ZipFile(fmus[name][3]) as zf:
            names = set(zf.namelist())
        assert {f"binaries/x86_64-linux/{mid}.so", f"resources/{mid}_slave.py", f"resources/{mid}_base.py",
                "resources/pythonfmu3/fmi3slave.py"} <= names
        assert not any(n.startswith(("binaries/linux64/", "resources/pythonfmu/")) for n in names)


# ------------------------------------------------------------------------------------------------- outputs
@pytest.mark.parametrize("name", ["seed", "mixed"])
def test_outputs_equal_the_fmi2_fmu_to_the_last_bit_and_the_core(built, name):
    """Every output (the seed's field array read whole) through fmpy's FMI 3.0 loop: the FMI 2.0 Python FMU's to
    the last bit, ``ebb_model.simulate``'s within RTOL."""
    cfgs, fmus = built
    cfg = cfgs[name]
    u = np.random.default_rng(7).standard_normal((1500, len(cfg.actuators)))
    y3 = fmpy_outputs(fmus[name][3], u)
    np.testing.assert_array_equal(y3, fmpy_outputs(fmus[name][2], u))
    ref = simulate(assemble(field_config(cfg) if name == "seed" else cfg), u).outputs
    assert y3.shape == ref.shape and _rel_err(y3, ref) < RTOL


def test_parameters_set_before_initialisation_give_the_cores_model(built):
    cfg = built[0]["mixed"]
    params = {"EI": 15.0, "N": 10.0, "rhoI": 2e-3}
    u = np.random.default_rng(5).standard_normal((400, 2))
    y = fmpy_outputs(built[1]["mixed"][3], u, params=params)
    ref = simulate(assemble(cfg, params), u).outputs
    assert _rel_err(y, ref) < RTOL
    assert _rel_err(simulate(assemble(cfg), u).outputs, ref) > 1e-2
    np.testing.assert_array_equal(y, fmpy_outputs(built[1]["mixed"][2], u, params=params))


def test_a_step_of_several_samples_holds_the_input_and_time_advances(slave):
    a, b = slave("mixed"), slave("mixed")
    for s in (a, b):
        s.init()
        s.f.setFloat64([s.vr["F1"], s.vr["F2"]], [1.5, 0.25])
    a.f.doStep(0.0, 3 * a.dt)
    for k in range(3):
        b.f.doStep(k * b.dt, b.dt)
    outs = [a.vr[n] for n in ("d1", "v1", "a1")]
    np.testing.assert_allclose(a.f.getFloat64(outs), b.f.getFloat64(outs), rtol=1e-13, atol=0)
    assert a.f.getFloat64([a.vr["time"]]) == [pytest.approx(3 * a.dt, rel=1e-15)]


# -------------------------------------------------------------------------------------------------- errors
@pytest.mark.parametrize("step", [1.5, 0.5, 0.0, -1.0, math.nan])
def test_bad_step_size_is_an_error_not_a_crash(slave, step):
    s = slave("seed")
    s.init()
    with pytest.raises(FMICallException) as exc:
        s.f.doStep(0.0, step * s.dt)
    assert exc.value.status == 3  # fmi3Error, never fmi3Fatal
    assert any(m.startswith("fmi3DoStep") and "multiple of the sample time" in m for m in s.errors()), s.messages
    s.f.doStep(0.0, s.dt)        # the instance goes on


@pytest.mark.parametrize("name, value", [("EI", -1.0), ("rhoA", 0.0), ("EI", math.nan), ("N", -1e6)])
def test_bad_parameters_fail_at_exit_initialisation(slave, name, value):
    s = slave("seed")
    with pytest.raises(FMICallException) as exc:
        s.init(**{name: value})
    assert exc.value.status == 3
    errors = s.errors()
    assert errors and errors[0].startswith("fmi3ExitInitializationMode") and name in errors[0], s.messages
    with pytest.raises(FMICallException) as exc:
        s.f.doStep(0.0, s.dt)
    assert exc.value.status == 3
    s.f.reset()                  # and the instance is usable again
    s.init()
    s.f.doStep(0.0, s.dt)


@pytest.mark.parametrize("value", [math.nan, math.inf])
def test_non_finite_input_is_an_error(slave, value):
    s = slave("seed")
    s.init()
    with pytest.raises(FMICallException) as exc:
        s.f.setFloat64([s.vr["F1"]], [value])
    assert exc.value.status == 3
    assert any("F1" in m and "finite" in m for m in s.errors()), s.messages
    assert s.f.getFloat64([s.vr["y1"]]) == [0.0]


def test_misuse_and_what_the_fmu_does_not_offer_are_errors_not_fatal(slave):
    s = slave("seed")
    s.init()
    n = 52
    cases = [(lambda: s.f.setFloat64([s.vr["y1"]], [1.0]), "fmi3SetFloat64: variable 'y1'"),
             (lambda: s.f.setFloat64([s.vr["beam.length"]], [2.0]), "cannot be set"),
             (lambda: s.f.getFloat64([s.vr["w"]], nValues=3), f"3 values given for variables of {n} element(s)"),
             (lambda: s.f.getFloat64([10_000]), "fmi3GetFloat64: value references [10000]"),
             (lambda: s.f.getBoolean([s.vr["EI"]]), "this FMU has no Boolean variables"),
             (lambda: s.f.setInt32([s.vr["beam.nodes"]], [3]), "fmi3SetInt32"),
             (lambda: s.f.getFMUState(), "fmi3GetFMUState: this FMU cannot get or set its state"),
             (lambda: s.f.getDirectionalDerivative([s.vr["y1"]], [s.vr["F1"]], [1.0]), "no derivatives")]
    for call, needle in cases:
        s.messages.clear()
        with pytest.raises(FMICallException) as exc:
            call()
        assert exc.value.status == 3, needle
        assert any(needle in m for m in s.errors()), (needle, s.messages)
    assert len(s.f.getFloat64([s.vr["w"]], nValues=n)) == n
    assert s.f.getInt32([s.vr["beam.nodes"]]) == [50]
    assert s.f.getString([s.vr["beam.left"]]) == ["clamped"]


def test_a_wrong_instantiation_token_is_refused(built):
    with pytest.raises(Exception, match="instantiate"):
        Slave(built[1]["seed"][3], token="{not-this-one}")


# ----------------------------------------------------------------------------------- an independent master
@pytest.fixture(scope="module")
def host(tmp_path_factory):
    return compile_host(tmp_path_factory.mktemp("host3"), fmi=3)


def test_a_plain_c_fmi3_master_without_python_equals_fmpy(built, host, tmp_path):
    """The C master (FMI 3.0 headers, environment reduced to PATH): every output row equal to fmpy's FMI 3.0
    loop; then it asks for directional derivatives, which this FMU does not provide: an error with a logged,
    categorised message, not a crash."""
    cfg = built[0]["mixed"]
    u = np.random.default_rng(21).standard_normal((300, 2))
    proc = host_run(host, built[1]["mixed"][3], u, tmp_path / "run")
    lines = proc.stdout.splitlines()
    assert lines[len(u)] == "J", proc.stderr[-3000:]
    rows = np.array([[float(x) for x in ln.split()] for ln in lines[:len(u)]])
    np.testing.assert_array_equal(rows, fmpy_outputs(built[1]["mixed"][3], u, outputs=cfg.output_names))
    assert proc.returncode == 3 and "fmi3GetDirectionalDerivative failed with status 3" in proc.stderr
    assert "category=logStatusError: fmi3GetDirectionalDerivative: this FMU provides no derivatives" in proc.stderr


def test_a_plain_c_master_gets_errors_not_crashes(built, host, tmp_path):
    fmu = built[1]["seed"][3]
    u = np.zeros((5, 1))
    bad_step = host_run(host, fmu, u, tmp_path / "a", step=1.5e-4)
    assert bad_step.returncode == 3, bad_step.stderr[-3000:]
    assert "fmi3DoStep failed with status 3" in bad_step.stderr
    assert "category=logStatusError: fmi3DoStep: communication step size" in bad_step.stderr
    bad_param = host_run(host, fmu, u, tmp_path / "b", params={"EI": -1.0})
    assert bad_param.returncode == 3
    assert "fmi3ExitInitializationMode failed with status 3" in bad_param.stderr and "EI" in bad_param.stderr


def test_a_host_whose_python_lacks_a_package_gets_a_categorised_message(built, host, tmp_path):
    """The FMU's Python meets a numba that fails to import (a module of that name first on PYTHONPATH):
    instantiation fails, pythonfmu3's message (logged without a category) reaches the host as logStatusFatal."""
    shadow = tmp_path / "shadow"
    (shadow / "numba").mkdir(parents=True)
    (shadow / "numba" / "__init__.py").write_text("raise ImportError('numba is broken in this environment')\n")
    proc = host_run(host, built[1]["seed"][3], np.zeros((3, 1)), tmp_path / "run",
                    env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(shadow)})
    assert proc.returncode == 3, (proc.returncode, proc.stderr[-2000:])
    assert "fmi3InstantiateCoSimulation failed" in proc.stderr
    assert "status=4 category=logStatusFatal: Fatal py exception" in proc.stderr, proc.stderr[-2000:]
    assert "ImportError('numba is broken in this environment')" in proc.stderr, proc.stderr[-2000:]


# ---------------------------------------------------------------------------------------------------- CLI
def test_cli_builds_the_python_fmu_in_fmi3(tmp_path, capsys):
    out = tmp_path / "py3.fmu"
    assert main(["build-fmu", str(SEED_TOML), "--fmi", "3", "--field", "--out", str(out)]) == 0
    md = fmpy.read_model_description(str(out))
    assert md.fmiVersion == "3.0" and md.generationTool.startswith("PythonFMU3") and validate_fmu(str(out)) == []
    with pytest.raises(FmuError, match="2 or 3"):
        build_fmu(SEED_TOML, tmp_path / "x.fmu", fmi=4)
    assert not (tmp_path / "x.fmu").exists()


def test_the_diagnosed_model_exports_the_python_fmu_in_fmi3(tmp_path):
    """``ebb diagnose --target fmu_fmi3`` (``export_corrected(..., targets=["fmu_fmi3"])``): the corrected beam as
    the Python FMU in FMI 3.0, its outputs those of the core under the corrected parameters."""
    from diagnosis.corrected.export import export_corrected
    from diagnosis.effects import AugmentedModel

    cfg = load_config(SEED_TOML)
    params = cfg.parameter_values() | {"EI": 10.5, "c": 0.2}
    files = export_corrected(AugmentedModel(cfg, params), tmp_path / "corrected", {"effect": "test"},
                             targets=["fmu_fmi3"])
    fmu = tmp_path / "corrected" / "corrected_fmi3.fmu"
    assert fmu in files and fmpy.read_model_description(str(fmu)).fmiVersion == "3.0"
    u = np.random.default_rng(13).standard_normal((300, len(cfg.actuators)))
    assert _rel_err(fmpy_outputs(fmu, u), simulate(assemble(cfg, params), u).outputs) <= RTOL
