"""The beam FMU outside fmpy: a plain C master, libcosim (OSP), two FMUs in one process, lifecycle.

Every master runs in its own process (a crash at interpreter exit must not
take the test session down).  The C master's process has no Python at all and
an environment reduced to ``PATH``: the FMU's loader must find the
interpreter itself.  fmpy's outputs are the reference (1e-12 relative).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pythonfmu  # noqa: F401 - a dependency: a broken install must fail, not skip
import fmpy  # noqa: F401

HOSTS = Path(__file__).resolve().parent / "fmu_hosts"
sys.path.insert(0, str(HOSTS))
from fmu_configs import SEED_TOML, mixed_config  # noqa: E402
from fmu_loops import compile_host, fmpy_outputs, host_run  # noqa: E402

from ebb_model import assemble, config_from_dict, load_config, simulate  # noqa: E402
from fmu_build import build_fmu  # noqa: E402

LOOPS = HOSTS / "fmu_loops.py"
RTOL_HOSTS = 1e-12


def _rel_err(y: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.max(np.abs(y - ref), axis=0) / np.max(np.abs(ref), axis=0)))


def _run(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    proc = subprocess.run([sys.executable, str(LOOPS), *args], capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    d = tmp_path_factory.mktemp("fmus")
    return {"seed": build_fmu(SEED_TOML, d / "seed.fmu"),
            "mixed": build_fmu(config_from_dict(mixed_config()), d / "mixed.fmu")}


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    return compile_host(tmp_path_factory.mktemp("host"))  # gcc is required anyway (it builds the FMU's loader)


@pytest.mark.parametrize("name", ["seed", "mixed"])
def test_c_host_matches_fmpy(fmus, host, tmp_path, name):
    u = np.random.default_rng(21).standard_normal((800, 2 if name == "mixed" else 1))
    proc = host_run(host, fmus[name], u, tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    y = np.loadtxt(proc.stdout.splitlines(), ndmin=2)
    ref = fmpy_outputs(fmus[name], u)
    assert y.shape == ref.shape
    assert _rel_err(y, ref) <= RTOL_HOSTS
    # the loader started Python without leaving environment variables behind
    assert "after fmi2Instantiate: PYTHONHOME=(unset) PYTHONPATH=(unset)" in proc.stderr


def test_c_host_keeps_user_python_variables(fmus, host, tmp_path):
    """Variables the user did set are neither overwritten nor removed."""
    import sysconfig

    home = sys.base_prefix
    site = sysconfig.get_path("purelib")
    proc = host_run(host, fmus["seed"], np.zeros((3, 1)), tmp_path,
                    env={"PATH": "/usr/bin:/bin", "PYTHONHOME": home, "PYTHONPATH": site})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert f"after fmi2Instantiate: PYTHONHOME={home} PYTHONPATH={site}" in proc.stderr


def test_c_host_gets_errors_not_crashes(fmus, host, tmp_path):
    u = np.zeros((5, 1))
    bad_step = host_run(host, fmus["seed"], u, tmp_path / "a", step=1.5e-4)
    assert bad_step.returncode == 3, bad_step.stderr
    assert "fmi2DoStep failed with status 3" in bad_step.stderr
    assert "multiple of the sample time" in bad_step.stderr
    bad_param = host_run(host, fmus["seed"], u, tmp_path / "b", params={"EI": -1.0})
    assert bad_param.returncode == 3
    assert "fmi2ExitInitializationMode failed with status 3" in bad_param.stderr
    assert "EI" in bad_param.stderr


def test_c_host_with_parameters_matches_core(fmus, host, tmp_path):
    cfg = load_config(SEED_TOML)
    params = {"EI": 15.0, "N": 10.0}
    u = np.random.default_rng(2).standard_normal((300, 1))
    proc = host_run(host, fmus["seed"], u, tmp_path, params=params)
    assert proc.returncode == 0, proc.stderr[-3000:]
    y = np.loadtxt(proc.stdout.splitlines(), ndmin=2)
    assert _rel_err(y, simulate(assemble(cfg, params), u).outputs) < 1e-10


@pytest.mark.parametrize("name", ["seed", "mixed"])
def test_libcosim_matches_fmpy(fmus, tmp_path, name):
    u = np.random.default_rng(4).standard_normal((600, 2 if name == "mixed" else 1))
    np.save(tmp_path / "u.npy", u)
    _run("cosim", str(fmus[name]), str(tmp_path / "u.npy"), str(tmp_path / "y.npy"))
    y = np.load(tmp_path / "y.npy")
    ref = fmpy_outputs(fmus[name], u, protocol="after")
    assert _rel_err(y, ref) <= RTOL_HOSTS


def test_two_fmus_side_by_side_in_one_process(fmus, tmp_path):
    u = np.random.default_rng(9).standard_normal((400, 1))
    np.save(tmp_path / "u.npy", u)
    _run("two", str(fmus["seed"]), str(fmus["mixed"]), str(tmp_path / "u.npy"),
         str(tmp_path / "a.npy"), str(tmp_path / "b.npy"))
    seed_ref = simulate(assemble(load_config(SEED_TOML)), u).outputs
    mixed_ref = simulate(assemble(config_from_dict(mixed_config())), np.hstack([u, u])).outputs
    assert _rel_err(np.load(tmp_path / "a.npy"), seed_ref) < 1e-10
    assert _rel_err(np.load(tmp_path / "b.npy"), mixed_ref) < 1e-10


def test_two_builds_of_one_config_side_by_side(tmp_path):
    """Same config, two builds with different nominal parameters: each keeps its own model."""
    cfg = load_config(SEED_TOML)
    stiff = cfg.with_parameters(EI=30.0)
    a = build_fmu(cfg, tmp_path / "a.fmu")
    b = build_fmu(stiff, tmp_path / "b.fmu")
    u = np.random.default_rng(1).standard_normal((300, 1))
    np.save(tmp_path / "u.npy", u)
    _run("two", str(a), str(b), str(tmp_path / "u.npy"), str(tmp_path / "ya.npy"), str(tmp_path / "yb.npy"))
    assert _rel_err(np.load(tmp_path / "ya.npy"), simulate(assemble(cfg), u).outputs) < 1e-10
    assert _rel_err(np.load(tmp_path / "yb.npy"), simulate(assemble(stiff), u).outputs) < 1e-10


def test_thousand_instantiate_reset_free_cycles_keep_memory_flat(fmus):
    proc = _run("lifecycle", str(fmus["seed"]), "1000", timeout=600)
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert result["cycles"] == 1000
    assert result["rss_growth_mb"] < 20.0, result
    assert result["sys_path_entries"] < 50, result


def _valgrind_errors_in(stderr: str, needle: str) -> list[str]:
    """Valgrind error records (first lines) whose stack or allocation names ``needle``."""
    records, current = [], []
    for line in stderr.splitlines():
        body = line.split("== ", 1)[1] if line.startswith("==") and "== " in line else None
        if body is None:
            continue
        if body and not body.startswith(" "):  # a record's headline
            if current:
                records.append(current)
            current = [body]
        elif current:
            current.append(body)
    if current:
        records.append(current)
    return [r[0] for r in records if any(needle in x for x in r[1:])]


@pytest.mark.parametrize("master", ["c-host", "fmpy"])
def test_no_use_after_free_when_the_process_exits(fmus, host, tmp_path, master):
    """pythonfmu's library cannot be unloaded; its state must be released once, not twice, at exit.

    Before the loader reset pythonfmu's interpreter state itself, every process
    that had instantiated the FMU read freed memory at exit (valgrind shows it
    deterministically; without valgrind it aborted now and then with
    "corrupted double-linked list").

    The model's compiled kernels are run as Python here (``NUMBA_DISABLE_JIT``): what is checked is the
    wrapper's life cycle (load, instantiate, step, free, exit), and compiling the kernels under valgrind took most
    of the test's time (the fmpy run 5–7 min with them, 75 s without, on 2 cores).
    """
    import shutil

    if shutil.which("valgrind") is None:
        pytest.skip("valgrind is not installed")
    library = "_pythonfmu.so"
    if master == "c-host":
        env = {"PATH": "/usr/bin:/bin", "NUMBA_DISABLE_JIT": "1",
               **{k: v for k, v in os.environ.items() if k.startswith("OPENBLAS_")}}
        proc = host_run(host, fmus["seed"], np.zeros((20, 1)), tmp_path, wrapper=["valgrind", "--num-callers=40"],
                        env=env, timeout=900)
    else:
        np.save(tmp_path / "u.npy", np.zeros((20, 1)))
        proc = subprocess.run(["valgrind", "--num-callers=40", sys.executable, str(LOOPS), "fmpy",
                               str(fmus["seed"]), str(tmp_path / "u.npy"), str(tmp_path / "y.npy")],
                              capture_output=True, text=True, timeout=900,
                              env={**os.environ, "NUMBA_DISABLE_JIT": "1"})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "ERROR SUMMARY" in proc.stderr  # valgrind did run to the end
    assert _valgrind_errors_in(proc.stderr, library) == []


def test_a_master_that_accumulates_float_time(fmus):
    """A master that accumulates its time in floating point (``t += dt``, as OMSimulator does) and passes it as the
    communication point: 2000 steps of 1e-4 s arrive 5.7e-15 s short of its stop time 0.2 s, and it steps the
    rest.  The FMU takes that remainder as no step (it refused it before: "not a positive integer multiple"); the
    outputs equal fmpy's integer-time loop to the last digit, and after the remainder they are those after the last
    full step."""
    u = np.random.default_rng(5).standard_normal((2000, 1))
    y = fmpy_outputs(fmus["seed"], u, protocol="accumulating")
    assert _rel_err(y[:-1], fmpy_outputs(fmus["seed"], u)) <= RTOL_HOSTS
    assert np.array_equal(y[-1], fmpy_outputs(fmus["seed"], u, protocol="after")[-1])


def test_a_null_category_never_reaches_the_host(fmus, host, tmp_path):
    """pythonfmu logs some fatal errors with a NULL category; a host that builds strings from it (OMSimulator)
    aborts.  The loader passes "" on.  The C host here aborts on a NULL, as OMSimulator does; the FMU's Python
    meets a numba that fails to import (a module of that name first on PYTHONPATH), so instantiation fails and
    is logged — the host gets the message and an error status, not an abort."""
    shadow = tmp_path / "shadow"
    (shadow / "numba").mkdir(parents=True)
    (shadow / "numba" / "__init__.py").write_text("raise ImportError('numba is broken in this environment')\n")
    proc = host_run(host, fmus["seed"], np.zeros((3, 1)), tmp_path / "run",
                    env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(shadow), "FMI2_HOST_REJECT_NULL": "1"})
    assert "logger called with a NULL" not in proc.stderr, proc.stderr[-2000:]
    assert proc.returncode == 3, (proc.returncode, proc.stderr[-2000:])
    assert "numba is broken in this environment" in proc.stderr, proc.stderr[-2000:]
