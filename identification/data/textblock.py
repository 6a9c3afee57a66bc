"""Fast parsing of a delimited block of numbers, with a precise error when it fails.

The fast path is :func:`numpy.loadtxt` (a C parser: ~60 ms for the 63,041-row
LabVIEW record).  Only when it fails is the block scanned line by line in
Python, to say *which* line, column and field is wrong.
"""
from __future__ import annotations

import io

import numpy as np

from ebb_model.errors import DataError
from ebb_model.textio import printable, quote

from .table import printed_resolution

__all__ = ["parse_block", "edge_lines", "column_resolutions"]


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


def edge_lines(block: str, count: int = 5) -> list[str]:
    """The first and last ``count`` non-empty lines of ``block`` (without splitting all of it)."""
    head = [ln for ln in block[: 4096].splitlines()[:count + 2] if ln.strip()][:count]
    tail = [ln for ln in block[-4096:].splitlines()[-(count + 2):] if ln.strip()][-count:]
    return head + tail


def column_resolutions(lines: list[str], delimiter: str, k: int) -> tuple[float, ...]:
    """Printed quantum of each of the first ``k`` columns, from a few sample lines."""
    cols: list[list[str]] = [[] for _ in range(k)]
    for ln in lines:
        fields = ln.split(delimiter)
        for j in range(min(k, len(fields))):
            cols[j].append(fields[j])
    return tuple(printed_resolution(c) for c in cols)
