"""Export of Pareto points: python-control StateSpace (``.npz``) and, when available, FMUs.

``export_points(DIR)`` reads ``DIR/pareto.json`` (written by
:func:`identification.run.identify`) and writes, per chosen Pareto point
``i``, ``DIR/export/point_<i>.npz`` (reload with
:func:`identification.export_statespace.load_statespace`) and
``DIR/export/point_<i>.fmu`` with the identified values as start values (via
:mod:`fmu_build`; each FMU gets its own model identifier so several load side
by side), and the same per chosen polished point ``j`` as
``DIR/export/polished_<j>.*``.  With ``standalone=True`` each point also gets
``<stem>_standalone.fmu``, the C FMU of :mod:`fmu_build.standalone` (no Python
at run time), beside the pythonfmu one (or alone with ``fmu=False``).
Optionally a balanced-truncation reduced model with its error bound.  Unstable points are listed in ``pareto.json`` but not
exported.

The formats are export targets (:data:`TARGETS`): one module of :mod:`identification.export_targets` each,
registered by one line.
"""
from __future__ import annotations

import importlib
import json
from collections.abc import Callable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Sequence

from ebb_model import assemble, config_from_dict
from ebb_model.errors import ConfigError, StabilityError
from ebb_model.output import check_writable_dir, make_dir

from .export_targets import ExportItem
from .parameters import ParameterSpace
from .settings import SECTION

__all__ = ["TARGETS", "export_points", "export_target"]

#: Export targets: name → module of :mod:`identification.export_targets` providing ``write(item, out_dir)``.
TARGETS: Mapping[str, str] = MappingProxyType({
    "statespace": "identification.export_targets.statespace",   # python-control StateSpace (.npz)
    "fmu": "identification.export_targets.fmu",                 # pythonfmu FMU
    "standalone": "identification.export_targets.standalone",   # standalone C FMU
})


def export_target(name: str) -> Callable[[ExportItem, Path], list[Path]]:
    """The ``write`` function of export target ``name``.

    Raises
    ------
    ConfigError
        ``name`` is not in :data:`TARGETS` (the message lists them).
    """
    if name not in TARGETS:
        raise ConfigError(f"`targets`: unknown export target {name!r}; allowed: {', '.join(TARGETS)}")
    return importlib.import_module(TARGETS[name]).write


def _chosen(what: str, selection: Sequence[int] | str | None, n: int) -> Sequence[int]:
    """Indices chosen by ``selection``: ``None`` none, ``"all"`` every one (there must be some)."""
    if selection is None:
        return []
    if isinstance(selection, str):
        if selection != "all":
            raise ConfigError(f"`{what}`: expected indices or 'all', got {selection!r}")
        if n == 0:
            hint = " (run `identify` with `polish` K)" if what == "polished" else ""
            raise ConfigError(f"`{what}`: this run has no {what} points{hint}")
        return range(n)
    chosen = [int(i) for i in selection]
    bad = [i for i in chosen if not 0 <= i < n]
    if bad:
        raise ConfigError(f"`{what}`: {bad} out of range" + (f" 0 … {n - 1}" if n else f" (no {what} points)"))
    return chosen


def export_points(result_dir: str | Path, points: Sequence[int] | str | None = None, *,
                  polished: Sequence[int] | str | None = None, fmu: bool = True,
                  reduce_order: int | None = None, standalone: bool = False,
                  targets: Sequence[str] | None = None) -> list[Path]:
    """Export Pareto and polished points of a result directory. Returns the written files.

    ``points`` and ``polished`` are index lists or ``"all"``.  With neither
    given, every Pareto point and every polished point is exported; when one
    selection is given, the other defaults to none.  ``targets`` names the
    formats (:data:`TARGETS`); by default ``statespace``, then ``fmu`` if
    ``fmu`` and ``standalone`` if ``standalone``.

    Raises
    ------
    ConfigError
        No readable result, indices out of range, ``"all"`` of none, or
        ``reduce_order`` outside ``1 … nstates``, an unknown target — before anything is written.
    OutputError
        ``result_dir`` cannot take the exports (read-only, full: checked before any work), or writing failed
        (no half-written file is left).
    """
    if targets is None:
        targets = ["statespace"] + ["fmu"] * bool(fmu) + ["standalone"] * bool(standalone)
    writers = [export_target(t) for t in targets]
    d = Path(result_dir)
    try:
        doc = json.loads((d / "pareto.json").read_text())
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{d}: no readable pareto.json ({exc})") from None
    check_writable_dir(d / "export" if (d / "export").is_dir() else d)   # before any work
    cfg = config_from_dict(doc["config"], extra_sections=(SECTION,))
    pts = doc["points"]
    pol = doc.get("polished", [])
    if points is None and polished is None:
        chosen_pts = range(len(pts))
        chosen_pol = range(len(pol))
    else:
        chosen_pts = _chosen("points", points, len(pts))
        chosen_pol = _chosen("polished", polished, len(pol))
    names = tuple(doc["parameter_names"])
    jobs = [(f"point_{i}", pts[i]["parameters"]) for i in chosen_pts]
    jobs += [(f"polished_{j}", pol[j]["parameters"]) for j in chosen_pol]
    models = []
    for stem, values in jobs:
        space = ParameterSpace(names, [0.0] * len(names), [0.0] * len(names), [0.0] * len(names))
        c, params = space.apply(cfg, [values[n] for n in names])
        try:
            models.append((stem, c, params, assemble(c, params)))
        except StabilityError:
            continue  # unstable points are listed in pareto.json but not exported
    if reduce_order is not None and models:
        n_states = models[0][3].nstates
        if isinstance(reduce_order, bool) or not 1 <= reduce_order <= n_states:
            raise ConfigError(f"`reduce_order`: must lie in 1 … {n_states} (the model's states), "
                              f"got {reduce_order}")
    out = make_dir(d / "export", exist_ok=True)
    written: list[Path] = []
    title = doc.get("config_name") or d.name
    options = MappingProxyType({"reduce_order": reduce_order} if reduce_order else {})
    for stem, c, params, sys in models:
        item = ExportItem(stem, f"{title}_{stem}", c, params, sys, options)
        for write in writers:
            written += write(item, out)
    return written
