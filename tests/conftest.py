"""Shared fixtures: config factories and a single-threaded BLAS for the whole session.

The suite's test processes are its parallelism (``run.sh test``: one per core), so the blind diagnoses run their
refits in the test's own process (``diagnose(..., workers=1)``): a pool of their own would double-book the cores
and start two interpreters per diagnosis (measured: 5.3 CPU-s more per diagnosis with both cores busy).  That the
pool and a Dask cluster give the single process's diagnosis is tested in ``test_diagnose_dask.py``; the CLI's
tests and the demo keep the default pool.
"""
from __future__ import annotations

import math
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import ebb_model as em
from ebb_model import config_from_dict
from ebb_model.threads import single_blas_thread


@pytest.fixture(scope="session", autouse=True)
def _single_thread_blas():
    # many small dense problems: BLAS threads only thrash on the 2-core CI machine
    with single_blas_thread():
        yield


def make_config(left: str = "clamped", right: str = "clamped", *, length: float = 1.0, nodes: int = 50,
                dt: float = 1e-4, theta: float = 0.25, substeps: int = 1, EI: float = 10.0,
                rhoA: float = 1.0, c: float = 0.0, eta: float = 0.0, N: float = 0.0,
                actuators: list[tuple[str, float]] | None = None,
                sensors: list[tuple[str, float, str]] | None = None,
                masses: list[tuple[str, float, float]] | None = None,
                springs: list[tuple[str, float, float]] | None = None,
                left_springs: tuple[float, float] | None = None,
                right_springs: tuple[float, float] | None = None, scheme: str | None = None):
    """Build a validated config from keyword arguments (tests only); ``scheme=None``: the project's default."""
    beam: dict[str, Any] = {"length": length, "nodes": nodes, "left": left, "right": right}
    for side, sp in (("left", left_springs), ("right", right_springs)):
        if sp is not None:
            beam[f"{side}_kt"], beam[f"{side}_kr"] = sp
    d: dict[str, Any] = {
        "beam": beam,
        "time": {"dt": dt, "theta": theta, "substeps": substeps} | ({"scheme": scheme} if scheme else {}),
        "parameters": {"EI": {"value": EI}, "rhoA": {"value": rhoA}, "c": {"value": c},
                       "eta": {"value": eta}, "N": {"value": N}},
        "actuators": [{"name": n, "x": x} for n, x in (actuators or [("F1", 0.3 * length)])],
        "sensors": [{"name": n, "x": x, "kind": k}
                    for n, x, k in (sensors or [("y1", 0.5 * length, "displacement"),
                                                ("y2", 0.71 * length, "displacement")])],
    }
    if masses:
        d["masses"] = [{"name": n, "x": x, "mass": m} for n, x, m in masses]
    if springs:
        d["springs"] = [{"name": n, "x": x, "k": k} for n, x, k in springs]
    return config_from_dict(d)


@pytest.fixture
def cfg_factory():
    return make_config


INF = math.inf


def make_identification_config(**kw):
    """``make_config(**kw)`` with EI ∈ [5, 20] and N ∈ [0, 100] marked for identification (tests only)."""
    d = make_config(**kw).to_dict()
    d["parameters"]["EI"].update(bounds=[5.0, 20.0], identify=True)
    d["parameters"]["N"].update(bounds=[0.0, 100.0], identify=True)
    return config_from_dict(d, extra_sections=("identification",))


def foh_reference(cfg, u):
    """Sensor outputs and nodal deflection field by the *non-causal* first-order-hold recursion (tests only).

    ``x[k+1] = Φ x[k] + Γ₀ u[k] + Γ₁ u[k+1]`` on the physical state
    ``(q, v)``, ``y[k] = C x[k] + D u[k]``: an independent check of the causal
    realisation that the core builds.
    """
    import numpy as np

    from ebb_model import field_matrix
    from ebb_model.space.discretisation import discretise
    from ebb_model.theta.theta_scheme import hold_matrices, one_step, output_matrices, theta_coefficients

    ts = cfg.time
    beam = discretise(cfg)
    co = theta_coefficients(beam, ts.dt, ts.theta, ts.substeps)
    S, G = one_step(co.Kt, co.Ct, co.Bt, co.tau)
    Phi, G0, G1 = hold_matrices(S, G, ts.substeps, "foh")
    C, D = output_matrices(beam.S, beam.sensor_kinds, co.Kt, co.Ct, co.Bt, co.tau)
    _, Cf = field_matrix(cfg)
    u = np.atleast_2d(np.asarray(u, float).T).T
    x = np.zeros(Phi.shape[0])
    y = np.empty((u.shape[0], C.shape[0]))
    w = np.empty((u.shape[0], Cf.shape[0]))
    for k in range(u.shape[0]):
        y[k] = C @ x + D @ u[k]
        w[k] = Cf @ x
        x = Phi @ x + G0 @ u[k] + G1 @ u[min(k + 1, u.shape[0] - 1)]
    return y, w


def run_identify_signalled(cfg: Path, data: Path, out: Path, sig: int, after_generation: int,
                           *extra: str) -> subprocess.CompletedProcess:
    """Run ``ebb identify`` in a subprocess that sends itself ``sig`` right after checkpoint ``after_generation``.

    Deterministic: the signal follows a given checkpoint, whatever the machine's speed (no polling race).
    """
    script = textwrap.dedent(f"""
        import os, signal, sys
        # Ctrl-C handled as under a terminal, whatever the test process left to its children (an inherited
        # "ignore" would keep Python from installing its handler, and the run would finish)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        import identification.optimise as opt
        save = opt._save_atomic
        def save_then_signal(algo, path):
            save(algo, path)
            if algo.n_gen - 1 >= {after_generation}:
                os.kill(os.getpid(), {int(sig)})
        opt._save_atomic = save_then_signal
        from ebb_cli import main
        sys.exit(main(sys.argv[1:]))
    """)
    return subprocess.run([sys.executable, "-c", script, "identify", str(cfg), str(data), "--out", str(out),
                           *extra], capture_output=True, text=True, timeout=600)


#: A small identification config: clamped–clamped, 16 nodes, EI and N unknown, one force, two sensors.
IDENTIFY_CFG = """
[beam]
length = 1.0
nodes = 16
left = "clamped"
right = "clamped"
[time]
dt = 1e-4
[parameters]
EI   = { value = 10.0, bounds = [5.0, 20.0], identify = true }
rhoA = { value = 1.0 }
c    = { value = 0.5 }
N    = { value = 50.0, bounds = [0.0, 100.0], identify = true }
[[actuators]]
name = "F1"
x = 0.3
[[sensors]]
name = "y1"
x = 0.5
[[sensors]]
name = "y2"
x = 0.75
"""


@pytest.fixture
def identify_case(tmp_path: Path):
    """A small identification case: config (EI and N unknown), a 600-sample record of the model, 1 % noise."""
    cfg_path = tmp_path / "cfg.toml"
    cfg_path.write_text(IDENTIFY_CFG)
    cfg = em.load_config(cfg_path)
    rng = np.random.default_rng(0)
    u = rng.standard_normal((600, 1))
    y = em.simulate_config(cfg, u).outputs
    y += 0.01 * y.std(0) * rng.standard_normal(y.shape)
    t = np.arange(600) * 1e-4
    data = tmp_path / "data.csv"
    np.savetxt(data, np.column_stack([t, u[:, 0], y]), delimiter=",", header="time,F1,y1,y2", comments="")
    return cfg_path, data, tmp_path
