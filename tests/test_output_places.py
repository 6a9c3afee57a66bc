"""Output that never destroys anything and never half-writes, on every place a user can give (issue 35).

One test per row of the issue, then a fuzz test over places: random combinations of existing, missing,
read-only, full, symlinked, device and FIFO targets for every command that writes.

Real places only. The tests run as root, for whom ``chmod`` does not stop writing, so a read-only or full
place is a real file system: a tmpfs mounted read-only, or of 64 KiB, in the test's directory. Where mounting
is not permitted a read-only place is ``/sys/kernel`` (sysfs: no file can be created there, whoever asks)
and the full-disk cases are skipped; the file-size limit (``RLIMIT_FSIZE``, ``EFBIG``) is the mid-write failure
that runs everywhere. A device is a node made here with the null device's numbers (never ``/dev`` itself).
"""
from __future__ import annotations

import errno
import json
import os
import stat
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from contextlib import contextmanager, nullcontext
from pathlib import Path

import numpy as np
import pytest

import ebb_model as em
import identification.optimise as opt
from ebb_cli import main
from ebb_model.space.adequacy import adequacy_line
from ebb_model.assemble import buckling_load
from ebb_model.io.output import MIN_FREE_BYTES, make_dir, staged_dir

from conftest import IDENTIFY_CFG
from test_bad_input import one_line_error

SMALL_CFG = IDENTIFY_CFG.replace("nodes = 16", "nodes = 8")


# ------------------------------------------------------------------------------------------------ places
@contextmanager
def tmpfs(where: Path, options: str):
    """A tmpfs mounted at ``where`` (created) for the block; skips the test where mounting is not permitted."""
    where.mkdir()
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)], capture_output=True)
    if proc.returncode != 0:
        pytest.skip(f"mounting a tmpfs is not permitted here: {proc.stderr.decode().strip()}")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=True)


def can_mount() -> bool:
    probe = Path(tempfile.mkdtemp())
    ok = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(probe)],
                        capture_output=True).returncode == 0
    if ok:
        subprocess.run(["umount", str(probe)], check=True)
    probe.rmdir()
    return ok


MOUNTS = can_mount()


@pytest.fixture
def read_only(tmp_path):
    """A read-only directory: a tmpfs mounted ``ro`` — or, without mounts, sysfs (no new file in /sys/kernel)."""
    if not MOUNTS:
        yield Path("/sys/kernel")
        return
    with tmpfs(tmp_path / "ro", "ro,size=1m") as d:
        yield d


@pytest.fixture
def full(tmp_path):
    """A file system with 64 KiB: below :data:`MIN_FREE_BYTES`."""
    with tmpfs(tmp_path / "full", "size=64k") as d:
        yield d


def null_device(path: Path) -> Path:
    os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    return path


def no_parts(d: Path, through: Path | None = None) -> None:
    """No temporary file left in ``d`` — nor, for a target written through, in the temporary directory."""
    left = list(d.rglob("*.part*"))
    if through is not None:
        left += list(Path(tempfile.gettempdir()).glob(f".{through.name}.*.part*"))
    assert not left, left


@pytest.fixture
def small(tmp_path):
    """A tiny config (8 nodes) and a 50-sample input CSV."""
    cfg = tmp_path / "cfg.toml"
    cfg.write_text(SMALL_CFG)
    t = np.arange(50) * 1e-4
    inp = tmp_path / "in.csv"
    np.savetxt(inp, np.column_stack([t, np.sin(1e3 * t)]), delimiter=",", header="time,F1", comments="")
    return cfg, inp


def simulate(cfg: Path, inp: Path, out: Path, *extra: str) -> int:
    return main(["simulate", str(cfg), "--input", str(inp), "--out", str(out), *extra])


def csv_ok(text: str) -> None:
    lines = text.strip().splitlines()
    assert lines[0] == "time,y1,y2" and len(lines) == 51, lines[:3]


# ------------------------------------------------------------------------------------- one test per row
def test_a_device_is_written_through_never_replaced(small, tmp_path, capsys):
    cfg, inp = small
    dev = null_device(tmp_path / "null")
    assert simulate(cfg, inp, dev) == 0
    st = os.stat(dev)
    assert stat.S_ISCHR(st.st_mode) and st.st_rdev == os.makedev(1, 3)
    assert capsys.readouterr().out.strip() == f"wrote {dev}"
    no_parts(tmp_path, dev)


def test_a_fifo_is_written_through(small, tmp_path, capsys):
    cfg, inp = small
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()), daemon=True)
    reader.start()
    assert simulate(cfg, inp, fifo) == 0
    reader.join(30)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    csv_ok(got[0].decode())
    no_parts(tmp_path)


def test_a_symlink_is_followed_and_kept(small, tmp_path):
    cfg, inp = small
    other = tmp_path / "other"
    other.mkdir()
    real = other / "real.csv"
    real.write_text("old")
    link = tmp_path / "link.csv"
    link.symlink_to(real)
    assert simulate(cfg, inp, link) == 0
    assert link.is_symlink() and os.readlink(link) == str(real)
    csv_ok(real.read_text())
    assert sorted(p.name for p in other.iterdir()) == ["real.csv"]
    dangling = tmp_path / "to_new.csv"                      # a link to a file not yet there: the file is made
    dangling.symlink_to(other / "new.csv")
    assert simulate(cfg, inp, dangling) == 0
    assert dangling.is_symlink() and (other / "new.csv").is_file()
    dev_link = tmp_path / "to_dev.csv"                      # a link to a device (as /dev/stdout): written through
    dev_link.symlink_to(null_device(tmp_path / "null"))
    assert simulate(cfg, inp, dev_link) == 0
    assert dev_link.is_symlink() and stat.S_ISCHR(os.stat(tmp_path / "null").st_mode)
    no_parts(tmp_path)


def test_an_output_that_is_an_input_is_refused_by_any_path(small, tmp_path, capsys):
    """``--out`` naming the input (itself, through a symbolic or a hard link, another spelling of its directory)
    or the config: exit 2, one line naming it, the file untouched; a new name beside it is written."""
    cfg, inp = small
    before = inp.read_bytes(), cfg.read_bytes()
    (tmp_path / "sub").mkdir()
    (tmp_path / "via.csv").symlink_to(inp)
    os.link(inp, tmp_path / "hard.csv")
    for out in (inp, tmp_path / "via.csv", tmp_path / "hard.csv", tmp_path / "sub" / ".." / "in.csv", cfg):
        assert simulate(cfg, inp, out) == 2, out
        line = one_line_error(capsys, "simulate")
        assert "is the input" in line and "destroy" in line, line
        assert (inp.read_bytes(), cfg.read_bytes()) == before
    assert main(["build-fmu", str(cfg), "--out", str(cfg)]) == 2        # (refused for its name first)
    one_line_error(capsys, "build-fmu")
    fmu_named = tmp_path / "cfg.fmu"
    fmu_named.write_text(SMALL_CFG)
    assert main(["build-fmu", str(fmu_named), "--out", str(fmu_named)]) == 2
    assert "is the input" in one_line_error(capsys, "build-fmu")
    assert fmu_named.read_text() == SMALL_CFG
    assert simulate(cfg, inp, tmp_path / "y.csv") == 0
    csv_ok((tmp_path / "y.csv").read_text())


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished ``ebb identify`` run (no exports) and its config and data."""
    tmp = tmp_path_factory.mktemp("finished")
    (tmp / "cfg.toml").write_text(IDENTIFY_CFG)
    cfg = em.load_config(tmp / "cfg.toml")
    u = np.random.default_rng(1).standard_normal((600, 1))
    y = em.simulate_config(cfg, u).outputs
    np.savetxt(tmp / "d.csv", np.column_stack([np.arange(600) * 1e-4, u[:, 0], y]), delimiter=",",
               header="time,F1,y1,y2", comments="")
    assert main(["identify", str(tmp / "cfg.toml"), str(tmp / "d.csv"), "--out", str(tmp / "run"), "--pop", "4",
                 "--generations", "1", "--no-progress", "--no-export"]) == 0
    return tmp


def writing_commands(d: Path, target: Path) -> dict[str, list[str]]:
    """Every command that writes, aimed at ``target`` (a file or a directory, as the command wants)."""
    cfg, data = str(d / "cfg.toml"), str(d / "d.csv")
    return {
        "simulate": ["simulate", cfg, "--input", str(d / "in.csv"), "--out", str(target / "y.csv")],
        "build-fmu": ["build-fmu", cfg, "--out", str(target / "b.fmu")],
        "build-fmu --standalone": ["build-fmu", cfg, "--standalone", "--out", str(target / "b.fmu")],
        "identify": ["identify", cfg, data, "--out", str(target / "run"), "--no-progress"],
        "diagnose": ["diagnose", cfg, data, "--out", str(target / "gap"), "--quiet"],
        "demo": ["demo", "--quick", "--quiet", "--out", str(target / "demo")],
    }


@pytest.mark.parametrize("kind", ["read_only", "full"])
def test_an_unwritable_place_is_refused_before_any_work(finished, tmp_path, request, capsys, kind):
    if kind == "full" and not MOUNTS:
        pytest.skip("no tmpfs mounts here")
    place = request.getfixturevalue(kind)
    t = np.arange(50) * 1e-4
    np.savetxt(finished / "in.csv", np.column_stack([t, t]), delimiter=",", header="time,F1", comments="")
    reason = "only 64 KiB free" if kind == "full" else ("Read-only file system" if MOUNTS else "Permission denied")
    for name, argv in writing_commands(finished, place).items():
        t0 = time.perf_counter()
        assert main(argv) == 2, name
        line = one_line_error(capsys, argv[0])
        assert str(place) in line and reason in line, line
        assert time.perf_counter() - t0 < 3.0, name            # diagnose used to compute 9 s first
    if MOUNTS:                                                   # export into a result held on such a place
        result = tmp_path / ("res_" + kind)
        with tmpfs(result, "size=2m"):
            for f in ("pareto.json", "pareto.csv"):
                (result / f).write_bytes((finished / "run" / f).read_bytes())
            if kind == "full":
                (result / "ballast").write_bytes(b"\0" * (2 * MIN_FREE_BYTES - 64 * 1024))
            else:
                subprocess.run(["mount", "-o", "remount,ro", str(result)], check=True)
            assert main(["export", str(result), "--target", "statespace"]) == 2
            line = one_line_error(capsys, "export")
            assert str(result) in line and ("Read-only" in line if kind == "read_only" else "KiB free" in line)
            assert not (result / "export").exists()


def fill(place: Path) -> None:
    """Fill the file system of ``place`` with a ballast file (``place/ballast``) until it reports ENOSPC."""
    with open(place / "ballast", "wb", buffering=0) as fh:
        try:
            while True:
                fh.write(b"\0" * 65536)
        except OSError as exc:
            assert exc.errno == errno.ENOSPC


def fill_before_save(monkeypatch, place: Path, generation: int) -> None:
    """Fill ``place`` with a ballast file just before the checkpoint of ``generation`` is written (a real ENOSPC
    in the real writer: only the moment is chosen here)."""
    save = opt._save_atomic

    def filled_then_saved(algo, path):
        if algo.n_gen - 1 == generation:
            fill(place)
        save(algo, path)

    monkeypatch.setattr(opt, "_save_atomic", filled_then_saved)


@pytest.mark.skipif(not MOUNTS, reason="no tmpfs mounts here")
def test_disk_full_during_identify_keeps_a_checkpoint_that_resumes(identify_case, tmp_path, monkeypatch, capsys):
    cfg, data, _ = identify_case
    args = ["--pop", "6", "--generations", "3", "--no-progress", "--no-export", "--seed", "2"]
    with tmpfs(tmp_path / "disk", "size=2m") as disk:
        out = disk / "run"
        fill_before_save(monkeypatch, disk, 2)
        assert main(["identify", str(cfg), str(data), "--out", str(out), *args]) == 2
        line = one_line_error(capsys, "identify")
        assert "checkpoint.pkl: cannot write (No space left on device)" in line, line
        assert f"the checkpoint of the last finished generation is kept in {out}" in line
        assert "continue with --resume" in line
        assert sorted(p.name for p in out.iterdir()) == ["checkpoint.pkl", "identifiability.json", "run.json"]
        no_parts(disk)
        (disk / "ballast").unlink()
        monkeypatch.undo()
        assert main(["identify", str(cfg), str(data), "--out", str(out), "--resume", *args]) == 0
        resumed = json.loads((out / "pareto.json").read_text())
    capsys.readouterr()
    assert main(["identify", str(cfg), str(data), "--out", str(tmp_path / "ref"), *args]) == 0
    assert json.loads((tmp_path / "ref" / "pareto.json").read_text())["points"] == resumed["points"]


@pytest.mark.skipif(not MOUNTS, reason="no tmpfs mounts here")
def test_disk_full_during_the_exports_gives_advice_that_works(identify_case, tmp_path, monkeypatch, capsys):
    """The disk fills while the exports are written (the run finished, pareto.json written): the advice names
    `ebb export`, not `--resume` (which would say the run has finished, nothing to resume), and after making room
    that command writes the exports."""
    import identification.export as export

    cfg, data, _ = identify_case
    real = export.export_points

    def filled_then_exported(*a, **kw):
        fill(disk)
        return real(*a, **kw)

    with tmpfs(tmp_path / "disk", "size=4m") as disk:
        out = disk / "run"
        monkeypatch.setattr(export, "export_points", filled_then_exported)
        assert main(["identify", str(cfg), str(data), "--out", str(out), "--pop", "6", "--generations", "2",
                     "--no-progress", "--target", "statespace"]) == 2
        line = one_line_error(capsys, "identify")
        # (the exports check the free space first: "only 0 KiB free")
        assert "free in" in line and "make room, then write the exports with `ebb export` on it" in line, line
        assert "resume" not in line and f"the results are written in {out}" in line, line
        assert (out / "pareto.json").is_file()
        no_parts(disk)
        (disk / "ballast").unlink()
        monkeypatch.undo()
        assert main(["export", str(out), "--target", "statespace"]) == 0
        assert (out / "export" / "point_0.npz").is_file()


@pytest.mark.skipif(not MOUNTS, reason="no tmpfs mounts here")
def test_disk_full_at_the_first_checkpoint_leaves_nothing(identify_case, tmp_path, monkeypatch, capsys):
    cfg, data, _ = identify_case
    with tmpfs(tmp_path / "disk", "size=2m") as disk:
        fill_before_save(monkeypatch, disk, 1)
        assert main(["identify", str(cfg), str(data), "--out", str(disk / "run"), "--pop", "4", "--generations",
                     "2", "--no-progress", "--no-export"]) == 2
        line = one_line_error(capsys, "identify")
        assert "No space left on device" in line and line.endswith("nothing was kept"), line
        assert sorted(p.name for p in disk.iterdir()) == ["ballast"]


FSIZE_SCRIPT = textwrap.dedent("""
    import resource, signal, sys
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)       # the write fails with EFBIG instead of killing us
    resource.setrlimit(resource.RLIMIT_FSIZE, ({limit}, {limit}))
    {body}
""")


def run_limited(limit: int, body: str, cwd: Path) -> subprocess.CompletedProcess:
    """Python with a file size limit of ``limit`` bytes: a real failure in the middle of writing (``EFBIG``)."""
    return subprocess.run([sys.executable, "-c", FSIZE_SCRIPT.format(limit=limit, body=body)], cwd=cwd,
                          capture_output=True, text=True, timeout=300,
                          env=os.environ | {"PYTHONDONTWRITEBYTECODE": "1"})


def test_a_write_that_fails_midway_leaves_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "big.bin"
    target.write_text("old")
    body = textwrap.dedent(f"""
        from ebb_model.errors import OutputError
        from ebb_model.io.output import atomic_path
        try:
            with atomic_path({str(target)!r}) as tmp, open(tmp, "wb") as fh:
                fh.write(b"x" * 1_000_000)
        except OutputError as exc:
            print(exc)
    """)
    proc = run_limited(65536, body, Path(__file__).resolve().parents[1])
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"{target}: cannot write (File too large); no partial file is left"
    assert target.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["big.bin"]


def test_identify_over_a_file_size_limit_leaves_nothing(identify_case):
    cfg, data, tmp = identify_case
    body = (f"from ebb_cli import main; sys.exit(main(['identify', {str(cfg)!r}, {str(data)!r}, '--out', "
            f"{str(tmp / 'run')!r}, '--pop', '4', '--generations', '1', '--no-progress', '--no-export']))")
    proc = run_limited(16384, body, Path(__file__).resolve().parents[1])     # the checkpoint is ~22 kB
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "checkpoint.pkl: cannot write (File too large)" in lines[0], lines
    assert lines[0].endswith("nothing was kept") and not (tmp / "run").exists()


def test_identify_checks_every_option_and_file_before_writing(identify_case, capsys):
    cfg, data, tmp = identify_case
    other = tmp / "other.toml"
    other.write_text(IDENTIFY_CFG.replace('name = "y2"', 'name = "z2"').replace("nodes = 16", "nodes = 8"))
    assert main(["build-fmu", str(other), "--standalone", "--out", str(tmp / "other.fmu")]) == 0
    notes = tmp / "notes.txt"
    notes.write_text("not an FMU")
    capsys.readouterr()
    out = tmp / "run"
    for extra, needle in ((["--pop", "1"], "--pop must be an integer >= 4, got 1"),
                          (["--generations", "0"], "--generations must be an integer >= 1, got 0"),
                          (["--backend", "fmu", "--fmu", str(tmp / "other.fmu")], "other.fmu: no variable(s) y2"),
                          (["--backend", "fmu", "--fmu", str(notes)], "notes.txt: not an FMU (not a zip archive)"),
                          (["--fmu", str(tmp / "other.fmu")], "evaluated only with --backend fmu")):
        assert main(["identify", str(cfg), str(data), "--out", str(out), "--no-progress", *extra]) == 2
        assert needle in one_line_error(capsys, "identify")
        assert not out.exists()


def test_beam_nodes_limit_and_modes_progress(tmp_path, capsys):
    big = tmp_path / "big.toml"
    big.write_text(SMALL_CFG.replace("nodes = 8", "nodes = 5000"))
    assert main(["modes", str(big)]) == 2
    assert "beam.nodes: must be <= 1000, got 5000 (the standalone FMU's limit" in one_line_error(capsys, "modes")
    mid = tmp_path / "mid.toml"
    mid.write_text(SMALL_CFG.replace("nodes = 8", "nodes = 220"))
    assert main(["modes", str(mid), "--n-modes", "2"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0].startswith("ebb modes: 220 nodes: modes (0 s so far") and len(err) == 3, err


def test_an_actuator_on_a_clamped_end_is_warned_about(tmp_path, capsys):
    p = tmp_path / "end.toml"
    p.write_text(SMALL_CFG.replace("x = 0.3", "x = 0.0"))
    assert main(["modes", str(p), "--n-modes", "1"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["ebb modes: warning: actuator 'F1' at x = 0 m acts on the clamped left end, which does not "
                   "move: its force goes into the support and the outputs it drives are all zero"], err


def test_compression_beyond_buckling_is_named_first(small, capsys):
    cfg, inp = small
    assert simulate(cfg, inp, cfg.parent / "y.csv", "--param", "N=-5000") == 2
    line = one_line_error(capsys, "simulate")
    n_cr = buckling_load(em.load_config(cfg))
    assert n_cr == pytest.approx(-4 * np.pi ** 2 * 10.0, rel=0.05)    # Euler: clamped-clamped, 4π² EI / L²
    assert line.split("): ", 1)[1].startswith(f"N = -5000 N exceeds the buckling load {n_cr:.6g} N of this beam")


def test_numerical_share_of_no_gap_is_not_a_percentage():
    at_floor = {"refined_nodes": 183, "max_numerical_share": 9.7,
                "sensors": {"y1": {"gap_ratio": 1.02, "change": 9.7, "gap_ratio_refined": 1.1,
                                   "numerical_share": 9.5}}}
    line = adequacy_line(at_floor)
    assert "%" not in line and "none to share, the fit is at the noise floor" in line and "9.7 noise" in line
    gap = {**at_floor, "max_numerical_share": 0.5,
           "sensors": {"y1": {"gap_ratio": 4.0, "change": 2.0, "gap_ratio_refined": 2.0, "numerical_share": 0.5}}}
    assert adequacy_line(gap).startswith("numerical share of the gap: 50 % at most")


def test_header_only_csv_names_the_file(identify_case, capsys):
    cfg, _, tmp = identify_case
    hdr = tmp / "hdr.csv"
    hdr.write_text("time,F1,y1,y2\n")
    assert main(["identify", str(cfg), str(hdr), "--out", str(tmp / "o"), "--no-progress"]) == 2
    assert one_line_error(capsys, "identify") == f"ebb identify: error: {hdr}: no data rows"


def test_help_shows_every_default_and_where_to_start(capsys):
    for argv in (["identify", "--help"], ["--help"]):
        with pytest.raises(SystemExit):
            main(argv)
    text = " ".join(capsys.readouterr().out.split())
    for flag, default in (("--pop", "40"), ("--generations", "30"), ("--workers", "1"), ("--backend", "auto"),
                          ("--seed", "1"), ("--algorithm", "nsga2")):
        assert f"(default {default}" in text.rsplit(f"{flag} {flag.strip('-').upper()}", 1)[1].split(" --")[0], flag
    assert "Start with `ebb demo`" in text


def test_one_rule_for_directory_modes(identify_case):
    cfg, data, tmp = identify_case
    mask = os.umask(0o022)
    os.umask(mask)
    want = 0o777 & ~mask
    with staged_dir(tmp / "gap") as d:           # how diagnose writes its result
        (d / "f").write_text("x")
    assert main(["identify", str(cfg), str(data), "--out", str(tmp / "run"), "--pop", "4", "--generations", "1",
                 "--no-progress", "--no-export"]) == 0
    modes = {p.name: stat.S_IMODE(os.stat(p).st_mode) for p in (tmp / "gap", tmp / "run", make_dir(tmp / "x"))}
    assert modes == {"gap": want, "run": want, "x": want}, modes


def test_names_must_be_ascii_and_say_so(tmp_path, capsys):
    p = tmp_path / "u.toml"
    p.write_text(SMALL_CFG.replace('name = "y1"', 'name = "ü"'))
    assert main(["modes", str(p)]) == 2
    assert "sensors[0].name: must be an ASCII identifier" in one_line_error(capsys, "modes")


# -------------------------------------------------------------------------------------------------- fuzz
def _snapshot(root: Path, skip: Path) -> dict[str, tuple]:
    out = {}
    for p in sorted(root.rglob("*")):
        if p == skip or skip in p.parents:
            continue
        st = os.lstat(p)
        if stat.S_ISDIR(st.st_mode):      # a directory's mtime moves when the target in it is replaced
            out[str(p)] = (stat.S_IFDIR, stat.S_IMODE(st.st_mode))
        else:
            out[str(p)] = (stat.S_IFMT(st.st_mode), st.st_size, st.st_mtime_ns, os.readlink(p) if p.is_symlink()
                           else "")
    return out


def test_fuzz_places_nothing_outside_the_target_is_touched(finished, tmp_path, capsys):
    """Random places for every writing command: exit 0 with the target written, or exit 2 with one line naming
    it; either way nothing else changes and no temporary file is left."""
    t = np.arange(50) * 1e-4
    np.savetxt(finished / "in.csv", np.column_stack([t, t]), delimiter=",", header="time,F1", comments="")
    rng = np.random.default_rng(35)
    kinds = ["absent", "existing_file", "nonempty_dir", "missing_parent", "read_only", "symlink", "dangling",
             "device", "fifo"] + (["full"] * MOUNTS)
    seen: list[tuple[str, str, int]] = []
    for k in range(40):
        kind = str(rng.choice(kinds))
        case = tmp_path / f"c{k}"
        case.mkdir()
        place, target_of = case, {}
        if kind == "read_only":
            place = Path("/sys/kernel") if not MOUNTS else case / "ro"
        elif kind == "missing_parent":
            place = case / "nowhere"
        elif kind == "full":
            place = case / "full"
        mounted = MOUNTS and kind in ("read_only", "full")
        with tmpfs(place, "ro,size=1m" if kind == "read_only" else "size=64k") if mounted else nullcontext():
            commands = writing_commands(finished, place)
            name = str(rng.choice(sorted(commands)))
            argv = list(commands[name])
            target = Path(argv[argv.index("--out") + 1])
            file_out = name.startswith(("simulate", "build-fmu"))
            if kind in ("absent", "existing_file", "symlink", "dangling", "device", "fifo") and name != "simulate" \
                    and (file_out or kind != "existing_file"):
                name, argv = "simulate", list(commands["simulate"])      # the others would run in full
                target, file_out = Path(argv[argv.index("--out") + 1]), True
            reader = None
            if kind == "existing_file":
                target.write_text("keep me")
            elif kind == "nonempty_dir":
                target.mkdir()
                (target / "mine").write_text("keep me")
            elif kind in ("symlink", "dangling"):
                real = case / "elsewhere" / "real.csv"
                real.parent.mkdir()
                if kind == "symlink":
                    real.write_text("old")
                target.symlink_to(real)
                target_of[target] = real
            elif kind == "device":
                null_device(target)
            elif kind == "fifo":
                os.mkfifo(target)
                got: list[bytes] = []
                reader = threading.Thread(target=lambda t=target, g=got: g.append(t.read_bytes()), daemon=True)
                reader.start()
            before = _snapshot(case, target_of.get(target, target))
            capsys.readouterr()
            rc = main([a for a in argv])
            if reader is not None:
                reader.join(30)
            err = capsys.readouterr().err
            assert _snapshot(case, target_of.get(target, target)) == before, (k, kind, name)
            no_parts(case, target)
            if rc == 0:
                assert kind in ("absent", "existing_file", "symlink", "dangling", "device", "fifo"), (kind, name)
                written = target_of.get(target, target)
                if kind == "fifo":
                    csv_ok(got[0].decode())
                elif kind != "device":
                    csv_ok(written.read_text())
                assert os.path.lexists(target) and (kind not in ("symlink", "dangling") or target.is_symlink())
                assert kind != "device" or stat.S_ISCHR(os.stat(target).st_mode)
            else:
                assert rc == 2, (k, kind, name, err)
                lines = err.strip().splitlines()
                assert len(lines) == 1 and lines[0].startswith(f"ebb {argv[0]}: error: "), (kind, name, err)
                assert str(target) in lines[0] or str(place) in lines[0], lines
                if kind == "existing_file" and not file_out or kind == "nonempty_dir":
                    assert "keep me" in (target.read_text() if target.is_file() else (target / "mine").read_text())
            seen.append((kind, name, rc))
    assert len({kind for kind, _, _ in seen}) >= 8 and len({name for _, name, _ in seen}) >= 5, seen
    assert {rc for _, _, rc in seen} == {0, 2}, seen

