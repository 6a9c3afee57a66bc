"""NumPy ``.npz`` and MATLAB ``.mat`` experiment files: one named vector per signal plus ``time``.

* NPZ: arrays ``time`` and one per signal, as written by
  :meth:`~identification.data.Experiment.to_npz` (whose JSON entry
  ``__experiment__`` also declares the units).  Read without pickling.
* MAT (level 5 / v7, via :func:`scipy.io.loadmat`): numeric variables, each a
  vector (n,), (n, 1) or (1, n).  MATLAB v7.3 files are HDF5 and not read;
  save with ``save(..., '-v7')``.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import scipy.io

from ebb_model.errors import DataError
from ebb_model.io.textio import printable

from .experiment import NPZ_META_KEY
from .table import RawTable

__all__ = ["read_npz", "read_mat"]


def _table(src: str, kind: str, arrays: dict[str, np.ndarray], units: dict[str, str]) -> RawTable:
    names = tuple(arrays)
    return RawTable(source=src, kind=kind, names=names, columns=tuple(arrays[n] for n in names),
                    units=tuple(units.get(n) for n in names), resolution=(0.0,) * len(names), time_key="time")


def _reason(exc: BaseException) -> str:
    """A third-party parser's complaint, fit for a one-line message."""
    return f"{type(exc).__name__}: {printable(str(exc), 160)}"


def read_npz(path: str | Path) -> RawTable:
    """Read an ``.npz`` archive (no pickled objects) into a RawTable.

    Raises
    ------
    DataError
        Unreadable archive, object arrays, malformed ``__experiment__`` entry.
    """
    p = Path(path)
    try:
        with np.load(p, allow_pickle=False) as z:
            arrays = {k: np.asarray(z[k]) for k in z.files}
    except FileNotFoundError as exc:
        raise DataError(f"{p}: cannot read ({exc.strerror or exc})") from None
    except Exception as exc:  # noqa: BLE001 - numpy/zipfile on a damaged archive: EOFError, BadZipFile, zlib...
        raise DataError(f"{p}: not a readable .npz archive ({_reason(exc)})") from None
    units: dict[str, str] = {}
    meta = arrays.pop(NPZ_META_KEY, None)
    if meta is not None:
        try:
            info = json.loads(str(meta))
            units = {str(k): str(v) for k, v in dict(info.get("units", {})).items()}
        except (ValueError, TypeError, AttributeError):
            raise DataError(f"{p}: entry {NPZ_META_KEY!r} is not the JSON written by Experiment.to_npz") from None
    return _table(str(p), "array", arrays, units)


def read_mat(path: str | Path) -> RawTable:
    """Read a MATLAB ``.mat`` file (v4 to v7) into a RawTable of its numeric variables.

    Raises
    ------
    DataError
        Unreadable file, v7.3 (HDF5) file.
    """
    p = Path(path)
    try:
        raw = scipy.io.loadmat(p, squeeze_me=False, struct_as_record=True)
    except NotImplementedError:
        raise DataError(f"{p}: MATLAB v7.3 (HDF5) files are not supported; save with save(..., '-v7')") from None
    except FileNotFoundError as exc:
        raise DataError(f"{p}: cannot read ({exc.strerror or exc})") from None
    except Exception as exc:  # noqa: BLE001 - scipy.io on a damaged file: MatReadError, ValueError, zlib...
        raise DataError(f"{p}: not a readable MATLAB file ({_reason(exc)})") from None
    arrays = {k: np.asarray(v) for k, v in raw.items() if not k.startswith("__")}
    return _table(str(p), "variable", arrays, {})
