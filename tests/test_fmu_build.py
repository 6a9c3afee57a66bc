"""Building the beam FMU: validity, model description, identity, typed errors, the CLI."""
from __future__ import annotations

import json
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

import pythonfmu  # noqa: F401 - a dependency: a broken install must fail, not skip
from fmpy import read_model_description  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent / "fmu_hosts"))
from fmu_configs import SEED_TOML, mixed_config  # noqa: E402

import fmu_build.builder as builder_module  # noqa: E402
from ebb_model import assemble, config_from_dict, load_config  # noqa: E402
from ebb_model.errors import ConfigError, FmuError, ParameterError, StabilityError  # noqa: E402
from fmu_build import build_fmu  # noqa: E402


@pytest.fixture(scope="module")
def seed_fmu(tmp_path_factory) -> Path:
    return build_fmu(SEED_TOML, tmp_path_factory.mktemp("seed") / "beam.fmu")


@pytest.fixture(scope="module")
def mixed_fmu(tmp_path_factory) -> Path:
    return build_fmu(config_from_dict(mixed_config()), tmp_path_factory.mktemp("mixed") / "mixed.fmu", field=True)


def _variables(md):
    return {v.name: v for v in md.modelVariables}


def test_validate_fmu_reports_nothing(seed_fmu, mixed_fmu):
    assert validate_fmu(str(seed_fmu)) == []
    assert validate_fmu(str(mixed_fmu)) == []


def test_variables_units_and_causality(seed_fmu):
    md = read_model_description(str(seed_fmu))
    v = _variables(md)
    for name, unit in {"EI": "N.m2", "rhoA": "kg/m", "c": "N.s/m2", "eta": "s", "N": "N",
                       "rhoI": "kg.m", "kf": "N/m2"}.items():
        assert (v[name].causality, v[name].variability, v[name].unit) == ("parameter", "tunable", unit)
        assert v[name].description
    cfg = load_config(SEED_TOML)
    assert float(v["EI"].start) == cfg.parameter_values()["EI"]
    assert (v["F1"].causality, v["F1"].unit) == ("input", "N")
    assert [(v[s].causality, v[s].unit) for s in ("y1", "y2")] == [("output", "m")] * 2
    for name in ("beam.length", "beam.nodes", "beam.left", "time.dt", "time.theta", "time.substeps",
                 "actuators.F1.x", "sensors.y1.x", "sensors.y2.kind"):
        assert (v[name].causality, v[name].variability) == ("calculatedParameter", "fixed"), name
    assert float(md.defaultExperiment.stepSize) == pytest.approx(1e-4, rel=1e-15)
    assert "Python" in md.description and "numpy" in md.description
    assert md.coSimulation.canHandleVariableCommunicationStepSize


def test_units_of_all_sensor_kinds_and_feedthrough_dependencies(mixed_fmu):
    md = read_model_description(str(mixed_fmu))
    v = _variables(md)
    assert [v[s].unit for s in ("d1", "v1", "a1")] == ["m", "m/s", "m/s2"]
    deps = {u.variable.name: sorted(d.name for d in (u.dependencies or [])) for u in md.outputs}
    # the default (exact) scheme with its first-order hold: the state reached at t_k depends on u_k (the force
    # ramps to it within the last sample), so every output that can move depends on both inputs at once
    assert deps["d1"] == deps["v1"] == deps["a1"] == ["F1", "F2"]
    field = [n for n in v if n.startswith("w[")]
    assert len(field) == 30 + 2
    assert deps["w[0]"] == []                                    # the pinned end does not move
    assert all(deps[n] == ["F1", "F2"] for n in field[1:])         # the elastic end does
    initial = {u.variable.name for u in md.initialUnknowns}
    assert {"d1", "v1", "a1", "beam.length", "masses.m1.mass", "springs.k1.k", "beam.right_kt"} <= initial


def test_binaries_resources_and_embedded_config(seed_fmu):
    md = read_model_description(str(seed_fmu))
    mid = md.coSimulation.modelIdentifier
    with zipfile.ZipFile(seed_fmu) as zf:
        names = set(zf.namelist())
        spec = json.loads(zf.read("resources/ebb_fmu.json"))
        entry = zf.read(f"resources/{mid}.py").decode()
    assert f"binaries/linux64/{mid}.so" in names
    assert f"resources/{mid}_slave.py" in names
    assert any(n.startswith("resources/ebb_core_") and n.endswith("/assemble.py") for n in names)
    # byte code and the core's compiled kernels only (fmu_build.kernels; test_fmu_start.py)
    cached = [n for n in names if "/__pycache__/" in n]
    assert all(n.endswith(".pyc") or (n.startswith("resources/ebb_core_") and n.endswith((".nbi", ".nbc")))
               for n in cached)
    assert any(n.endswith(".nbc") for n in cached) and f"resources/__pycache__/{mid}_slave.cpython-" in " ".join(cached)
    # the model core only: no reference solutions, data generator, file readers or reports
    core = {n.split("/", 2)[2] for n in names if n.startswith("resources/ebb_core_")}
    assert "stability/bistritz.py" in core and "config/__init__.py" in core
    assert not any(n.startswith("reference/") for n in core)
    assert not core & {"io/signals_io.py", "io/csvio.py", "reports.py", "io/jsonio.py"}
    assert config_from_dict(spec["config"]) == load_config(SEED_TOML)
    assert mid in entry and "import" in entry


def test_each_build_has_its_own_identity(tmp_path):
    a = read_model_description(str(build_fmu(SEED_TOML, tmp_path / "a.fmu")))
    b = read_model_description(str(build_fmu(SEED_TOML, tmp_path / "b.fmu")))
    assert a.guid != b.guid
    assert a.coSimulation.modelIdentifier != b.coSimulation.modelIdentifier
    assert a.coSimulation.modelIdentifier.startswith("seed_clamped_")


def test_build_replaces_existing_file(tmp_path):
    out = tmp_path / "beam.fmu"
    out.write_bytes(b"old")
    build_fmu(SEED_TOML, out)
    assert zipfile.is_zipfile(out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["beam.fmu"]


def test_invalid_config_is_a_config_error_and_leaves_nothing(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(SEED_TOML.read_text().replace("nodes = 50", "nodes = 2"))
    with pytest.raises(ConfigError, match="nodes"):
        build_fmu(bad, tmp_path / "out.fmu")
    with pytest.raises(ConfigError):
        build_fmu(tmp_path / "missing.toml", tmp_path / "out.fmu")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]


def test_unstable_nominal_parameters_are_refused(tmp_path):
    d = mixed_config()
    d["parameters"]["N"] = {"value": -1e6}
    with pytest.raises((StabilityError, ParameterError), match="N"):
        build_fmu(config_from_dict(d), tmp_path / "out.fmu")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("target", ["no_such_dir/beam.fmu", "afile/beam.fmu", "beam.zip", "."])
def test_unusable_output_path_is_an_fmu_error(tmp_path, target):
    (tmp_path / "afile").write_text("x")
    out = tmp_path if target == "." else tmp_path / target
    with pytest.raises(FmuError):
        build_fmu(SEED_TOML, out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_failure_while_writing_leaves_no_partial_fmu(tmp_path, monkeypatch):
    out = tmp_path / "beam.fmu"
    out.write_bytes(b"previous build")

    def broken(*args, **kwargs):
        raise FmuError("compiler exploded", function="build_fmu")

    monkeypatch.setattr(builder_module, "compile_loader", broken)
    with pytest.raises(FmuError, match="compiler exploded"):
        build_fmu(SEED_TOML, out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["beam.fmu"]
    assert out.read_bytes() == b"previous build"


def test_reserved_signal_names_are_refused(tmp_path):
    d = mixed_config()
    d["sensors"][0]["name"] = "w"
    with pytest.raises(FmuError, match="w"):
        build_fmu(config_from_dict(d), tmp_path / "out.fmu")


def test_cli_in_process(tmp_path, capsys):
    from ebb_cli import main

    out = tmp_path / "cli.fmu"
    assert main(["build-fmu", str(SEED_TOML), "--out", str(out), "--field"]) == 0
    md = read_model_description(str(out))
    assert any(v.name == "w[0]" for v in md.modelVariables)
    assert main(["build-fmu", str(tmp_path / "missing.toml"), "--out", str(out)]) == 2
    assert "error" in capsys.readouterr().err


def test_cli_subprocess(tmp_path):
    out = tmp_path / "sub.fmu"
    cmd = [sys.executable, "-m", "ebb_cli", "build-fmu", str(SEED_TOML), "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert validate_fmu(str(out)) == []
    bad = subprocess.run(cmd[:-1] + [str(tmp_path / "nodir" / "x.fmu")], capture_output=True, text=True,
                         timeout=300)
    assert bad.returncode == 2 and "does not exist" in bad.stderr


def test_nominal_system_matches_core(seed_fmu):
    """The FMU's defaults are the config's nominal values (the same system the core assembles)."""
    md = read_model_description(str(seed_fmu))
    cfg = load_config(SEED_TOML)
    starts = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    assert starts == cfg.parameter_values()
    assert assemble(cfg).dt == pytest.approx(float(md.defaultExperiment.stepSize), rel=1e-15)


def test_missing_c_compiler_is_an_fmu_error(tmp_path, monkeypatch):
    import fmu_build.loader as loader_module

    monkeypatch.setattr(loader_module.shutil, "which", lambda name: None)
    with pytest.raises(FmuError, match="compiler"):
        build_fmu(SEED_TOML, tmp_path / "beam.fmu")
    assert list(tmp_path.iterdir()) == []


def test_the_bundle_finds_every_import_statement_at_any_depth():
    """The bundle renames and follows imports found by visiting statements only; every place a statement can
    hold one must be reached (the reference: ``ast.walk`` over every node)."""
    import ast

    from fmu_build.bundle import _import_statements

    source = '''
import a
from b import c
def f():
    import d
    class K:
        from e import g
        def m(self):
            if x:
                import h
            elif y:
                import i
            else:
                import j
for _ in range(2):
    import k
else:
    import l
while False:
    import m
else:
    import n
try:
    import o
except ImportError:
    import p
else:
    import q
finally:
    import r
with ctx():
    import s
async def af():
    async with ctx():
        import t
    async for _ in it():
        import u
match v:
    case 1:
        import w
    case _:
        from . import z
'''
    tree = ast.parse(source)
    reference = {ast.dump(n) for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))}
    found = [ast.dump(n) for n in _import_statements(tree)]
    assert len(reference) == 20          # a, b … z: one per place
    assert sorted(found) == sorted(reference)
