"""Reading input signals from CSV files (a ``time`` column plus named columns)."""
from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Sequence

import numpy as np

from .errors import DataError
from .textio import printable, quote, read_text

__all__ = ["read_signal_csv", "check_time_vector"]


def check_time_vector(t: np.ndarray, dt: float | None = None, *, where: str = "time",
                      rtol: float = 1e-6) -> None:
    """Check that ``t`` is finite, strictly increasing and (optionally) uniformly sampled at ``dt``.

    Raises
    ------
    DataError
        Naming the first offending sample.
    """
    if t.ndim != 1 or t.size == 0:
        raise DataError(f"{where}: must be a non-empty 1-D vector")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise DataError(f"{where}: non-finite value at sample {bad[0]}")
    if t.size > 1:
        steps = np.diff(t)
        nonmono = np.flatnonzero(steps <= 0)
        if nonmono.size:
            i = nonmono[0]
            raise DataError(f"{where}: not strictly increasing at sample {i + 1} "
                            f"({float(t[i]):.9g} s -> {float(t[i + 1]):.9g} s)")
        if dt is not None:
            off = np.flatnonzero(np.abs(steps - dt) > rtol * dt)
            if off.size:
                i = off[0]
                raise DataError(f"{where}: sample time {steps[i]:.9g} s at sample {i + 1} is "
                                f"inconsistent with the config's dt = {dt:g} s")


def read_signal_csv(path: str | Path, columns: Sequence[str], *, dt: float | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Read ``time`` and the named columns from a CSV file with a header row.

    Parameters
    ----------
    path
        CSV file; the header must contain ``time`` and every name in ``columns``
        (extra columns are ignored).
    columns
        Column names to return, in this order.
    dt
        If given, the time vector must be uniformly sampled at ``dt``.

    Returns
    -------
    time : numpy.ndarray
        Shape (n,).
    values : numpy.ndarray
        Shape (n, len(columns)).

    Raises
    ------
    DataError
        Unreadable file, missing columns, non-numeric or non-finite values,
        non-monotonic time or inconsistent sample time.
    """
    p = Path(path)
    reader = csv.reader(read_text(p, DataError, what="CSV file").splitlines())
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise DataError(f"{p}: empty file") from None
    except csv.Error as exc:
        raise DataError(f"{p}, line 1: not a CSV header ({exc})") from None
    missing = [c for c in ("time", *columns) if c not in header]
    if missing:
        raise DataError(f"{p}: missing column(s) {', '.join(missing)}; found {printable(', '.join(header))}")
    idx = [header.index(c) for c in ("time", *columns)]
    rows: list[list[float]] = []
    try:
        for lineno, row in enumerate(reader, start=2):
            if not row or all(not c.strip() for c in row):
                continue
            if len(row) != len(header):
                raise DataError(f"{p}, line {lineno}: {len(row)} fields, expected {len(header)}")
            vals = []
            for j in idx:
                try:
                    v = float(row[j])
                except ValueError:
                    raise DataError(f"{p}, line {lineno}, column {quote(header[j])}: not a number "
                                    f"({quote(row[j])})") from None
                if not math.isfinite(v):
                    raise DataError(f"{p}, line {lineno}, column {quote(header[j])}: non-finite value "
                                    f"{quote(row[j])}")
                vals.append(v)
            rows.append(vals)
    except csv.Error as exc:
        raise DataError(f"{p}, line {reader.line_num}: malformed CSV ({exc})") from None
    if not rows:
        raise DataError(f"{p}: no data rows")
    arr = np.asarray(rows)
    t = arr[:, 0]
    check_time_vector(t, dt, where=f"{p}: time")
    return t, arr[:, 1:]
