"""The FMU carries its core compiled: a host's first step does not wait for numba or for Python's byte code.

The bundled core's kernels are numba functions cached on disk (``cache=True``): compiled on their first call, kept
in a ``__pycache__`` beside their module and found again by the source's content hash, the Python version and the
processor.  A host extracts an FMU afresh, so an FMU without that cache compiled them again in every new process
(about 2.5 s before its first step on the seed config).  The build therefore puts into the FMU:

* the numba cache of every kernel the built model's assembly runs (``.nbi``/``.nbc`` files in the
  ``__pycache__`` of each of ``resources/<core>``'s sub-packages);
* hash-checked byte code (``.pyc``) of every Python module in ``resources/`` — valid wherever the archive is
  extracted, unlike Python's default timestamped byte code (an extraction sets new times);
* the model at the FMU's own parameter values (``resources/`` + the slave's ``MODEL_FILE``: the matrices its
  first assembly would make, made by the same core here — bit for bit when the host's BLAS runs as many
  threads as the build's, to round-off otherwise, as a thread count orders a product's sums): a host that
  starts it at those values steps it without assembling, so without numba's start-up nor scipy's import
  (0.25 s of the seed config's 0.5 s start).  Other values assemble as before.

Numba's cached code imports its module by name when it loads, so the bundled core's name must be the same in
every FMU that shares the cache: it is a hash of the core's sources (:func:`core_package_name`), the same for
every FMU built from one version of the project and different for another.  The kernels are compiled once per
core, in a copy of it kept in the cache directory (:func:`ebb_model.exact.recursion.cache_directory`), by assembling
each built config's model there: a later build loads what an earlier one compiled.  The carried cache only
accelerates: a host with another processor or a read-only extraction directory compiles as before, and a build
whose cache directory cannot be written carries the byte code alone.
"""
from __future__ import annotations

import compileall
import hashlib
import importlib.util
import os
import py_compile
import shutil
import sys
import tempfile
from pathlib import Path
from types import ModuleType
from typing import Any, Iterable, Mapping

import numpy as np

from ebb_model.exact.recursion import cache_directory

from .slave_template import MODEL_FILE

__all__ = ["core_package_name", "carry_kernels", "compile_bytecode", "write_model", "KERNEL_SUFFIXES"]

#: numba's cache files: an index per kernel and its compiled overloads.
KERNEL_SUFFIXES = (".nbi", ".nbc")


def core_package_name(sources: Iterable[Path], root: Path) -> str:
    """The bundled core's package name: ``ebb_core_`` and a hash of its sources (their paths below ``root`` and
    their bytes) — one name per version of the core."""
    digest = hashlib.sha256()
    for path in sorted(sources):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return f"ebb_core_{digest.hexdigest()[:12]}"


def _import_copy(name: str, folder: Path) -> ModuleType:
    """The package ``name`` of ``folder`` (imported from there unless this process has it already)."""
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, folder / name / "__init__.py",
                                                  submodule_search_locations=[str(folder / name)])
    if spec is None or spec.loader is None:
        raise ImportError(f"no package {name} in {folder}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def _kept_copy(core: Path) -> Path:
    """The folder in the cache directory holding a copy of the bundled core ``core`` (made once, atomically)."""
    home = cache_directory() / f"fmu-{core.name}"
    if not (home / core.name / "__init__.py").is_file():
        home.parent.mkdir(parents=True, exist_ok=True)
        fresh = Path(tempfile.mkdtemp(prefix=f".fmu-{core.name}-", dir=home.parent))
        try:
            shutil.copytree(core, fresh / core.name, ignore=shutil.ignore_patterns("__pycache__"))
            os.replace(fresh, home)
        except OSError:
            if not (home / core.name / "__init__.py").is_file():  # not another build's copy made meanwhile
                raise
        finally:
            shutil.rmtree(fresh, ignore_errors=True)
    return home


def carry_kernels(core: Path, config: Mapping[str, Any], *, field: bool) -> int:
    """Put the numba cache of the kernels that assembling ``config`` runs into ``core``'s ``__pycache__`` folders
    (each beside its module, in every sub-package).

    Parameters
    ----------
    core
        The FMU's bundled core package (its name from :func:`core_package_name`).
    config
        The config as the FMU's spec holds it (``BeamConfig.to_dict``).
    field
        The FMU outputs the deflection field (the slave assembles with ``field=True``).

    Returns
    -------
    int
        The number of cache files carried; 0 when the cache directory cannot be written or the copy's assembly
        fails (the FMU then compiles its kernels when it first assembles, as numba does by itself).
    """
    try:
        home = _kept_copy(core)
        copy = _import_copy(core.name, home)
        cfg = copy.causal_config(copy.config_from_dict(dict(config)))     # as the slave takes it
        values = dict(cfg.parameter_values())
        system = copy.assemble_modal(cfg, values, field=field)
        write_model(core.parent / MODEL_FILE, values, system)
        # where this process's copy keeps its kernels (the kept copy, unless an FMU loaded here brought its own),
        # then the kept copy's
        # (every sub-package's ``__pycache__``: the kernels live in ``exact/``, ``modal/``, ``space/`` …)
        found: dict[Path, Path] = {}
        for base in (Path(str(copy.__file__)).parent, home / core.name):
            for f in sorted(base.rglob("__pycache__/*")) if base.is_dir() else ():
                if f.suffix in KERNEL_SUFFIXES:
                    found.setdefault(f.relative_to(base), f)
        rels = sorted(found, key=lambda r: (r.suffix != ".nbi", r.as_posix()))
        for rel in rels:   # indexes first: an overload an index names was written before it
            (core / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(found[rel], core / rel)
        files = rels
    except Exception:   # an acceleration only: any failure leaves the FMU compiling as numba does by itself
        return 0
    return len(files)


def write_model(path: Path, values: Mapping[str, float], system: Any) -> None:
    """The model ``system`` (``A, B, C, D`` and the first-order hold's ``Γ₁``, ``hold``, or ``None``) at the
    parameter values ``values``, as the slave reads it (``.npz``: numbers only, nothing to unpickle)."""
    hold = getattr(system, "hold", None)
    with open(path, "wb") as fh:
        np.savez(fh, names=np.array(list(values), dtype=str), values=np.array(list(values.values()), dtype=float),
                 A=system.A, B=system.B, C=system.C, D=system.D,
                 hold=np.zeros((0, 0)) if hold is None else np.asarray(hold, dtype=float),
                 has_hold=np.array(hold is not None))


def compile_bytecode(resources: Path) -> None:
    """Hash-checked byte code of every module in ``resources`` (valid after any extraction)."""
    compileall.compile_dir(str(resources), quiet=2, workers=1,
                           invalidation_mode=py_compile.PycInvalidationMode.CHECKED_HASH)
