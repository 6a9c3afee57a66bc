"""CSV experiment files, read by :func:`ebb_model.io.csvio.read_csv_table` (the one set of CSV rules).

Leading blank lines and ``#`` comment lines are skipped; the delimiter is
the first of ``,`` ``;`` tab found in the header.  The time column is called
``time`` unless the mapping says otherwise.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ebb_model.io.csvio import read_csv_table
from ebb_model.errors import DataError
from ebb_model.io.textio import read_text as read_file_text

from .table import RawTable
from .textblock import column_resolutions, edge_lines

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
    table = read_csv_table(path, what="data file")
    res = column_resolutions(edge_lines(table.block), table.delimiter, len(table.names))
    columns = tuple(np.ascontiguousarray(table.data[:, j]) for j in range(table.data.shape[1]))
    return RawTable(source=table.source, kind="column", names=table.names, columns=columns,
                    units=(None,) * len(table.names), resolution=res, time_key="time")
