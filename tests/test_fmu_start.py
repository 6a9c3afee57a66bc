"""The pythonfmu FMU carries its core compiled and its model at its own parameter values (issue 74): a host's fresh
process compiles nothing before the first step — no numba kernel, no byte code — at those values assembles
nothing either, and the outputs are the model's.

How it is checked: the FMU is extracted into a writable folder and run through fmpy in a new Python process
(instantiate, initialise, one step). Whatever numba compiles there it writes into the extracted core's
``__pycache__``, and whatever byte code Python finds invalid it writes anew, so a compile shows as a new or
changed file. A control strips the carried files from the same FMU and sees the kernels compiled: the check
can fail. How long the start takes is measured in ``benchmarks/bench_fmu.py``, not here.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "fmu_hosts"))
from fmu_configs import SEED_TOML, mixed_config, substep_config  # noqa: E402

from ebb_model import assemble, config_from_dict, load_config, simulate  # noqa: E402
from fmu_build import build_fmu  # noqa: E402
from fmu_build.kernels import KERNEL_SUFFIXES  # noqa: E402
from fmu_build.slave_template import MODEL_FILE  # noqa: E402

#: One fresh process: instantiate, initialise, one step of a unit force on the first input; the outputs as JSON.
FIRST_STEP = """
import json, sys
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave
d = sys.argv[1]
md = read_model_description(d)
vr = {v.name: v.valueReference for v in md.modelVariables}
f = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="x")
f.instantiate()
f.setupExperiment(startTime=0.0)
f.enterInitializationMode()
for name, value in json.loads(sys.argv[2]).items():
    f.setReal([vr[name]], [value])
f.exitInitializationMode()
inputs = [v for v in md.modelVariables if v.causality == "input"]
outputs = [v for v in md.modelVariables if v.causality == "output"]
f.setReal([inputs[0].valueReference], [1.0])
f.doStep(0.0, float(md.defaultExperiment.stepSize))
out = {v.name: f.getReal([v.valueReference])[0] for v in outputs}
print(json.dumps({"outputs": out, "scipy": "scipy.linalg" in sys.modules}))
f.terminate()
f.freeInstance()
"""

#: The environment variables that set the number of BLAS threads in a new process.
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")

#: Parameter values set before the first step: the FMU's own (the model it carries) or EI 10 % up (assembled).
VALUES = {"own values": {}, "EI tuned": {"EI": 1.1}}


def _cached(folder: Path) -> dict[Path, int]:
    """Every file in a ``__pycache__`` below ``folder``, with its modification time."""
    return {p: p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file() and p.parent.name == "__pycache__"}


def _first_step(fmu: Path, folder: Path, *, strip: bool = False, values: dict[str, float] | None = None,
                without_model: bool = False) -> tuple[dict[str, float], list[str], bool]:
    """The outputs after one step in a fresh process, the cache files that process wrote and whether it imported
    scipy's linear algebra (``strip``: the FMU's carried cache removed first; ``values``: factors of parameters set
    before the first step; ``without_model``: the model the FMU carries removed first)."""
    with zipfile.ZipFile(fmu) as zf:
        zf.extractall(folder)
        default = {v.get("name"): float(v[0].get("start")) for v in _variables(zf) if v[0].get("start") is not None}
    if strip:
        for p in _cached(folder):
            p.unlink()
    if without_model:
        (folder / "resources" / MODEL_FILE).unlink()
    before = _cached(folder)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONDONTWRITEBYTECODE", "NUMBA_CACHE_DIR",
                                                             "NUMBA_DISABLE_JIT")}
    # BLAS with this process's one thread (conftest): its threads change the order of the sums of a matrix
    # product, so the model a host assembles differs in its last bits from one BLAS thread count to another
    # (measured on the seed config: 1.8e-15 in C, 1 vs 2 threads) — and the FMU's model is made here
    env.update({name: "1" for name in BLAS_THREADS})
    tuned = {name: factor * default[name] for name, factor in (values or {}).items()}
    run = subprocess.run([sys.executable, "-c", FIRST_STEP, str(folder), json.dumps(tuned)], capture_output=True,
                         text=True, env=env, timeout=300)
    assert run.returncode == 0, run.stderr
    after = _cached(folder)
    written = sorted(p.relative_to(folder).as_posix() for p in after if before.get(p) != after[p])
    got = json.loads(run.stdout)
    return got["outputs"], written, got["scipy"]


def _variables(zf: zipfile.ZipFile) -> list:
    """The ``ScalarVariable`` elements of the FMU's model description."""
    import xml.etree.ElementTree as ET

    return ET.fromstring(zf.read("modelDescription.xml")).findall("ModelVariables/ScalarVariable")


def _reference(cfg, values: dict[str, float]) -> np.ndarray:
    """The model's outputs after one step of a unit force on the first input, at the config's parameter values
    times the factors ``values``."""
    tuned = cfg.with_parameters(**{n: f * float(cfg.parameters[n].value) for n, f in values.items()})
    u = np.zeros((2, len(cfg.actuators)))
    u[:, 0] = 1.0                                   # the force set at the start and held over the step
    return simulate(assemble(tuned), u).outputs[1]


CONFIGS = {"seed": lambda: load_config(SEED_TOML), "mixed": lambda: config_from_dict(mixed_config()),
           "theta scheme": lambda: config_from_dict(substep_config())}


@pytest.mark.parametrize("field", [False, True], ids=["sensors", "field"])
@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_a_fresh_process_compiles_nothing_before_the_first_step(name, field, tmp_path):
    """At the FMU's own parameter values (the model it carries) and at others (assembled with the carried kernels):
    nothing compiled, the model's outputs."""
    cfg = CONFIGS[name]()
    fmu = build_fmu(cfg, tmp_path / "beam.fmu", field=field)
    with zipfile.ZipFile(fmu) as zf:
        names = zf.namelist()
    core = [n for n in names if n.startswith("resources/ebb_core_") and "/__pycache__/" in n]
    assert all(n.endswith((".pyc", *KERNEL_SUFFIXES)) for n in core)
    for label, values in VALUES.items():
        outputs, written, _ = _first_step(fmu, tmp_path / label, values=values)
        assert written == [], label
        # the outputs of that process are the model's after one step (the FMU's own equivalence to 1e-10 is
        # test_fmu_fmpy's; here it shows the carried model and kernels are the ones the model runs)
        ref = _reference(cfg, values)
        got = np.array([outputs[s.name] for s in cfg.sensors])
        assert np.max(np.abs(got - ref)) <= 1e-10 * np.max(np.abs(ref)), label


def test_the_carried_model_is_the_one_the_host_would_assemble(tmp_path):
    """At its own values the FMU steps the model it carries — scipy's linear algebra not loaded, no assembly — and
    that model's outputs are bit for bit those the same FMU gives when the host's process assembles it (the file
    removed)."""
    fmu = build_fmu(load_config(SEED_TOML), tmp_path / "beam.fmu")
    carried, _, scipy_carried = _first_step(fmu, tmp_path / "carried")
    assembled, _, scipy_assembled = _first_step(fmu, tmp_path / "assembled", without_model=True)
    assert carried == assembled
    assert not scipy_carried and scipy_assembled      # the control: assembling loads it (numba's linear algebra)


def test_without_the_carried_cache_the_kernels_compile(tmp_path):
    """The control: the same FMU stripped of its carried cache compiles its kernels in the host's process when it
    assembles (parameters other than its own)."""
    fmu = build_fmu(load_config(SEED_TOML), tmp_path / "beam.fmu")
    outputs, written, _ = _first_step(fmu, tmp_path / "extracted", strip=True, values=VALUES["EI tuned"])
    assert any(w.endswith(".nbi") for w in written) and any(w.endswith(".pyc") for w in written)
    carried, again, _ = _first_step(fmu, tmp_path / "again", values=VALUES["EI tuned"])
    assert again == [] and carried == outputs


def test_a_cache_directory_that_cannot_be_written_leaves_a_working_fmu(tmp_path, monkeypatch):
    """The carried kernels only accelerate: a builder whose cache directory is unusable (a file in its place)
    still writes an FMU that runs, with its byte code."""
    blocker = tmp_path / "blocker"
    blocker.write_text("not a directory")
    monkeypatch.setenv("EBB_MODEL_CACHE", str(blocker / "cache"))
    cfg = load_config(SEED_TOML)
    fmu = build_fmu(cfg, tmp_path / "beam.fmu")
    with zipfile.ZipFile(fmu) as zf:
        assert any(n.endswith(f"_slave.{sys.implementation.cache_tag}.pyc") for n in zf.namelist())
    outputs, _, _ = _first_step(fmu, tmp_path / "extracted")
    got = np.array([outputs[s.name] for s in cfg.sensors])
    ref = _reference(cfg, {})
    assert np.max(np.abs(got - ref)) <= 1e-10 * np.max(np.abs(ref))
