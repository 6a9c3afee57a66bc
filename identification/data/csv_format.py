"""CSV experiment files: one header row naming the columns, then numbers.

Leading blank lines and ``#`` comment lines are skipped; the delimiter is
the first of ``,`` ``;`` tab found in the header.  The time column is called
``time`` unless the mapping says otherwise.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ebb_model.errors import DataError
from ebb_model.textio import read_text as read_file_text

from .table import RawTable
from .textblock import column_resolutions, edge_lines, parse_block

__all__ = ["read_csv"]


def read_text(path: Path) -> str:
    """Read a text data file (UTF-8, BOM tolerated; Latin-1 as a fallback; binary data refused)."""
    return read_file_text(path, DataError, what="data file", latin1_fallback=True)


def read_csv(path: str | Path) -> RawTable:
    """Read a CSV file into a :class:`~identification.data.table.RawTable`.

    Raises
    ------
    DataError
        Empty file, duplicate column names, ragged rows, non-numeric fields.
    """
    p = Path(path)
    text = read_text(p)
    pos, lineno = 0, 1
    header = None
    while pos < len(text):
        nl = text.find("\n", pos)
        end = len(text) if nl < 0 else nl
        line = text[pos:end].strip()
        pos = end + 1
        if line and not line.startswith("#"):
            header = line
            break
        lineno += 1
    if header is None:
        raise DataError(f"{p}: empty file (no header row)")
    delimiter = next((d for d in (",", ";", "\t") if d in header), ",")
    names = tuple(h.strip().strip('"').strip() for h in header.split(delimiter))
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise DataError(f"{p}: column name(s) used more than once in the header: {', '.join(dup)}")
    block = text[pos:]
    arr = parse_block(block, delimiter=delimiter, names=names, source=str(p), first_line=lineno + 1)
    res = column_resolutions(edge_lines(block), delimiter, len(names))
    columns = tuple(np.ascontiguousarray(arr[:, j]) for j in range(arr.shape[1]))
    return RawTable(source=str(p), kind="column", names=names, columns=columns,
                    units=(None,) * len(names), resolution=res, time_key="time")
