"""Bad input never ends in a traceback: one line naming the problem, exit 2 (130 for Ctrl-C), no partial output.

One test per input a new user tried (issue: green on a fresh machine), plus a fuzz test that feeds random
bytes, truncations and flipped bytes of every supported file type (TOML config, CSV, NPZ, MAT, LVM,
UFF58) to the readers and to the command line.
"""
from __future__ import annotations

import json
import signal
import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.io

import ebb_model as em
from ebb_model import load_config
from ebb_cli import main
from ebb_model.errors import DataError, DataWarning, EbbError, StabilityError
from identification.data import load_experiment

from conftest import IDENTIFY_CFG as CFG
from conftest import run_identify_signalled
from test_data_loaders import cfg as loader_cfg
from test_data_loaders import UNITS, signals, write_csv, write_lvm, write_txt, write_uff

FIXTURES = Path(__file__).resolve().parent / "fixtures"
SEED = Path(__file__).resolve().parents[1] / "examples" / "seed_clamped.toml"


@pytest.fixture
def case(identify_case):
    return identify_case


def one_line_error(capsys, command: str) -> str:
    """The CLI's stderr: exactly one line ``ebb COMMAND: error: ...`` (no traceback, no numpy reprs)."""
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"ebb {command}: error: "), err
    assert "Traceback" not in err and "np.float64(" not in err and "np.int64(" not in err, err
    return lines[0]


# ------------------------------------------------------------------------------------------ one test per row
def test_config_with_non_utf8_bytes(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_bytes(SEED.read_bytes().replace(b"clamped", b"cl\xff\xfeamped", 1))
    assert main(["modes", str(bad)]) == 2
    line = one_line_error(capsys, "modes")
    assert "bad.toml: config file is not UTF-8 text (byte 0xff at offset" in line


def test_out_pointing_at_an_existing_file(case, capsys):
    cfg, data, tmp = case
    target = tmp / "results"
    target.write_text("keep me")
    assert main(["identify", str(cfg), str(data), "--out", str(target), "--no-progress"]) == 2
    assert "is a file, expected a directory" in one_line_error(capsys, "identify")
    assert target.read_text() == "keep me"
    for cmd in (["diagnose", str(cfg), str(data)], ["demo", "--quick"]):
        assert main([*cmd, "--out", str(target)]) == 2
        assert "is a file, expected a directory" in one_line_error(capsys, cmd[0])
        assert target.read_text() == "keep me"


def test_ctrl_c_during_identify_keeps_the_checkpoint_and_resumes(case):
    cfg, data, tmp = case
    args = ["--pop", "8", "--generations", "8", "--no-progress", "--no-export", "--seed", "3"]
    out = tmp / "run"
    proc = run_identify_signalled(cfg, data, out, signal.SIGINT, 2, *args)
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr.strip().splitlines() == [
        f"ebb identify: interrupted; resume with --resume (checkpoint kept in {out})"], proc.stderr
    assert (out / "checkpoint.pkl").exists() and not (out / "pareto.json").exists()
    assert main(["identify", str(cfg), str(data), "--out", str(out), "--resume", *args]) == 0
    assert main(["identify", str(cfg), str(data), "--out", str(tmp / "ref"), *args]) == 0
    a = json.loads((tmp / "ref" / "pareto.json").read_text())
    b = json.loads((out / "pareto.json").read_text())
    assert a["points"] == b["points"]


def test_ctrl_c_before_the_first_checkpoint_leaves_nothing(case, monkeypatch, capsys):
    cfg, data, tmp = case
    import identification.run as run

    def interrupted(*_a, **_k):
        raise KeyboardInterrupt

    monkeypatch.setattr(run, "optimise", interrupted)
    out = tmp / "run"
    assert main(["identify", str(cfg), str(data), "--out", str(out), "--no-progress"]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["ebb identify: interrupted before the first generation; nothing was written"]
    assert not out.exists()


def test_binary_garbage_csv_names_the_file_not_its_bytes(case, capsys):
    cfg, _, tmp = case
    junk = tmp / "junk.csv"
    junk.write_bytes(bytes(np.random.default_rng(5).integers(0, 256, 3000, dtype=np.uint8)))
    assert main(["identify", str(cfg), str(junk), "--out", str(tmp / "o"), "--no-progress"]) == 2
    line = one_line_error(capsys, "identify")
    assert "junk.csv: not a text data file (binary data" in line
    assert line.isprintable() and len(line) < 200, line
    assert main(["simulate", str(cfg), "--input", str(junk), "--out", str(tmp / "y.csv")]) == 2
    assert "junk.csv: not a text CSV file (binary data" in one_line_error(capsys, "simulate")
    assert not (tmp / "o").exists() and not (tmp / "y.csv").exists()


def _excerpt_lines() -> list[str]:
    return (FIXTURES / "arts_lab_test1_excerpt.lvm").read_text().split("\n")


def test_lvm_truncated_at_a_line_boundary_is_reported(tmp_path):
    sig = signals(400)
    full = write_lvm(tmp_path / "full.lvm", sig["time"], [sig["F1"], sig["y1"], sig["a2"]], ["F1", "y1", "a2"],
                     ["N", "m", "m/s2"])
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        load_experiment(full, loader_cfg())          # a complete file: no warning
    lines = full.read_bytes().split(b"\r\n")
    cut = tmp_path / "cut.lvm"
    cut.write_bytes(b"\r\n".join(lines[:250]) + b"\r\n")
    with pytest.warns(DataWarning, match=r"cut\.lvm: segment 1 ends at 0\.0228 s, its header declares 400 "
                                         r"samples of 0\.0001 s \(0\.04 s\): truncated file"):
        exp = load_experiment(cut, loader_cfg())
    assert exp.n_samples == 229          # 250 lines, 21 of them header and headings
    # without an X column the rows are the samples: fewer rows than declared is an error
    nox = write_lvm(tmp_path / "nox.lvm", sig["time"], [sig["F1"], sig["y1"], sig["a2"]], ["F1", "y1", "a2"],
                    ["N", "m", "m/s2"], x_columns="No")
    rows = nox.read_bytes().split(b"\r\n")
    nox.write_bytes(b"\r\n".join(rows[:250]) + b"\r\n")
    with pytest.raises(DataError, match=r"nox\.lvm: segment 1 holds 229 rows, its header declares "
                                         r"Samples = 400: the file is truncated"):
        load_experiment(nox, loader_cfg())


def test_lvm_truncation_on_the_command_line_is_one_warning_line(case, capsys):
    cfg, _, tmp = case
    sig = signals(600)
    p = write_lvm(tmp / "rec.lvm", sig["time"], [sig["F1"], sig["y1"], sig["a2"]], ["F1", "y1", "y2"],
                  ["N", "m", "m"])
    lines = p.read_bytes().split(b"\r\n")
    p.write_bytes(b"\r\n".join(lines[:420]) + b"\r\n")
    main(["identify", str(cfg), str(p), "--out", str(tmp / "o"), "--no-progress", "--pop", "4",
          "--generations", "1", "--no-export", "--force"])
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0].startswith("ebb identify: warning: ") and "rec.lvm: segment 1 ends at" in err[0], err


@pytest.mark.parametrize("keep,message", [
    (15, r"the segment header starting at line 14 is not closed by an \*\*\*End_of_Header\*\*\* line: "
         r"the file is truncated"),
    (8, r"the file header is not closed by an \*\*\*End_of_Header\*\*\* line \(the file is truncated"),
    (22, r"no data after the last \*\*\*End_of_Header\*\*\* line \(line 22\)"),
])
def test_lvm_truncated_inside_its_header(tmp_path, keep, message):
    p = tmp_path / "head.lvm"
    p.write_text("\n".join(_excerpt_lines()[:keep]) + "\n")
    with pytest.raises(EbbError, match=r"head\.lvm: " + message):
        load_experiment(p, loader_cfg())


def test_lvm_truncated_inside_a_row_says_so(tmp_path):
    text = (FIXTURES / "arts_lab_test1_excerpt.lvm").read_text()
    p = tmp_path / "mid.lvm"
    p.write_text(text[: len(text) // 2])
    with pytest.raises(EbbError, match=r"mid\.lvm, line \d+ \(sample \d+\): \d fields, expected 4 .*it is the "
                                       r"last line: the file is truncated"):
        load_experiment(p, loader_cfg())


def test_non_monotonic_time_prints_plain_numbers(case, capsys):
    cfg, data, tmp = case
    a = np.loadtxt(data, delimiter=",", skiprows=1)
    a[5, 0] = 0.5
    p = tmp / "swap.csv"
    np.savetxt(p, a, delimiter=",", header="time,F1,y1,y2", comments="")
    assert main(["identify", str(cfg), str(p), "--out", str(tmp / "o"), "--no-progress"]) == 2
    assert "not strictly increasing at sample 6 (0.5 s -> 0.0006 s)" in one_line_error(capsys, "identify")


def test_wrong_sample_time_names_the_config_key(case, capsys):
    cfg, data, tmp = case
    a = np.loadtxt(data, delimiter=",", skiprows=1)
    a[:, 0] *= 2
    p = tmp / "slow.csv"
    np.savetxt(p, a, delimiter=",", header="time,F1,y1,y2", comments="")
    assert main(["identify", str(cfg), str(p), "--out", str(tmp / "o"), "--no-progress"]) == 2
    line = one_line_error(capsys, "identify")
    assert "resample = true under [identification.data]" in line and "pass resample" not in line


@pytest.mark.parametrize("value", ['["abc", 1e-3]', '"abc"', "true", "[1e-3]", "[1e-3, -1e-3]", "[[1e-3], [1, 2]]",
                                   "[1e-3, nan]"])
def test_noise_std_that_is_not_one_positive_number_per_sensor(case, capsys, value):
    cfg, data, tmp = case
    bad = tmp / "noise.toml"
    bad.write_text(cfg.read_text() + f"\n[identification]\nnoise_std = {value}\n")
    for command in ("identify", "diagnose"):
        out = tmp / f"out_{command}"
        assert main([command, str(bad), str(data), "--out", str(out), "--no-progress" if command == "identify"
                     else "--quiet"]) == 2
        assert "noise_std: need one positive number per sensor (2), got" in one_line_error(capsys, command)
        assert not out.exists()


@pytest.mark.parametrize("entry,message", [
    ('stabilising = "no"', "identification.stabilising: must be true or false, got 'no'"),
    ("stabilising = 0", "identification.stabilising: must be true or false, got 0"),
    ("per = 3", 'identification.per: must be "sensor" or "experiment", got 3'),
    ("positions = 5", "identification.positions: must be a table {name = [lo, hi]}, got 5"),
])
def test_identification_table_values_of_the_wrong_type(case, capsys, entry, message):
    """Before, ``stabilising = "no"`` switched the objective on and ``positions = 5`` was ignored, silently."""
    cfg, data, tmp = case
    bad = tmp / "ident.toml"
    bad.write_text(cfg.read_text() + f"\n[identification]\n{entry}\n")
    assert main(["identify", str(bad), str(data), "--out", str(tmp / "out"), "--no-progress"]) == 2
    assert one_line_error(capsys, "identify") == f"ebb identify: error: {message}"
    assert not (tmp / "out").exists()


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory):
    """A finished ``ebb identify`` run with one polished point, no exports yet."""
    tmp = tmp_path_factory.mktemp("run")
    (tmp / "cfg.toml").write_text(CFG)
    rng = np.random.default_rng(1)
    u = rng.standard_normal((600, 1))
    y = em.simulate_config(em.load_config(tmp / "cfg.toml"), u).outputs
    np.savetxt(tmp / "d.csv", np.column_stack([np.arange(600) * 1e-4, u[:, 0], y]), delimiter=",",
               header="time,F1,y1,y2", comments="")
    out = tmp / "out"
    assert main(["identify", str(tmp / "cfg.toml"), str(tmp / "d.csv"), "--out", str(out), "--pop", "6",
                 "--generations", "2", "--no-progress", "--no-export", "--polish", "1"]) == 0
    return tmp, out


def test_export_polished_without_indices_exports_every_polished_point(finished_run, capsys):
    _, out = finished_run
    assert main(["export", str(out), "--polished", "--target", "statespace"]) == 0
    written = sorted(p.name for p in (out / "export").iterdir())
    # --polish 1: the knee's polish, the records' start's and the front's best fit's when it is not the knee
    # (identification.basins.polish_basins)
    n = len(json.loads((out / "pareto.json").read_text())["polished"])
    assert n in (2, 3) and written == [f"polished_{j}.npz" for j in range(n)], written
    capsys.readouterr()


def test_export_polished_of_a_run_without_polish_refuses(case, capsys):
    cfg, data, tmp = case
    out = tmp / "nopolish"
    assert main(["identify", str(cfg), str(data), "--out", str(out), "--pop", "4", "--generations", "1",
                 "--no-progress", "--no-export", "--polish", "0"]) == 0
    capsys.readouterr()
    assert not (out / "polished.csv").exists()              # no header-only file
    assert main(["export", str(out), "--polished", "--target", "statespace"]) == 2
    assert "--polished: this run has no polished points (run `ebb identify` with --polish K)" in \
        one_line_error(capsys, "export")
    assert not (out / "export").exists()


def test_export_reduce_order_out_of_range(finished_run, capsys):
    tmp, out = finished_run
    # the exported StateSpace's states: the modes the 16-node grid resolves (of its 16) and the cubic input's two
    # past samples (ebb_model.modal.truncation.design_model)
    from ebb_model.modal.truncation import design_model
    from identification.result import IdentificationResult

    (_, c, params), = IdentificationResult.read(out).models([0])
    n = design_model(c, params).nstates
    assert 4 <= n < em.assemble(c, params).nstates == 34
    for order in ("0", "10000"):
        assert main(["export", str(out), "--points", "0", "--target", "statespace", "--reduce-order", order]) == 2
        assert f"--reduce-order: must lie in 1 … {n} (the model's states)" in one_line_error(capsys, "export")


def test_out_directories_that_are_not_a_run_get_one_consistent_message(case, finished_run, capsys):
    cfg, data, tmp = case
    other = tmp / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    args = [str(cfg), str(data), "--no-progress"]
    assert main(["identify", *args, "--out", str(other)]) == 2
    assert "exists and is not empty; choose a new directory" in one_line_error(capsys, "identify")
    assert main(["identify", *args, "--out", str(other), "--resume"]) == 2
    assert "holds no interrupted `ebb identify` run" in one_line_error(capsys, "identify")
    _, done = finished_run
    assert main(["identify", *args, "--out", str(done)]) == 2
    assert "holds a finished run; choose a new directory" in one_line_error(capsys, "identify")
    assert main(["identify", *args, "--out", str(done), "--resume"]) == 2
    assert "has finished (pareto.json); nothing to resume" in one_line_error(capsys, "identify")
    assert sorted(p.name for p in other.iterdir()) == ["notes.txt"]


def test_instability_has_its_own_error_type(case):
    """The Fisher information next to an unstable point raises StabilityError (not a bare ValueError)."""
    from identification.fisher import fisher_information
    from identification.native import NativeEvaluator, experiments_from_arrays
    from identification.parameters import parameter_space
    from identification.run import load_identification_config

    cfg_path, data, _ = case
    cfg = load_identification_config(cfg_path)
    a = np.loadtxt(data, delimiter=",", skiprows=1)
    ev = NativeEvaluator(cfg, parameter_space(cfg), experiments_from_arrays([("e", a[:, 1:2], a[:, 2:])]))
    x = np.array([10.0, -1e4])                        # N = -1e4: far beyond the buckling load
    with pytest.raises(StabilityError, match="unstable next to the point"):
        fisher_information(ev, x, noise_std=[1e-3, 1e-3])


# ------------------------------------------------------------------------------------------------- fuzz
def _valid_files(d: Path) -> dict[str, Path]:
    sig = signals(300)
    files = {
        "csv": write_csv(d / "a.csv", sig),
        "lvm": write_lvm(d / "a.lvm", sig["time"], [sig["F1"], sig["y1"], sig["a2"]], ["F1", "y1", "a2"],
                         ["N", "m", "m/s2"]),
        "uff": write_uff(d / "a.uff", sig),
        "txt": write_txt(d / "a.txt", sig, UNITS),
        "toml": SEED,
    }
    np.savez(d / "a.npz", **sig)
    scipy.io.savemat(d / "a.mat", sig)
    files["npz"], files["mat"] = d / "a.npz", d / "a.mat"
    return files


def _variants(raw: bytes, rng: np.random.Generator, n_random: int, n_cuts: int, n_flips: int):
    for k in range(n_random):
        yield f"random{k}", bytes(rng.integers(0, 256, int(rng.integers(0, 4000)), dtype=np.uint8))
    for frac in np.linspace(0, 1, n_cuts, endpoint=False):
        yield f"cut{frac:.3f}", raw[: int(frac * len(raw))]
    for k in range(n_flips):
        b = bytearray(raw)
        for _ in range(5):
            b[int(rng.integers(0, len(b)))] = int(rng.integers(0, 256))
        yield f"flip{k}", bytes(b)


def _check_message(msg: str) -> None:
    """One line per problem (a config lists all its problems, one per line), nothing unprintable."""
    for line in msg.splitlines():
        assert line.isprintable() and len(line) < 400, msg
    assert "np.float64(" not in msg and "np.int64(" not in msg, msg


@pytest.mark.parametrize("kind", ["toml", "csv", "npz", "mat", "lvm", "uff", "txt"])
def test_fuzz_readers_raise_only_the_projects_errors(tmp_path, kind):
    src = _valid_files(tmp_path)[kind]
    raw = src.read_bytes()
    rng = np.random.default_rng(sum(map(ord, kind)))
    n = 0
    for name, data in _variants(raw, rng, n_random=40, n_cuts=40, n_flips=20):
        p = tmp_path / f"fuzz_{name}.{kind}"
        p.write_bytes(data)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DataWarning)
                load_config(p) if kind == "toml" else load_experiment(p, loader_cfg())
        except EbbError as exc:
            _check_message(str(exc))
            n += 1
        p.unlink()
    assert n >= 60, n        # most variants are invalid (a few truncations or flips leave a valid file)


@pytest.mark.parametrize("kind", ["toml", "csv", "npz", "mat", "lvm", "uff", "txt"])
def test_fuzz_command_line_exit_2_one_line_no_output(tmp_path, kind, capsys):
    files = _valid_files(tmp_path)
    (tmp_path / "cfg.toml").write_text(CFG.replace('name = "y2"\nx = 0.75', 'name = "a2"\nx = 0.75\n'
                                                   'kind = "acceleration"'))
    raw = files[kind].read_bytes()
    rng = np.random.default_rng(7 + len(kind))
    for name, data in _variants(raw, rng, n_random=3, n_cuts=4, n_flips=2):
        p = tmp_path / f"fuzz_{name}.{kind}"
        p.write_bytes(data)
        out = tmp_path / f"out_{name}"
        if kind == "toml":
            argv = ["modes", str(p)]
        else:
            argv = ["identify", str(tmp_path / "cfg.toml"), str(p), "--out", str(out), "--no-progress",
                    "--pop", "4", "--generations", "1", "--no-export", "--force"]
        rc = main(argv)
        err = capsys.readouterr().err
        if rc == 0:                        # a truncation that left a valid, shorter file
            continue
        assert rc == 2, (name, err)
        assert "Traceback" not in err
        lines = [ln for ln in err.strip().splitlines() if ": warning: " not in ln]
        assert lines and lines[0].startswith(f"ebb {argv[0]}: error: "), (name, err)
        _check_message("\n".join(lines))
        assert not out.exists(), name
