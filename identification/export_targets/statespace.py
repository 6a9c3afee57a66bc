"""Export target ``statespace``: the model as a python-control StateSpace file (``<stem>.npz``).

With the option ``reduce_order`` also a balanced truncation of that order (``<stem>_reduced<order>.npz``) and
its H∞ error bound (``<stem>_reduced<order>.json``), unless the model has no balanced realisation.
"""
from __future__ import annotations

from pathlib import Path

from ebb_model.errors import StabilityError
from ebb_model.io.jsonio import write_json

from ..export_statespace import balanced_truncation, save_statespace
from . import ExportItem

__all__ = ["carries", "write"]


def carries(item: ExportItem) -> str:
    """What the files carry (or why there are none)."""
    if item.system is None:
        return f"no StateSpace: {item.no_system}"
    return ("StateSpace of the model" + item.acquisition
            + (f" ({item.parts} as states in series)" if item.parts else ""))


def write(item: ExportItem, out_dir: Path) -> list[Path]:
    """Write ``<stem>.npz`` (and the reduced model on request) into ``out_dir``; return the files — none when the
    model has no StateSpace form (``item.system`` is ``None``: :func:`carries` says why)."""
    if item.system is None:
        return []
    config = item.config.to_dict()
    written = [save_statespace(item.system, out_dir / f"{item.stem}.npz", name=item.title,
                               parameters=item.params, config=config, modes=item.modes)]
    order = item.options.get("reduce_order")
    if not order:
        return written
    try:
        bm = balanced_truncation(item.system, order)
    except StabilityError:
        return written
    stem = f"{item.stem}_reduced{order}"
    written.append(save_statespace(bm.system, out_dir / f"{stem}.npz", name=f"{item.title}_reduced{order}",
                                   parameters=item.params, config=config))
    written.append(write_json(out_dir / f"{stem}.json", {
        "order": bm.order, "error_bound_hinf": bm.error_bound,
        "hankel_singular_values": [float(v) for v in bm.hankel_singular_values]}))
    return written
