"""Text tables with a preamble: what DAQ software writes as ``.txt`` (LabVIEW's spreadsheet export, DROPBEAR's runs).

A few free lines (a path, the operator, the sampling rate, a date), then a line of channel names, often a line of
units, sometimes more lines, then rows of numbers separated by tabs (or, without a tab in the file, by blanks)::

    C:\\Users\\...\\test0.txt
    Sampling Frequency - 5000
    Low G Accel	Accel	PinLoc	Time
    Voltage (unscaled)	Voltage (unscaled)	Voltage (unscaled)	Sec
    0.00000E+0	6.71387E-2	1.22559E+0	0.00000E+0
    ...

The data are the rows of as many numbers as most numeric rows hold, from the first such row after the names to
the end (blank lines skipped; any other line there is refused, naming it).  The names are the first of the last
run of lines, before the data, that split into that many fields of which none is a number; the line after it in
that run holds the units (kept as written: :mod:`identification.data.units` converts what it knows, and a label
it does not know — ``Voltage (unscaled)`` — is refused when read, with how to override it).  The time channel is
the one named ``time`` in any case.
"""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from ebb_model.errors import DataError

from .csv_format import read_text
from .table import RawTable
from .textblock import column_resolutions

__all__ = ["read_text_table"]


def _fields(line: str, tabbed: bool) -> list[str]:
    return [f.strip() for f in (line.split("\t") if tabbed else line.split())]


def _numbers(fields: list[str]) -> list[float] | None:
    """The fields as numbers, or ``None`` when one is not a number."""
    try:
        return [float(f) for f in fields]
    except ValueError:
        return None


def _is_text(fields: list[str]) -> bool:
    """Fields that are all labels (none empty, none a number)."""
    for f in fields:
        if not f:
            return False
        try:
            float(f)
            return False
        except ValueError:
            pass
    return True


def read_text_table(path: str | Path) -> RawTable:
    """Read a text table with a preamble (module docstring) into a :class:`~identification.data.table.RawTable`.

    Raises
    ------
    DataError
        A binary or empty file, no row of numbers, no line of names before them, a line among the rows that is not
        as many numbers — naming the file and the line.
    """
    p = Path(path)
    text = read_text(p)
    lines = text.splitlines()
    tabbed = "\t" in text
    rows = {i: _numbers(_fields(ln, tabbed)) for i, ln in enumerate(lines) if ln.strip()}
    counts = Counter(len(v) for v in rows.values() if v is not None)
    if not counts:
        raise DataError(f"{p}: no row of numbers")
    k = counts.most_common(1)[0][0]
    first = next(i for i, v in rows.items() if v is not None and len(v) == k)
    names_at = None
    for i in range(first - 1, -1, -1):                 # the last run of k labels before the first row
        f = _fields(lines[i], tabbed) if lines[i].strip() else []
        if len(f) == k and _is_text(f):
            names_at = i
        elif names_at is not None:
            break
    if names_at is None:
        raise DataError(f"{p}: no line of {k} channel names before the first row of numbers (line {first + 1})")
    first = next((i for i, v in rows.items() if i > names_at and v is not None and len(v) == k), first)
    data = []
    for i in range(first, len(lines)):
        if not lines[i].strip():
            continue
        v = rows[i]
        if v is None or len(v) != k:
            raise DataError(f"{p}: line {i + 1} is not {k} numbers like the rows before it: "
                            f"{lines[i].strip()[:60]!r}")
        data.append(v)
    names = tuple(_fields(lines[names_at], tabbed))
    if len(set(names)) < k:
        raise DataError(f"{p}: channel names repeat on line {names_at + 1}: {', '.join(names)}")
    after = _fields(lines[names_at + 1], tabbed) if names_at + 1 < first else []
    units = tuple(after) if len(after) == k and _is_text(after) else (None,) * k
    a = np.array(data, dtype=float)
    sample = [lines[i] for i in range(first, min(first + 5, len(lines)))] + lines[-5:]
    res = column_resolutions(["\t".join(_fields(ln, tabbed)) for ln in sample if ln.strip()], "\t", k)
    time_key: str | int = next((n for n in names if n.lower() == "time"), "time")
    return RawTable(source=str(p), kind="column", names=names,
                    columns=tuple(np.ascontiguousarray(a[:, j]) for j in range(k)), units=units, resolution=res,
                    time_key=time_key)
