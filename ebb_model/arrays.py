"""The one normaliser of 2-D arrays: signals of shape (n_samples, n_channels) and system matrices.

Every array handed to the package by a caller (input forces, measured outputs, predictions, the matrices of a
state-space system) passes through :func:`as_matrix`, which converts it to float, turns a vector into one
column where a single column is expected, checks the shape and finiteness, and raises one typed error naming
the array and what is wrong ("inputs has shape (10, 2), expected (10, 1)").
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .errors import DataError

__all__ = ["as_matrix"]


def as_matrix(value: object, name: str, *, shape: tuple[int | None, int | None] = (None, None),
              columns: Sequence[str] | None = None, vector: bool = True, finite: bool = True,
              min_rows: int = 0, readonly: bool = False, error: type[Exception] = DataError,
              row: str = "sample", column: str = "column") -> np.ndarray:
    """Float 2-D array of ``value`` with the expected shape.

    Parameters
    ----------
    value : array_like
        The array; a 1-D array is read as one column when ``vector`` is true and one column (or any number,
        ``shape[1] is None``) is expected.
    name : str
        How the array is called in error messages (e.g. ``"inputs"``, ``"rec.csv: outputs"``, ``"B"``).
    shape : tuple of (int or None), optional
        Expected ``(rows, columns)``; ``None`` accepts any count (at least one column).
    columns : sequence of str, optional
        Names of the expected columns; error messages then name the column instead of its index.
    vector : bool, optional
        Accept a 1-D array as one column (default); ``False`` requires a 2-D array.
    finite : bool, optional
        Reject NaN and ±inf (default), naming the first offending row and column.
    min_rows : int, optional
        Least number of rows.
    readonly : bool, optional
        Return a read-only copy (for immutable value objects); otherwise a C-contiguous array, copied only
        when needed.
    error : type of Exception, optional
        Exception raised on a problem (default :class:`~ebb_model.errors.DataError`).
    row, column : str, optional
        What a row and a column are called in messages (``"sample"``/``"column"``; ``"row"`` for a matrix,
        ``"actuator"`` for forces).

    Returns
    -------
    numpy.ndarray
        The float64 array of shape ``shape`` (``None`` entries filled in).

    Raises
    ------
    Exception
        ``error`` with one line naming ``name`` and the problem: not numeric, wrong shape, too few rows,
        a non-finite value.
    """
    try:
        a = np.array(value, dtype=float, copy=True) if readonly else np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise error(f"{name} is not a numeric array") from None
    if vector and a.ndim == 1 and shape[1] in (None, 1):
        a = a.reshape(-1, 1)
    want = f" for {column}s {', '.join(columns)}" if columns else ""
    if a.ndim != 2:
        exp = tuple(f"n_{lab}s" if s is None else s for s, lab in zip(shape, (row, column)))
        raise error(f"{name} has shape {a.shape}, expected ({exp[0]}, {exp[1]}){want}")
    exp = tuple(a.shape[i] if s is None else s for i, s in enumerate(shape))
    if a.shape != exp or a.shape[1] == 0:
        raise error(f"{name} has shape {a.shape}, expected {exp}{want}")
    if a.shape[0] < min_rows:
        raise error(f"{name} must contain at least {min_rows} {row}s, got {a.shape[0]}")
    if finite and not np.isfinite(a).all():   # (the check alone; locating the first bad entry costs 10x more)
        i, j = np.argwhere(~np.isfinite(a))[0]
        where = repr(columns[j]) if columns else str(j)
        raise error(f"{name} contains a non-finite value at {row} {i}, {column} {where}")
    if readonly:
        a.setflags(write=False)
        return a
    return np.ascontiguousarray(a)
