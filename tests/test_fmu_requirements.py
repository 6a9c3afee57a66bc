"""The pythonfmu FMU's real run-time requirements, declared and reported by name.

* the model description names every package the bundled core imports (numpy, scipy, numba);
* a Python master whose interpreter lacks one of them gets a message naming the missing package, the
  interpreter that lacks it and the one the FMU was built with — not a bare ``No module named ...``;
* a master without Python (the plain C host) whose build interpreter has moved gets a message naming the
  missing path — not the first module the relocated Python fails to import.

The "other interpreters" are real: virtual environments made here (without pip) that see the project's
packages through a ``.pth`` file, all of them or all but numba.
"""
from __future__ import annotations

import ast
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import numpy as np

import pythonfmu  # noqa: F401 - a dependency: a broken install must fail, not skip
import fmpy

HOSTS = Path(__file__).resolve().parent / "fmu_hosts"
sys.path.insert(0, str(HOSTS))
from fmu_configs import SEED_TOML  # noqa: E402
from fmu_loops import compile_host, host_run  # noqa: E402

from fmu_build import build_fmu  # noqa: E402
from fmu_build.slave_template import REQUIRED_PACKAGES  # noqa: E402

SITE = Path(sysconfig.get_path("purelib"))


def make_interpreter(root: Path, *, hide: tuple[str, ...] = ()) -> Path:
    """A venv at ``root`` whose site-packages shows this environment's packages except ``hide``."""
    venv.EnvBuilder(with_pip=False, symlinks=True).create(root)
    python = root / "bin" / "python"
    own_site = Path(subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
                                   capture_output=True, text=True, check=True).stdout.strip())
    if not hide:
        (own_site / "project.pth").write_text(f"import site; site.addsitedir({str(SITE)!r})\n")
        return python
    view = root / "view"
    view.mkdir()
    for entry in SITE.iterdir():
        name = entry.name.lower()
        if not any(name == h or name.startswith((h + "-", h + "_", h + ".")) for h in hide):
            (view / entry.name).symlink_to(entry)
    (own_site / "view.pth").write_text(f"{view}\n")
    return python


def _third_party_imports(package: Path) -> set[str]:
    """Third-party packages imported at module level anywhere in ``package`` (what importing it needs;
    imports inside functions, e.g. python-control for ``to_control``, are not used by the FMU)."""
    names: set[str] = set()
    for src in package.rglob("*.py"):
        for node in ast.parse(src.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.Import):
                names.update(a.name.split(".")[0] for a in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
    return {n for n in names if n not in sys.stdlib_module_names and n != package.name}


def test_model_description_declares_every_required_package(tmp_path):
    import ebb_model

    # the FMU bundles ebb_model: what it imports is what the FMU's Python needs (besides pythonfmu)
    assert _third_party_imports(Path(ebb_model.__file__).parent) == set(REQUIRED_PACKAGES)
    md = fmpy.read_model_description(str(build_fmu(SEED_TOML, tmp_path / "seed.fmu")))
    assert "with numpy, scipy, numba (built with " in md.description, md.description


def test_python_master_without_numba_is_told_what_is_missing(tmp_path):
    fmu = build_fmu(SEED_TOML, tmp_path / "seed.fmu")
    python = make_interpreter(tmp_path / "nonumba", hide=("numba", "llvmlite"))
    script = ("import fmpy, sys\n"
              "try:\n"
              f"    fmpy.simulate_fmu({str(fmu)!r}, stop_time=0.001, step_size=1e-4)\n"
              "except Exception as exc:\n"
              "    print('failed:', exc)\n")
    proc = subprocess.run([str(python), "-c", script], capture_output=True, text=True, timeout=300)
    text = proc.stdout + proc.stderr
    assert "failed:" in text, text
    assert (f"this FMU needs Python with numpy, scipy, numba; the Python running it ({python}) lacks numba. "
            f"It was built with {sys.executable}") in text, text


def test_c_master_names_a_build_interpreter_that_has_moved(tmp_path):
    exe = compile_host(tmp_path)
    python = make_interpreter(tmp_path / "builder")
    fmu = tmp_path / "moved.fmu"
    subprocess.run([str(python), "-m", "ebb_cli", "build-fmu", str(SEED_TOML), "--out", str(fmu)],
                   check=True, capture_output=True, text=True, timeout=300)
    u = np.zeros((5, 1))
    ok = host_run(exe, fmu, u, tmp_path / "before")
    assert ok.returncode == 0, ok.stderr[-2000:]             # where it was built, it runs
    (tmp_path / "builder").rename(tmp_path / "elsewhere")
    gone = host_run(exe, fmu, u, tmp_path / "after")
    assert gone.returncode != 0
    assert (f"the Python this FMU was built with is gone ({python}: No such file or directory); the FMU runs on "
            f"{python} with numpy, scipy and numba installed") in gone.stderr, gone.stderr
    assert "No module named" not in gone.stderr
