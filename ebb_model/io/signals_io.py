"""Signals in CSV files: reading inputs (a ``time`` column plus named columns), simulating a config on them
(:func:`simulate_files`, what ``ebb simulate`` does)."""
from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .csvio import read_csv_table
from ..errors import DataError
from .textio import printable, quote

__all__ = ["read_signal_csv", "check_time_vector", "simulate_files"]


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

    The file follows the rules of :func:`ebb_model.io.csvio.read_csv_table` (the same as every CSV
    experiment file).

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
    table = read_csv_table(path, what="CSV file")
    missing = [c for c in ("time", *columns) if c not in table.names]
    if missing:
        raise DataError(f"{table.source}: missing column(s) {', '.join(missing)}; "
                        f"found {printable(', '.join(table.names))}")
    arr = table.data[:, [table.names.index(c) for c in ("time", *columns)]]
    bad = np.argwhere(~np.isfinite(arr[:, 1:]))
    if bad.size:
        k, j = bad[0]
        raise DataError(f"{table.source}, column {quote(columns[j])}: non-finite value {float(arr[k, j + 1])!r} "
                        f"at sample {k}")
    t = np.ascontiguousarray(arr[:, 0])
    check_time_vector(t, dt, where=f"{table.source}: time")
    return t, np.ascontiguousarray(arr[:, 1:])


def simulate_files(config_path: str | Path, input_csv: str | Path, out_csv: str | Path, *,
                   params: Mapping[str, float] | None = None) -> Path:
    """Read inputs from CSV, simulate on the fast path, write outputs to CSV (atomically).

    Parameters
    ----------
    config_path : str or Path
        TOML config file.
    input_csv : str or Path
        CSV with a ``time`` column sampled at the config's ``dt`` and one column per actuator
        (:func:`read_signal_csv`).
    out_csv : str or Path
        CSV to write: ``time`` and one column per sensor.
    params : mapping, optional
        Parameter values instead of the config's nominal ones.

    Returns
    -------
    Path
        ``out_csv``.

    Raises
    ------
    ConfigError, ParameterError, StabilityError, DataError
        Nothing is written when anything fails.
    OutputError
        ``out_csv`` cannot be written (checked first, :func:`ebb_model.io.output.check_output_file`), or writing it
        failed (nothing half-written is left).
    """
    from ..assemble import check_stable
    from ..config import load_config
    from ..parameter_values import resolve_parameters
    from ..simulate import fast_model, simulate

    from .output import check_output_file

    out = check_output_file(out_csv, name="out_csv", inputs=(config_path, input_csv))
    cfg = load_config(config_path)
    t, u = read_signal_csv(input_csv, cfg.input_names, dt=cfg.time.dt)
    p = resolve_parameters(cfg, params)
    model = fast_model(cfg, p)
    check_stable(cfg, p, model.spectral_radius())
    res = simulate(model, u)
    res.to_csv(out, time=t)
    return out
