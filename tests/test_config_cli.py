"""Config validation and the ``ebb`` command line (in-process and as a subprocess)."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ebb_model import (ConfigError, ParameterError, assemble, config_from_dict, discretise, load_config,
                       simulate_config)
from ebb_cli import main

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "examples" / "seed_clamped.toml"


def base() -> dict:
    return {
        "beam": {"length": 1.0, "nodes": 10, "left": "clamped", "right": "pinned"},
        "time": {"dt": 1e-4},
        "parameters": {"EI": {"value": 10.0}, "rhoA": {"value": 1.0}},
        "actuators": [{"name": "F1", "x": 0.3}],
        "sensors": [{"name": "y1", "x": 0.5, "kind": "displacement"}],
    }


BAD = [
    ("negative EI", lambda d: d["parameters"].update(EI={"value": -1.0}), "parameters.EI.value"),
    ("zero rhoA", lambda d: d["parameters"].update(rhoA={"value": 0.0}), "parameters.rhoA.value"),
    ("sensor outside", lambda d: d["sensors"][0].update(x=1.5), "sensors[0].x"),
    ("actuator outside", lambda d: d["actuators"][0].update(x=-0.1), "actuators[0].x"),
    ("unknown bc", lambda d: d["beam"].update(left="welded"), "beam.left"),
    ("unknown kind", lambda d: d["sensors"][0].update(kind="strain"), "sensors[0].kind"),
    ("dt zero", lambda d: d["time"].update(dt=0.0), "time.dt"),
    ("dt negative", lambda d: d["time"].update(dt=-1e-3), "time.dt"),
    ("nodes 3", lambda d: d["beam"].update(nodes=3), "beam.nodes"),
    ("nan EI", lambda d: d["parameters"].update(EI={"value": math.nan}), "parameters.EI.value"),
    ("inf length", lambda d: d["beam"].update(length=math.inf), "beam.length"),
    ("length beyond any beam", lambda d: d["beam"].update(length=1e80), "beam.length: must lie in 1e-09 … 1e+06 m"),
    ("zero length", lambda d: d["beam"].update(length=0.0), "beam.length: must lie in"),
    ("dt beyond any record", lambda d: d["time"].update(dt=1e300), "time.dt: must be > 0 and at most 1000 s"),
    ("scheme not a string", lambda d: d["time"].update(scheme=[1]), "time.scheme: must be one of theta, exact"),
    ("EI beyond any beam", lambda d: d["parameters"].update(EI={"value": 1e300}),
     "parameters.EI.value: must be at most 1e+30 in magnitude"),
    ("rhoA below any beam", lambda d: d["parameters"].update(rhoA={"value": 1e-300}),
     "parameters.rhoA.value: must be at least 1e-30"),
    ("N bound beyond any beam", lambda d: d["parameters"].update(N={"value": 1.0, "bounds": [-1e300, 5.0]}),
     "parameters.N.bounds: each bound must be at most 1e+30 in magnitude"),
    ("unknown key", lambda d: d["beam"].update(colour="red"), "beam.colour"),
    ("unknown table", lambda d: d.update(solver={}), "solver"),
    ("unknown parameter", lambda d: d["parameters"].update(E={"value": 1.0}), "parameters.E"),
    ("bounds reversed", lambda d: d["parameters"].update(EI={"value": 10.0, "bounds": [20.0, 5.0]}),
     "parameters.EI.bounds"),
    ("springs without elastic", lambda d: d["beam"].update(left_kt=1.0), "beam.left_kt"),
    ("elastic without springs", lambda d: d["beam"].update(right="elastic"), "beam.right_kt"),
    ("duplicate names", lambda d: d["sensors"].append({"name": "F1", "x": 0.2}), "names"),
    ("negative mass", lambda d: d.update(masses=[{"name": "m", "x": 0.5, "mass": -1.0}]), "masses[0].mass"),
    ("identify without bounds", lambda d: d["parameters"].update(N={"value": 1.0, "identify": True}),
     "parameters.N.bounds"),
    ("negative rhoI", lambda d: d["parameters"].update(rhoI={"value": -1e-4}), "parameters.rhoI.value"),
    ("negative kf", lambda d: d["parameters"].update(kf={"value": -1.0}), "parameters.kf.value"),
    ("kf bounds below zero", lambda d: d["parameters"].update(kf={"value": 1.0, "bounds": [-1.0, 5.0]}),
     "parameters.kf.bounds"),
]


@pytest.mark.parametrize("name,mutate,field", BAD, ids=[b[0] for b in BAD])
def test_bad_config_names_the_field(name, mutate, field):
    d = base()
    mutate(d)
    with pytest.raises(ConfigError) as ei:
        config_from_dict(d)
    assert field in str(ei.value)


def test_all_problems_are_reported_at_once():
    d = base()
    d["parameters"]["EI"] = {"value": -1.0}
    d["sensors"][0]["x"] = 3.0
    d["time"]["dt"] = 0.0
    with pytest.raises(ConfigError) as ei:
        config_from_dict(d)
    assert len(ei.value.problems) == 3


def test_elastic_infinite_springs_equal_clamped():
    d = base()
    d["beam"].update(left="elastic", left_kt="inf", left_kr=math.inf)
    u = np.random.default_rng(0).standard_normal((500, 1))
    y1 = simulate_config(config_from_dict(d), u).outputs
    y2 = simulate_config(config_from_dict(base()), u).outputs
    np.testing.assert_allclose(y1, y2, rtol=1e-12, atol=1e-18)


def test_roundtrip_to_dict():
    cfg = load_config(SEED)
    assert config_from_dict(cfg.to_dict()).to_dict() == cfg.to_dict()
    assert json.loads(json.dumps(cfg.to_dict())) == cfg.to_dict()


def test_parameter_overrides_are_validated():
    cfg = load_config(SEED)
    with pytest.raises(ParameterError, match="EI"):
        assemble(cfg, {"EI": 0.0})
    with pytest.raises(ParameterError, match="rhoA"):
        assemble(cfg, {"rhoA": math.nan})
    with pytest.raises(ParameterError, match="unknown parameter"):
        assemble(cfg, {"E": 1.0})


def test_cli_modes_json(capsys):
    assert main(["modes", str(SEED), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    for key in ("frequencies_hz", "damping_ratios", "max_growth_factor", "spectral_radius", "stable"):
        assert key in rep
    assert rep["stable"] is True
    # clamped–clamped with U = N L²/EI = 5: first frequency from the characteristic equation
    from ebb_model.reference import analytic_frequencies_hz

    f1 = analytic_frequencies_hz("clamped", "clamped", length=1.0, EI=10.0, rhoA=1.0, N=50.0, n_modes=1)[0]
    assert rep["frequencies_hz"][0] == pytest.approx(f1, rel=2e-3)


def test_cli_modes_tells_which_grid_the_record_needs(tmp_path, capsys):
    """``ebb modes --band`` lists each mode's grid error in half-power bandwidths and names the grid to use
    (the advice itself is checked against the closed form in test_adequacy.py)."""
    def write(name: str, nodes: int, substeps: int) -> Path:
        text = SEED.read_text().replace("nodes = 50 ", f"nodes = {nodes} ").replace(
            "substeps = 1 ", f"substeps = {substeps}\nscheme = \"theta\" ").replace(
            "c    = { value = 0.0 }", "c    = { value = 2.0 }")
        path = tmp_path / name
        path.write_text(text)
        return path

    coarse = write("coarse.toml", 20, 1)
    assert load_config(coarse).time.scheme == "theta" and load_config(coarse).beam.nodes == 20
    assert main(["modes", str(coarse), "--band", "80"]) == 0
    out = capsys.readouterr().out
    assert "grid error [bw]" in out
    assert "grid: too coarse for modes 1-3" in out and "use [beam] nodes >= " in out, out
    assert main(["modes", str(coarse), "--band", "80", "--json"]) == 0
    grid = json.loads(capsys.readouterr().out)["grid"]
    assert not grid["adequate"] and grid["nodes_needed"] > 20
    fine = write("fine.toml", grid["nodes_needed"], grid["substeps_needed"])
    assert main(["modes", str(fine), "--band", "80"]) == 0
    assert "grid: adequate for modes 1-3" in capsys.readouterr().out
    assert main(["modes", str(fine), "--band", "-1"]) == 2
    assert capsys.readouterr().err.strip() == "ebb modes: error: --band must be a positive frequency in Hz, got -1"


def test_config_without_rhoI_and_kf_defaults_to_zero():
    cfg = config_from_dict(base())
    assert cfg.parameter_values()["rhoI"] == 0.0 and cfg.parameter_values()["kf"] == 0.0
    assert load_config(SEED).parameter_values()["kf"] == 0.0


def test_cli_modes_with_foundation_and_rotary_inertia(capsys):
    """``--param kf=..`` raises every ω² by kf/rhoA (uniform beam); ``--param rhoI=..`` lowers the modes."""
    assert main(["modes", str(SEED), "--json", "--n-modes", "3"]) == 0
    f0 = np.array(json.loads(capsys.readouterr().out)["frequencies_hz"])
    assert main(["modes", str(SEED), "--json", "--n-modes", "3", "--param", "kf=400"]) == 0
    f1 = np.array(json.loads(capsys.readouterr().out)["frequencies_hz"])
    np.testing.assert_allclose((2 * np.pi * f1) ** 2 - (2 * np.pi * f0) ** 2, 400.0, rtol=1e-8)
    assert main(["modes", str(SEED), "--json", "--n-modes", "3", "--param", "rhoI=1e-3"]) == 0
    f2 = np.array(json.loads(capsys.readouterr().out)["frequencies_hz"])
    assert np.all(f2 < f0)


def test_cli_simulate_roundtrip(tmp_path):
    out = tmp_path / "y.csv"
    assert main(["simulate", str(SEED), "--input", str(ROOT / "examples" / "seed_input.csv"),
                 "--out", str(out)]) == 0
    data = np.genfromtxt(out, delimiter=",", names=True)
    assert data.dtype.names == ("time", "y1", "y2")
    inp = np.genfromtxt(ROOT / "examples" / "seed_input.csv", delimiter=",", names=True)
    ref = simulate_config(load_config(SEED), inp["F1"][:, None]).outputs
    np.testing.assert_allclose(np.column_stack([data["y1"], data["y2"]]), ref, rtol=1e-15, atol=0)


def _write(p: Path, text: str) -> Path:
    p.write_text(text)
    return p


@pytest.mark.parametrize("case", ["nan", "missing column", "non-monotonic", "wrong dt", "bad config",
                                  "unstable param"])
def test_cli_simulate_bad_input_exit_2_and_no_output(tmp_path, case, capsys):
    cfg = SEED
    inp = _write(tmp_path / "in.csv", "time,F1\n0,0\n0.0001,1\n0.0002,0\n")
    args = []
    if case == "nan":
        inp = _write(tmp_path / "in.csv", "time,F1\n0,0\n0.0001,nan\n")
    elif case == "missing column":
        inp = _write(tmp_path / "in.csv", "time,F2\n0,0\n0.0001,1\n")
    elif case == "non-monotonic":
        inp = _write(tmp_path / "in.csv", "time,F1\n0,0\n0.0002,1\n0.0001,1\n")
    elif case == "wrong dt":
        inp = _write(tmp_path / "in.csv", "time,F1\n0,0\n0.001,1\n0.002,1\n")
    elif case == "bad config":
        cfg = _write(tmp_path / "c.toml", SEED.read_text().replace('left = "clamped"', 'left = "glued"'))
    elif case == "unstable param":
        args = ["--param", "N=-1000"]
    out = tmp_path / "out.csv"
    assert main(["simulate", str(cfg), "--input", str(inp), "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert "error" in err and err.count("\n") >= 1
    assert not out.exists()
    assert not any(tmp_path.glob("out.csv*"))


def test_cli_subprocess_exit_codes(tmp_path):
    env = dict(os.environ)
    ok = subprocess.run([sys.executable, "-m", "ebb_cli", "modes", str(SEED)], capture_output=True,
                        text=True, env=env, timeout=300)
    assert ok.returncode == 0, ok.stderr
    assert "verdict: stable" in ok.stdout
    bad = _write(tmp_path / "c.toml", SEED.read_text().replace("nodes = 50", "nodes = 2"))
    r = subprocess.run([sys.executable, "-m", "ebb_cli", "modes", str(bad)], capture_output=True,
                       text=True, env=env, timeout=300)
    assert r.returncode == 2
    assert "beam.nodes" in r.stderr and "Traceback" not in r.stderr


def test_a_reader_that_closed_the_pipe_ends_the_command_quietly():
    """``ebb modes CFG | head -2``: the reader gone before the table is written.  The read end is closed before
    the command starts, so that every write meets the broken pipe (with ``head`` it depends on timing): exit 141
    (128 + SIGPIPE, as a shell's own tools), nothing on standard error.  Before: a ``BrokenPipeError`` traceback,
    exit 1."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        r = subprocess.run([sys.executable, "-m", "ebb_cli", "modes", str(SEED)], stdout=write_end,
                           stderr=subprocess.PIPE, text=True, timeout=300)
    finally:
        os.close(write_end)
    assert r.returncode == 141, r.stderr
    assert r.stderr == ""


def test_impossible_magnitudes_are_parameter_errors_not_linear_algebra_failures():
    """A point mass 1e30 kg broke the Cholesky factor of M (LinAlgError); EI = 1e300 overflowed the matrices."""
    d = base()
    d["masses"] = [{"name": "m", "x": 0.5, "mass": 1e30}]
    with pytest.raises(ParameterError, match=r"masses\.m: 1e\+30 kg is more than 1e\+12 times the beam's mass "
                                                 r"per grid cell .*numerically singular"):
        assemble(config_from_dict(d))
    cfg = config_from_dict(base())
    with pytest.raises(ParameterError, match=r"parameters\.EI: must be at most 1e\+30 in magnitude"):
        assemble(cfg, {"EI": 1e300})
    with pytest.raises(ParameterError, match=r"parameters\.rhoA: must be at least 1e-30"):
        discretise(cfg, {"rhoA": 1e-300})

