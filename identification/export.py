"""Export of identified models: python-control StateSpace (``.npz``), FMUs — chosen by target name.

``export_points(result, …)`` writes, per chosen Pareto point ``i`` of an :class:`~identification.result.
IdentificationResult` (in memory, or read back with :meth:`~identification.result.IdentificationResult.read`),
``<out_dir>/export/point_<i>.*`` and per chosen polished point ``j`` ``<out_dir>/export/polished_<j>.*``: one file
(or more) per export target of :data:`~identification.export_targets.TARGETS` — ``statespace`` (``.npz``, reload with
:func:`identification.export_statespace.load_statespace`; optionally a balanced truncation with its error bound),
``fmu`` (the pythonfmu FMU, the identified values as start values; each FMU its own model identifier so several
load side by side), ``standalone`` (``<stem>_standalone.fmu``, the C FMU of :mod:`fmu_build.standalone`, no
Python at run time).  Each point is assembled once and handed to every target.  Unstable points are listed in
``pareto.json`` but not exported.

The formats are export targets (:data:`~identification.export_targets.TARGETS`): one module of
:mod:`identification.export_targets` each, registered by one line; ``identify``, ``export`` and the diagnosis'
corrected model choose them by name.
"""
from __future__ import annotations

import warnings
from pathlib import Path
from types import MappingProxyType
from typing import Sequence

from ebb_model import assemble
from ebb_model.acquisition.delay_line import delay_line, exported_config
from ebb_model.errors import ConfigError, ConfigWarning, StabilityError
from ebb_model.modal.truncation import design_model, design_resolution
from ebb_model.io.output import check_writable_dir, make_dir

from .export_targets import DEFAULT_TARGETS, ExportItem, check_targets, export_target
from .result import IdentificationResult

__all__ = ["export_points", "chosen"]


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


def chosen(result: IdentificationResult, points: Sequence[int] | str | None,
           polished: Sequence[int] | str | None) -> tuple[Sequence[int], Sequence[int]]:
    """The Pareto and polished indices a selection names: with neither given, every one of both; when one is
    given, the other defaults to none.

    Raises
    ------
    ConfigError
        Indices out of range, ``"all"`` of none.
    """
    if points is None and polished is None:
        return range(len(result.pareto.X)), range(len(result.polished))
    return (_chosen("points", points, len(result.pareto.X)), _chosen("polished", polished, len(result.polished)))


def export_points(result: IdentificationResult, points: Sequence[int] | str | None = None, *,
                  polished: Sequence[int] | str | None = None, targets: Sequence[str] = DEFAULT_TARGETS,
                  reduce_order: int | None = None, modes_up_to: float | None = None) -> list[Path]:
    """Export Pareto and polished points of an identification result into ``result.out_dir / "export"``.

    Parameters
    ----------
    result
        The identification's result (:func:`identification.run.identify`, or
        :meth:`IdentificationResult.read` of its directory).
    points, polished
        Index lists or ``"all"``.  With neither given, every Pareto point and every polished point is exported;
        when one selection is given, the other defaults to none.
    targets
        Export target names (:data:`TARGETS`), default :data:`DEFAULT_TARGETS`.
    reduce_order
        The ``statespace`` target also writes a balanced truncation of this order.
    modes_up_to
        The ``statespace`` target keeps the modes up to this frequency [Hz] that the grid resolves, the others
        as a static correction (:func:`ebb_model.modal.truncation.design_model`; which modes, with each one's error
        estimate, in the file's metadata, ``modes``); default the Nyquist frequency, ``math.inf`` every mode.
        The FMUs always carry the whole beam.

    Returns
    -------
    list of Path
        The written files.

    Raises
    ------
    ConfigError
        Indices out of range, ``"all"`` of none, ``reduce_order`` outside ``1 … nstates``, ``modes_up_to`` not
        positive, an unknown target — before anything is written.
    OutputError
        ``result.out_dir`` cannot take the exports (read-only, full: checked before any work), or writing failed
        (no half-written file is left).
    """
    writers = [export_target(t) for t in check_targets(targets, result.config)]
    if modes_up_to is not None and not modes_up_to > 0:
        raise ConfigError(f"`modes_up_to`: must be > 0 Hz, got {modes_up_to!r}")
    d = result.out_dir
    check_writable_dir(d / "export" if (d / "export").is_dir() else d)   # before any work
    models = []
    left_out = exported_config(result.config)[1]
    if left_out:
        warnings.warn(left_out, ConfigWarning, stacklevel=2)
    for stem, c, params in result.models(*chosen(result, points, polished)):
        # the channels' converter delays as delay-line states where causal (ebb_model.acquisition.delay_line)
        c = exported_config(c)[0]
        try:
            beam = assemble(c, params)
            resolution = design_resolution(c, params, f_max=modes_up_to)
            design = delay_line(design_model(c, params, f_max=modes_up_to, resolution=resolution))
            models.append((stem, c, params, design, beam, resolution))
        except StabilityError:
            continue  # unstable points are listed in pareto.json but not exported
    if reduce_order is not None and models:
        n_states = models[0][3].nstates
        if isinstance(reduce_order, bool) or not 1 <= reduce_order <= n_states:
            raise ConfigError(f"`reduce_order`: must lie in 1 … {n_states} (the model's states), "
                              f"got {reduce_order}")
    out = make_dir(d / "export", exist_ok=True)
    written: list[Path] = []
    options = MappingProxyType({"reduce_order": reduce_order} if reduce_order else {})
    for stem, c, params, sys, beam, resolution in models:
        item = ExportItem(stem, f"{result.config_name}_{stem}", c, params, sys, options, beam_system=beam,
                          modes=None if resolution is None else resolution.to_dict())
        for write in writers:
            written += write(item, out)
    return written
