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
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Sequence

from ebb_model import assemble, config_from_dict
from ebb_model.errors import ConfigError, StabilityError
from ebb_model.jsonio import write_json

from .export_statespace import balanced_truncation, save_statespace
from .parameters import ParameterSpace
from .settings import SECTION

__all__ = ["export_points"]


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
                  reduce_order: int | None = None, standalone: bool = False) -> list[Path]:
    """Export Pareto and polished points of a result directory. Returns the written files.

    ``points`` and ``polished`` are index lists or ``"all"``.  With neither
    given, every Pareto point and every polished point is exported; when one
    selection is given, the other defaults to none.

    Raises
    ------
    ConfigError
        No readable result, indices out of range, ``"all"`` of none, or
        ``reduce_order`` outside ``1 … nstates`` — before anything is written.
    """
    d = Path(result_dir)
    try:
        doc = json.loads((d / "pareto.json").read_text())
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{d}: no readable pareto.json ({exc})") from None
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
    out = d / "export"
    out.mkdir(exist_ok=True)
    written: list[Path] = []
    title = doc.get("config_name") or d.name
    for stem, c, params, sys in models:
        written.append(save_statespace(sys, out / f"{stem}.npz", name=f"{title}_{stem}", parameters=params,
                                       config=c.to_dict()))
        if reduce_order:
            try:
                bm = balanced_truncation(sys, reduce_order)
            except StabilityError:
                bm = None
            if bm is not None:
                written.append(save_statespace(bm.system, out / f"{stem}_reduced{reduce_order}.npz",
                                               name=f"{title}_{stem}_reduced{reduce_order}", parameters=params,
                                               config=c.to_dict()))
                written.append(write_json(out / f"{stem}_reduced{reduce_order}.json", {
                    "order": bm.order, "error_bound_hinf": bm.error_bound,
                    "hankel_singular_values": [float(v) for v in bm.hankel_singular_values]}))
        if fmu:
            from fmu_build import build_fmu

            c_fmu = c.with_parameters(**params)
            written.append(build_fmu(c_fmu, out / f"{stem}.fmu"))
        if standalone:
            from fmu_build.standalone import build_standalone_fmu

            written.append(build_standalone_fmu(c.with_parameters(**params), out / f"{stem}_standalone.fmu"))
    return written
