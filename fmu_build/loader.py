"""Compile the FMU's C loader against the interpreter that builds the FMU.

pythonfmu's export library needs a running Python with numpy; on Linux it is
not linked against libpython, so a master that is not itself Python fails
with ``undefined symbol: _Py_NoneStruct``.  The loader (``loader.c``, see its
header comment) is the FMU's entry library: it makes the *build* interpreter's
libpython globally visible, points ``PYTHONHOME``/``PYTHONPATH`` at it for the
moment Python starts, and forwards the fmi2 API to pythonfmu's library.

Which interpreter: the one running the build (``sys.executable``).  In a
virtual environment ``sys.prefix`` is the venv and ``sys.base_prefix`` the
installation holding the standard library and libpython; the venv's
site-packages (numpy, scipy, numba, ...) are not found from
``PYTHONHOME=sys.base_prefix`` alone, so they go into ``PYTHONPATH``.
"""
from __future__ import annotations

import os
import shutil
import site
import subprocess
import sys
import sysconfig
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import pythonfmu3

from ebb_model.errors import FmuError

__all__ = ["PythonRuntime", "find_python_runtime", "compile_loader", "LOADER_SOURCE", "LOADER3_SOURCE"]

#: The C source of the loader, shipped next to this module (FMI 2.0; ``loader3.c`` for FMI 3.0, both including
#: ``loader_common.h``).
LOADER_SOURCE = Path(__file__).with_name("loader.c")
LOADER3_SOURCE = Path(__file__).with_name("loader3.c")


@dataclass(frozen=True)
class PythonRuntime:
    """Where a non-Python host finds the interpreter an FMU was built with.

    Attributes
    ----------
    libpython
        Absolute path of the shared Python library (``libpython3.X.so.1.0``).
    home
        Value for ``PYTHONHOME``: ``sys.base_prefix``, or
        ``"base_prefix:base_exec_prefix"`` when they differ.
    path
        Entries for ``PYTHONPATH``: the site-packages directories of the build
        interpreter (its venv's, when it runs in one).
    version
        ``"3.X"`` of the interpreter.
    """

    libpython: Path
    home: str
    path: tuple[str, ...]
    version: str


def _libpython() -> Path:
    """Locate the shared libpython of the running interpreter."""
    names = [sysconfig.get_config_var(k) for k in ("INSTSONAME", "LDLIBRARY")]
    names = [n for n in names if n and ".so" in n]
    dirs = [sysconfig.get_config_var(k) for k in ("LIBDIR", "LIBPL")]
    multiarch = sysconfig.get_config_var("MULTIARCH")
    libdir = sysconfig.get_config_var("LIBDIR")
    if multiarch and libdir:
        dirs.append(os.path.join(libdir, multiarch))
    dirs += [os.path.join(sys.base_prefix, "lib")]
    for d in dirs:
        for n in names:
            if d and os.path.isfile(os.path.join(d, n)):
                return Path(d, n).resolve()
    raise FmuError(
        "cannot find a shared libpython for "
        f"{sys.executable} (looked for {names or ['libpython3.X.so']} in {[d for d in dirs if d]}); "
        "the FMU's loader needs a Python built with --enable-shared",
        function="build_fmu",
    )


def find_python_runtime() -> PythonRuntime:
    """Describe the running interpreter for the loader.

    Returns
    -------
    PythonRuntime

    Raises
    ------
    FmuError
        If the interpreter has no shared libpython.
    """
    home = sys.base_prefix
    if sys.base_exec_prefix != sys.base_prefix:
        home = f"{sys.base_prefix}:{sys.base_exec_prefix}"
    entries: list[str] = []
    candidates = list(site.getsitepackages()) + [
        sysconfig.get_path("purelib"),
        sysconfig.get_path("platlib"),
    ]
    if site.ENABLE_USER_SITE:
        candidates.append(site.getusersitepackages())
    # Further site directories on sys.path (e.g. added by the venv or a .pth).
    candidates += [p for p in sys.path if p and p.rstrip(os.sep).endswith(("site-packages", "dist-packages"))]
    for p in candidates:
        if p and os.path.isdir(p):
            entries.append(os.path.realpath(p))
    unique = tuple(dict.fromkeys(entries))
    return PythonRuntime(
        libpython=_libpython(),
        home=home,
        path=unique,
        version=f"{sys.version_info[0]}.{sys.version_info[1]}",
    )


def _c_string(text: str) -> str:
    """A C string literal for ``text`` (UTF-8, every non-printable byte octal-escaped)."""
    out = ['"']
    for b in text.encode("utf-8"):
        ch = chr(b)
        if ch in '"\\':
            out.append("\\" + ch)
        elif 32 <= b < 127 and ch != "?":
            out.append(ch)
        else:
            out.append(f"\\{b:03o}")
    out.append('"')
    return "".join(out)


def _compiler() -> str:
    for name in ("gcc", "cc"):
        found = shutil.which(name)
        if found:
            return found
    raise FmuError("no C compiler (gcc or cc) on PATH: it is needed to build the FMU's loader",
                   function="build_fmu")


def compile_loader(out: Path, *, inner_library: str, runtime: PythonRuntime, guid: str, fmi: int = 2,
                   arrays: Mapping[int, int] | None = None) -> Path:
    """Compile ``loader.c`` (``fmi=3``: ``loader3.c``) into the shared library ``out``.

    Parameters
    ----------
    out
        Path of the shared library to write (``binaries/linux64/<id>.so``).
    inner_library
        File name of pythonfmu's export library, placed next to ``out``.
    runtime
        The interpreter the FMU runs on outside Python (see
        :func:`find_python_runtime`).
    guid
        The FMU's GUID (FMI 3.0: instantiation token); instantiation refuses any other.
    fmi
        The FMI version: 2 (pythonfmu's library inside) or 3 (pythonfmu3's).
    arrays
        FMI 3.0: the number of elements of each array variable, by value reference (the loader checks the number
        of values a host passes).

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    FmuError
        If there is no C compiler or compilation fails (with its output).
    """
    if not sys.platform.startswith("linux"):
        raise FmuError(f"the FMU loader is built for Linux only, not {sys.platform}", function="build_fmu")
    cc = _compiler()
    header = "\n".join(
        [
            "/* generated by fmu_build.loader */",
            f"#define EBB_PYTHON {_c_string(sys.executable)}",
            f"#define EBB_LIBPYTHON {_c_string(str(runtime.libpython))}",
            f"#define EBB_PYTHONHOME {_c_string(runtime.home)}",
            f"#define EBB_PYTHONPATH {_c_string(os.pathsep.join(runtime.path))}",
            f"#define EBB_INNER_LIB {_c_string(inner_library)}",
            f"#define EBB_GUID {_c_string(guid)}",
            f"#define EBB_N_ARRAYS {len(arrays or {})}",
            "#define EBB_ARRAYS {" + "".join(f"{{{vr}u, {n}u}}, " for vr, n in sorted((arrays or {}).items()))
            + "{0u, 0u}}",
            "",
        ]
    )
    # FMI 3.0: the standard's headers as pythonfmu3 ships them (its library is built against them)
    fmi3 = ["-I", str(Path(str(pythonfmu3.__file__)).parent / "pythonfmu-export" / "src" / "fmi")] if fmi == 3 else []
    with tempfile.TemporaryDirectory(prefix="ebb_loader_") as tmp:
        Path(tmp, "loader_config.h").write_text(header, encoding="utf-8")
        cmd = [
            cc, "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-Wall", "-Werror=implicit-function-declaration",
            "-I", tmp, *fmi3, "-o", str(out), str(LOADER3_SOURCE if fmi == 3 else LOADER_SOURCE), "-ldl", "-lpthread",
        ]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        except OSError as exc:
            raise FmuError(f"cannot run the C compiler {cc}: {exc}", function="build_fmu") from None
    if proc.returncode != 0:
        raise FmuError(
            f"compiling the FMU loader failed ({' '.join(cmd)}):\n{proc.stderr.strip()}",
            function="build_fmu",
        )
    return out
