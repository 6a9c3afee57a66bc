"""The layout promised in docs/architecture.md, checked: no import cycle between the project's modules (imports at
module level; an import inside a function is a deliberate late binding and is not counted), and the diagnosis'
folders are its stages, each importing only the stages before it."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("ebb_model", "fmu_build", "identification", "diagnosis", "ebb_cli")


def _module(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, modules: set[str]) -> set[str]:
    """The project modules ``path`` imports at module level (``from . import x`` resolved to the module ``x``
    when it is one)."""
    tree = ast.parse(path.read_text(), str(path))
    me = _module(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    found: set[str] = set()
    for node in tree.body:     # module level only
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            found.add(target)
            found |= {f"{target}.{a.name}" for a in node.names}
    return {m for m in found if m in modules and m != me}


def test_no_import_cycle_between_modules():
    files = [p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")]
    modules = {_module(p) for p in files}
    graph = {_module(p): _imports(p, modules) for p in files}
    # a package's __init__ importing its own modules is how a package is made, not a cycle
    for m, deps in graph.items():
        graph[m] = {d for d in deps if not d.startswith(m + ".")}
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def visit(m: str, path: list[str]) -> None:
        state[m] = 1
        for d in sorted(graph.get(m, ())):
            if state.get(d) == 1:
                cycles.append(path[path.index(d):] + [d] if d in path else [m, d])
            elif d not in state:
                visit(d, path + [d])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert len(graph) > 150 and not cycles, cycles[:5]


def test_the_diagnosis_folders_are_its_stages():
    folders = {p.name for p in (ROOT / "diagnosis").iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert folders == {"problem", "baseline", "effects", "candidates", "search", "localise", "judgement", "design",
                       "report", "corrected"}
    loose = sorted(p.stem for p in (ROOT / "diagnosis").glob("*.py"))
    assert loose == ["__init__", "batch", "demo", "from_modes", "run", "settings", "setups", "stages"], loose


#: The diagnosis' stages in the order they run; the problem they share and the effects first.
STAGES = ("effects", "problem", "baseline", "candidates", "search", "localise", "judgement", "design", "report",
          "corrected")


def test_the_diagnosis_stages_point_one_way():
    """Every import of one stage's module from another's — at module level, under ``TYPE_CHECKING`` or inside a
    function — names an earlier stage: types several stages share live below them (the evidence and the
    plausibility checks in ``problem``, the sign weighed with the refits in ``baseline``), and what a stage must
    ask of a later one is handed to it (the search's ``settled``: the judgement's naming rule, bound by the
    orchestrator)."""
    late: list[str] = []
    for path in (ROOT / "diagnosis").rglob("*.py"):
        rel = path.relative_to(ROOT / "diagnosis").parts
        if len(rel) < 2:
            continue                                  # the orchestrator and the settings sit above the stages
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, ast.ImportFrom):
                continue
            mod = node.module or ""
            target = (mod.split(".")[0] if node.level == 2 else
                      mod.split(".")[1] if node.level == 0 and mod.startswith("diagnosis.") else None)
            if target in STAGES and target != rel[0] and STAGES.index(target) > STAGES.index(rel[0]):
                late.append(f"{'/'.join(rel)} imports the later stage {target}")
    assert not late, late


def test_no_package_attribute_hides_a_subpackage():
    """Every package's sub-packages are reachable as attributes of it: a name the package exports must not be one of
    its sub-packages' (``ebb_model.modes``, a function, hid the folder ``ebb_model/modes/``, and
    ``import ebb_model.modes.coupled_modes as m`` failed on a fresh clone)."""
    import importlib
    import pkgutil

    hidden = []
    for name in PACKAGES:
        top = importlib.import_module(name)
        for info in pkgutil.walk_packages(top.__path__, name + "."):
            if not info.ispkg:
                continue
            parent, _, child = info.name.rpartition(".")
            sub = importlib.import_module(info.name)
            if getattr(importlib.import_module(parent), child, None) is not sub:
                hidden.append(info.name)
    assert not hidden, hidden
