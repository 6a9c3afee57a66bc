"""The one reader of delimited text: a CSV header row naming the columns, then rows of numbers.

Rules (the same for ``ebb simulate``'s input file and every CSV experiment file): leading blank lines and ``#``
comment lines are skipped; the first other line is the header; the delimiter is the first of ``,`` ``;`` tab
found in it; column names are stripped of blanks and double quotes and must be unique; every data row has one
field per column (a trailing separator is tolerated). Numbers are parsed by :func:`parse_block` — the fast path
is :func:`numpy.loadtxt` (a C parser: ~60 ms for the 63,041-row LabVIEW record); only when it fails is the
block scanned line by line in Python, to say *which* line, column and field is wrong.
"""
from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataError
from .textio import printable, quote, read_text

__all__ = ["CsvTable", "parse_block", "read_csv_table"]


@dataclass(frozen=True, eq=False)
class CsvTable:
    """A CSV file as read: the header's column names and the numbers below it.

    Parameters
    ----------
    source
        The file (for messages).
    names
        Column names in file order.
    data
        Shape (n_rows, len(names)), float; non-finite values are kept (the caller decides).
    block
        The text of the data rows (e.g. to judge the printed precision of a column).
    delimiter
        The field separator found in the header.
    first_line
        Line number (1-based) of ``block``'s first line in the file.
    """

    source: str
    names: tuple[str, ...]
    data: np.ndarray
    block: str
    delimiter: str
    first_line: int


def read_csv_table(path: str | Path, *, what: str = "CSV file") -> CsvTable:
    """Read a CSV file by the rules of this module.

    Parameters
    ----------
    path
        The file (UTF-8, BOM tolerated; Latin-1 as a fallback; binary data refused).
    what
        What the file is called in the message for a binary or unreadable file.

    Raises
    ------
    DataError
        Unreadable or binary file, no header row, duplicate column names, no data rows, ragged rows,
        non-numeric fields -- naming file, line, sample and column.
    """
    p = Path(path)
    text = read_text(p, DataError, what=what, latin1_fallback=True)
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
    data = parse_block(block, delimiter=delimiter, names=names, source=str(p), first_line=lineno + 1)
    return CsvTable(str(p), names, data, block, delimiter, lineno + 1)


def _locate_problem(block: str, delimiter: str, names: tuple[str, ...], first_line: int,
                    usecols: int) -> str | None:
    """Describe the first malformed line of ``block`` (slow path, errors only)."""
    sample = 0
    lines = block.splitlines()
    last = max((i for i, ln in enumerate(lines) if ln.strip()), default=-1)
    for offset, line in enumerate(lines):
        if not line.strip():
            continue
        fields = line.split(delimiter)
        while len(fields) > usecols and not fields[-1].strip():
            fields.pop()                      # tolerated trailing separator
        lineno = first_line + offset
        if len(fields) < usecols or (len(fields) > usecols and usecols == len(names)):
            return (f"line {lineno} (sample {sample}): {len(fields)} fields, expected {usecols} "
                    f"({printable(', '.join(names[:usecols]))}) -- mismatched lengths"
                    + ("; it is the last line: the file is truncated" if offset == last and sample > 0 else ""))
        for j in range(usecols):
            f = fields[j].strip()
            try:
                float(f)
            except ValueError:
                what = "empty field" if not f else f"not a number ({quote(fields[j])})"
                return f"line {lineno} (sample {sample}), column {names[j]!r}: {what}"
        sample += 1
    return None


def parse_block(block: str, *, delimiter: str, names: tuple[str, ...], source: str, first_line: int,
                usecols: int | None = None) -> np.ndarray:
    """Parse ``block`` (rows of ``delimiter``-separated numbers) into an (n, k) float array.

    Parameters
    ----------
    block
        The data lines (no header).
    delimiter
        Field separator.
    names
        Column names, for messages.
    source
        The file, for messages.
    first_line
        Line number (1-based) of the block's first line in the file.
    usecols
        Number of leading numeric columns to read (the rest, e.g. a LabVIEW
        comment column, is ignored); default ``len(names)``.

    Raises
    ------
    DataError
        No data rows; a row with a different number of fields; a field that is
        not a number -- naming file, line, sample and column.
    """
    k = len(names) if usecols is None else usecols
    cols = None if usecols is None else range(usecols)
    if not block.strip():     # numpy would warn about its StringIO ("input contained no data: <_io…>")
        raise DataError(f"{source}: no data rows")
    try:
        arr = np.loadtxt(io.StringIO(block), delimiter=delimiter, dtype=float, ndmin=2, usecols=cols,
                         comments=None)
    except ValueError:
        where = _locate_problem(block, delimiter, names, first_line, k)
        raise DataError(f"{source}, {where}" if where else f"{source}: cannot parse the numbers") from None
    if arr.shape[0] == 0:
        raise DataError(f"{source}: no data rows")
    if arr.shape[1] != k:
        where = _locate_problem(block, delimiter, names, first_line, k)
        raise DataError(f"{source}, {where}" if where else
                        f"{source}: data rows have {arr.shape[1]} fields, the header names {k} "
                        f"({', '.join(names)})")
    return arr
