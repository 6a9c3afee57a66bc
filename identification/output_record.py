"""A record without a force, read as evidence: its sensors' columns, their modes, those modes as measured ones.

A free decay (:func:`identification.output_modes.free_decay_modes`) or a record under a force nobody measured
(:func:`identification.ambient_modes.ambient_modes`) is read with the options of ``[identification.data]`` (the
file's channels named by ``mapping``, their ``units`` and ``gains``; entries for the actuators are not read) —
only the config's sensors, no force column — and its modes become the config's ``[identification.modes]``
(:func:`identification.modal_data.with_modes`): ``ebb identify`` and ``ebb diagnose`` then weigh them alone or
with records that have their force.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import MappingProxyType
from typing import Any, Callable

import numpy as np

from ebb_model.config import BeamConfig
from ebb_model.errors import DataError

from .ambient_modes import ambient_modes
from .data import load_experiment
from .output_modes import OutputModes, free_decay_modes
from .settings import identification_settings

__all__ = ["KINDS", "sensor_record", "record_output_modes", "declared_channel"]

#: What a record without a force can be, and how its modes are read.
KINDS: dict[str, Callable[[np.ndarray, float], OutputModes]] = {"decay": free_decay_modes, "ambient": ambient_modes}


def sensor_record(config: BeamConfig, path: str | Path) -> np.ndarray:
    """The config's sensors' columns of the record at ``path`` ``(n, n_sensors)``, in SI units, sampled at the
    config's ``dt`` — read with ``[identification.data]``'s options, without the actuators.

    Raises
    ------
    DataError
        The file cannot be read, a sensor's column is missing, a value is not finite, the sample interval is not
        the config's (all from :func:`identification.data.load_experiment`).
    """
    forces = {a.name for a in config.actuators}
    opts: dict[str, Any] = dict(identification_settings(config).data)
    for key in ("mapping", "units", "gains"):
        if key in opts and opts[key] is not None:
            opts[key] = MappingProxyType({k: v for k, v in dict(opts[key]).items() if k not in forces})
    bare = replace(config, actuators=())
    return np.asarray(load_experiment(path, bare, **opts).outputs, dtype=float)


def record_output_modes(config: BeamConfig, path: str | Path, kind: str) -> OutputModes:
    """The modes of the record at ``path`` without a force: ``kind`` ``"decay"`` (the structure left ringing at the
    record's first sample) or ``"ambient"`` (stationary under an unmeasured broadband force).

    Raises
    ------
    DataError
        An unknown ``kind``; the record cannot be read (:func:`sensor_record`) or is too short for ``kind``.
    """
    if kind not in KINDS:
        raise DataError(f"a record without a force is a 'decay' or 'ambient', got {kind!r}")
    return KINDS[kind](sensor_record(config, path), config.time.dt)


def declared_channel(path: str | Path, name: str) -> np.ndarray:
    """The column ``name`` of the record at ``path`` as it is stored (a position sensor's volts, a load cell's
    reading: a channel that says when the set-up changed, in its own units).

    Raises
    ------
    DataError
        The file cannot be read, it has no such column, or a value is not finite.
    """
    from .data.loaders import EXTENSIONS, FORMATS

    p = Path(path)
    fmt = EXTENSIONS.get(p.suffix.lower())
    if fmt is None:
        raise DataError(f"{p}: cannot tell the format from the extension {p.suffix!r}; known: {', '.join(EXTENSIONS)}")
    table = FORMATS[fmt].read(p)
    i = table.index(name)
    if i is None and name.isdigit():            # a column by its 0-based index
        i = table.index(int(name))
    if i is None:
        raise DataError(f"{p}: no {table.kind} {name!r} for the declared channel; found {', '.join(table.names)}")
    a = np.asarray(table.columns[i], dtype=float).reshape(-1)
    if not np.all(np.isfinite(a)):
        raise DataError(f"{p}: the declared channel {name!r} holds NaN or infinite values")
    return a
