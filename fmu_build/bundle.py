"""What goes into an FMU's ``resources/``: the slave, its private core, pythonfmu.

Layout written by :func:`write_resources`::

    resources/
      slavemodule.txt          name of the entry module (read by pythonfmu's binary)
      <modelIdentifier>.py     entry module: imports the slave class, nothing else
      <modelIdentifier>_slave.py  the slave (slave_template.py or, FMI 3.0, slave_template_fmi3.py; class renamed)
      <modelIdentifier>_base.py   what the slaves share (slave_base.py, its core package renamed)
      <core_package>/          a private copy of the ebb_model modules the slave imports, with their
                               compiled kernels and byte code (fmu_build.kernels)
      pythonfmu/               pythonfmu's Python runtime (as pythonfmu's own builder does; FMI 3.0:
                               pythonfmu3/, pythonfmu3's)
      ebb_fmu.json             the config (JSON) and build options

Why an entry module apart from the slave: pythonfmu 0.7.0 compiles and
executes the entry module's source afresh for every instance it creates
(and never frees that namespace).  Keeping it to one import line makes
instantiation cheap and leaves almost nothing behind; the slave module
itself is imported once per process, like any module.  pythonfmu3 imports the
entry module once and reads the slave class's name from its source; its
library crashes when that import fails, so the FMI 3.0 entry module catches
the slave's import error and hands pythonfmu3 a class that raises it when
instantiated (reported to the host as a failed instantiation).

Why a private, renamed copy of ``ebb_model``: the FMU keeps working with the
interpreter it was built with even if the project is later changed or
uninstalled, and two FMUs (or an FMU and the project itself) never share a
``sys.modules`` entry, so each runs exactly the core it was built and tested
with.  ``ebb_model`` uses relative imports internally; any absolute
``import ebb_model...`` statement in the copy is rewritten to the new name.

Only the model core goes in: :func:`core_modules` follows the imports (at module level and inside functions)
from the modules the slave imports (:data:`~fmu_build.slave_template.CORE_MODULES`), so the reference
solutions, the data generator and the file readers stay out.
"""
from __future__ import annotations

import ast
import io
import json
import shutil
import tokenize
from pathlib import Path
from typing import Any, Collection, Iterator, Mapping, Sequence

import pythonfmu
import pythonfmu3

import ebb_model
from ebb_model.errors import FmuError

from . import slave_base, slave_template, slave_template_fmi3
from .model_description import FmuIdentity

__all__ = ["write_resources", "copy_package", "core_modules", "core_sources", "render_slave", "render_base",
           "render_entry"]

_SKIP_DIRS = {"__pycache__"}


def _render(source: str, replacements: Mapping[str, str]) -> str:
    for old, new in replacements.items():
        if source.count(old) != 1:
            raise FmuError(f"slave template: expected exactly one line {old!r}", function="build_fmu")
        source = source.replace(old, new)
    return source


def render_slave(identity: FmuIdentity, fmi: int = 2) -> str:
    """Source of the FMU's slave module (FMI ``fmi``): the template with its names replaced.

    Raises
    ------
    FmuError
        If the template no longer contains the lines to replace.
    """
    template, cls, base = ((slave_template, slave_template.BeamSlave, "Fmi2Slave") if fmi == 2 else
                           (slave_template_fmi3, slave_template_fmi3.BeamSlave3, "Fmi3Slave"))
    return _render(Path(str(template.__file__)).read_text(encoding="utf-8"), {
        f"class {cls.__name__}(BeamModel, {base}):": f"class {identity.class_name}(BeamModel, {base}):",
        "from fmu_build.slave_base import": f"from {identity.model_identifier}_base import",
    })


def render_base(identity: FmuIdentity) -> str:
    """Source of the FMU's ``<modelIdentifier>_base.py``: ``slave_base`` importing the FMU's core."""
    return _render(Path(slave_base.__file__).read_text(encoding="utf-8"), {
        f'CORE_PACKAGE = "{slave_base.CORE_PACKAGE}"': f'CORE_PACKAGE = "{identity.core_package}"',
    })


def _render_entry2(identity: FmuIdentity) -> str:
    """Source of the entry module that pythonfmu executes per instance.

    pythonfmu 0.7.0 (``findClass``) imports this module, then executes its
    source again for every instance, with the module's namespace as globals
    and a fresh dict as locals, takes the slave class from the locals and
    finally releases one reference to the module's namespace that it never
    acquired.  The last statement adds one lasting reference per execution
    to balance that release (a few bytes per instance), without which the
    namespace would be freed under the module after a few instantiations.
    """
    return (
        f'"""Entry module of FMU {identity.model_identifier}: pythonfmu looks here for the slave class.\n\n'
        "pythonfmu 0.7.0 executes this source once per instance and then drops one reference to\n"
        'this module\'s namespace that it did not take: the last line keeps the count balanced."""\n'
        f"from {identity.model_identifier}_slave import {identity.class_name}\n"
        "\n"
        'globals().setdefault("_balance_pythonfmu_references", []).append(globals())\n'
    )


def render_entry(identity: FmuIdentity, fmi: int = 2) -> str:
    """Source of the entry module pythonfmu (``fmi=2``, :func:`_render_entry2`) or pythonfmu3 (``fmi=3``) imports.

    pythonfmu3 0.3.4 imports the module once, finds the line ``class <name>(... Fmi3Slave ...):`` in its source
    and takes that class from it.  When the import fails (the Python running the FMU lacks a package) it goes on
    with no module and crashes the host; so the import of the slave is caught here, and the class pythonfmu3 finds
    is then one whose instantiation raises the reason: the host gets a failed instantiation and the message.
    """
    if fmi == 2:
        return _render_entry2(identity)
    name, slave = identity.class_name, f"{identity.model_identifier}_slave"
    return (
        f'"""Entry module of FMU {identity.model_identifier}: pythonfmu3 looks here for the slave class.\n\n'
        "The slave's import error, if any, is raised when pythonfmu3 instantiates the class (pythonfmu3 0.3.4\n"
        'crashes on a failed import of this module)."""\n'
        "try:\n"
        f"    from {slave} import {name} as Fmi3Slave\n"
        "except Exception as exc:  # noqa: BLE001 - any reason the slave cannot run here\n"
        "    _reason = exc\n"
        "\n"
        "    class Fmi3Slave:  # type: ignore[no-redef]\n"
        "        def __init__(self, **kwargs):\n"
        "            raise _reason\n"
        "\n"
        "\n"
        f"class {name}(Fmi3Slave):\n"
        f'    """The slave of {slave} (or, when it cannot be imported, its import error)."""\n'
    )


def _import_statements(tree: ast.Module) -> Iterator[ast.Import | ast.ImportFrom]:
    """Every import statement of a module, at any depth (functions, classes, branches, ``try``, ``with``,
    ``match``), visiting the statements only: an import is a statement, and the expressions ``ast.walk`` would
    also visit are four nodes in five (the bundle of every FMU build parses its 25 modules twice)."""
    todo: list[ast.AST] = list(tree.body)
    while todo:
        node = todo.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
            continue
        for name in ("body", "orelse", "finalbody", "handlers", "cases"):
            block = getattr(node, name, None)
            if isinstance(block, list):
                todo.extend(block)


def _absolute_import_lines(source: str, package: str) -> tuple[set[int], bool]:
    """Line numbers of statements importing ``package`` absolutely.

    The flag says whether the module binds the package's own name
    (``import package`` or ``import package.sub`` without ``as``), in which
    case every later use of that name refers to the package too.
    """
    lines: set[int] = set()
    binds_name = False
    for node in _import_statements(ast.parse(source)):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
            binds_name = binds_name or any(
                a.asname is None and (a.name == package or a.name.startswith(package + ".")) for a in node.names
            )
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        if any(n == package or n.startswith(package + ".") for n in names):
            lines.update(range(node.lineno, (node.end_lineno or node.lineno) + 1))
    return lines, binds_name


def _rename_imports(source: str, old: str, new: str) -> str:
    """Rewrite absolute imports of package ``old`` to ``new`` (token-exact)."""
    lines, everywhere = _absolute_import_lines(source, old)
    if not lines:
        return source
    hits: list[tuple[int, int, int]] = []
    prev: tokenize.TokenInfo | None = None
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if (tok.type == tokenize.NAME and tok.string == old and (everywhere or tok.start[0] in lines)
                and not (prev is not None and prev.string in (".", "as"))):
            hits.append((tok.start[0], tok.start[1], tok.end[1]))
        if tok.type not in (tokenize.NL, tokenize.NEWLINE, tokenize.COMMENT):
            prev = tok
    text = source.splitlines(keepends=True)
    for row, c0, c1 in sorted(hits, reverse=True):
        line = text[row - 1]
        text[row - 1] = line[:c0] + new + line[c1:]
    return "".join(text)


def _module_file(src: Path, parts: tuple[str, ...]) -> Path | None:
    """The source file of module ``parts`` of the package in ``src`` (``None``: no such module)."""
    path = src.joinpath(*parts)
    if (path / "__init__.py").is_file():
        return path / "__init__.py"
    if path.with_suffix(".py").is_file():
        return path.with_suffix(".py")
    return None


def core_modules(src: Path, package: str, entries: Sequence[str]) -> list[Path]:
    """Source files of the package in ``src`` that ``entries`` need: their import closure within the package.

    Every import statement of a reached module counts, at module level or inside a function (a function the
    slave calls may import lazily); ``from . import name`` counts when ``name`` is a module. The packages
    containing a reached module are reached too.

    Parameters
    ----------
    src : Path
        Package directory (contains ``__init__.py``).
    package : str
        The package's import name (for absolute self-imports).
    entries : sequence of str
        Modules imported from outside, relative to the package: ``""`` for the package, ``".beam"``.

    Returns
    -------
    list of Path
        Sorted source files.
    """
    todo = [tuple(m.split(".")[1:]) for m in entries]
    seen: set[Path] = set()
    while todo:
        parts = todo.pop()
        path = _module_file(src, parts)
        if path is None or path in seen:
            continue
        seen.add(path)
        todo += [parts[:i] for i in range(len(parts))]
        here = parts if path.name == "__init__.py" else parts[:-1]
        for node in _import_statements(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here[:len(here) - (node.level - 1)]
                    module = base + tuple(node.module.split(".")) if node.module else base
                elif node.module and node.module.split(".")[0] == package:
                    module = tuple(node.module.split(".")[1:])
                else:
                    continue
                todo.append(module)
                todo += [module + (a.name,) for a in node.names]
            elif isinstance(node, ast.Import):
                todo += [tuple(a.name.split(".")[1:]) for a in node.names if a.name.split(".")[0] == package]
    return sorted(seen)


def copy_package(src: Path, dest: Path, *, old_name: str, new_name: str,
                 only: Collection[Path] | None = None) -> None:
    """Copy the package directory ``src`` to ``dest``, renaming absolute self-imports.

    Parameters
    ----------
    src
        Package directory (contains ``__init__.py``).
    dest
        Directory to create.
    old_name, new_name
        The package's import name and the name of the copy.
    only
        The files to copy (e.g. :func:`core_modules`); default every file.
    """
    for path in sorted(src.rglob("*")):
        if only is not None and path not in only:
            continue
        rel = path.relative_to(src)
        if any(part in _SKIP_DIRS for part in rel.parts) or path.is_dir():
            continue
        if path.suffix in (".pyc", ".pyo", ".so", ".nbi", ".nbc"):
            continue
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        if path.suffix == ".py":
            text = path.read_text(encoding="utf-8")
            target.write_text(_rename_imports(text, old_name, new_name), encoding="utf-8")
        else:
            shutil.copy2(path, target)


def core_sources() -> list[Path]:
    """The ``ebb_model`` source files an FMU bundles: the import closure of the modules the slave imports."""
    return core_modules(Path(ebb_model.__file__).parent, "ebb_model", slave_base.CORE_MODULES)


def write_resources(resources: Path, *, identity: FmuIdentity, spec: Mapping[str, Any],
                    sources: Collection[Path], fmi: int = 2) -> None:
    """Fill ``resources`` with everything the slave needs at run time.

    Parameters
    ----------
    resources
        Empty directory (the future ``resources/`` of the FMU).
    identity
        Names of this build.
    spec
        JSON-serialisable model description for the slave (config, options).
    sources
        The core's source files to bundle (:func:`core_sources`; the caller named the core from them).
    fmi
        The FMI version: 2 (pythonfmu) or 3 (pythonfmu3).
    """
    resources.mkdir(parents=True, exist_ok=True)
    slave = f"{identity.model_identifier}_slave"
    (resources / "slavemodule.txt").write_text(identity.model_identifier, encoding="utf-8")
    (resources / f"{identity.model_identifier}.py").write_text(render_entry(identity, fmi), encoding="utf-8")
    (resources / f"{slave}.py").write_text(render_slave(identity, fmi), encoding="utf-8")
    (resources / f"{identity.model_identifier}_base.py").write_text(render_base(identity), encoding="utf-8")
    (resources / slave_base.SPEC_FILE).write_text(json.dumps(spec, indent=2, allow_nan=False), encoding="utf-8")
    core_src = Path(ebb_model.__file__).parent
    copy_package(core_src, resources / identity.core_package, old_name="ebb_model", new_name=identity.core_package,
                 only=set(sources))
    package = pythonfmu if fmi == 2 else pythonfmu3
    runtime = resources / package.__name__
    runtime.mkdir()
    for f in Path(str(package.__file__)).parent.glob("*.py"):
        shutil.copy2(f, runtime / f.name)
