"""Universal File Format data set 58 (function at nodal DOF) time histories, via pyuff.

Each channel is one type-58 record with function type 1 (time response); the
record is named by its ID line 1 (``id1``) and its unit is the ordinate units
label (record 9, field 6; ``NONE`` = not given).  The time vector is the
abscissa of the first record (``abscissa_min + k * abscissa_inc`` for even
spacing); every record used must share it.

UFF58 ASCII headers store the abscissa minimum and increment as ``E13.5``
(6 significant digits), so the time vector is known only to a relative
5e-6 per step; :attr:`RawTable.time_tolerance` carries that bound so that the
loader can recognise a record sampled at the config's ``dt``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyuff

from ebb_model.errors import DataError
from ebb_model.io.textio import printable

from .table import RawTable

__all__ = ["read_uff58"]

#: relative accuracy of a value written as E13.5 (half a unit in the 6th significant digit)
_E13_5 = 5e-6


def read_uff58(path: str | Path) -> RawTable:
    """Read the type-58 time-history records of a UFF file into a RawTable.

    Raises
    ------
    DataError
        Unreadable file, no type-58 records.
    """
    p = Path(path)
    if not p.is_file():
        raise DataError(f"{p}: cannot read (no such file)")
    try:
        sets = pyuff.UFF(str(p)).read_sets()
    except Exception as exc:  # pyuff raises bare Exception on malformed data sets
        raise DataError(f"{p}: not a readable universal file ({type(exc).__name__}: "
                        f"{printable(str(exc), 160)})") from None
    if isinstance(sets, dict):
        sets = [sets]
    records = [s for s in sets if int(s.get("type", -1)) == 58]
    if not records:
        raise DataError(f"{p}: no type-58 (function at nodal DOF) records")
    first = records[0]
    t = np.asarray(first["x"], dtype=float)
    if int(first.get("abscissa_spacing", 0)) == 1:
        t_min = float(first.get("abscissa_min", t[0]))
        inc = float(first.get("abscissa_inc", 0.0))
        tol = _E13_5 * (abs(t_min) + (t.size - 1) * abs(inc))
    else:
        tol = _E13_5 * float(np.max(np.abs(t))) if t.size else 0.0
    names: list[str] = []
    columns: list[np.ndarray] = []
    units: list[str | None] = []
    unusable: list[str | None] = []
    for r in records:
        names.append(str(r.get("id1", "")).strip())
        data = np.asarray(r.get("data"))
        x = np.asarray(r.get("x"), dtype=float)
        func = int(r.get("func_type", 0))
        why = None
        if func not in (0, 1) or np.iscomplexobj(data):
            why = f"is not a real time history (function type {func})"
        elif x.shape == t.shape and t.size and float(np.max(np.abs(x - t))) > 2 * tol + 1e-12 * np.max(np.abs(t)):
            why = f"has another abscissa (time) than the first record {names[0]!r}"
        columns.append(data)
        unusable.append(why)
        lab = str(r.get("ordinate_axis_units_lab", "") or "").strip()
        units.append(None if lab.upper() in ("", "NONE") else lab)
    return RawTable(source=str(p), kind="record", names=tuple(names), columns=tuple(columns),
                    units=tuple(units), resolution=(0.0,) * len(names), time=t, time_tolerance=tol,
                    time_key=0, unusable=tuple(unusable))
