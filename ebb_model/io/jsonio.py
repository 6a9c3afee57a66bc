"""JSON output shared by the CLI and the result writers: strict JSON (no NaN/inf), written atomically."""
from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .output import atomic_path

__all__ = ["jsonable", "write_json"]


def jsonable(v: Any) -> Any:
    """Recursively convert to strict-JSON values.

    The one converter of the project: NaN → ``null``, ±inf → ``"inf"``/``"-inf"`` (``float()`` reads them back),
    NumPy scalars and arrays → Python numbers and lists, dataclass instances and mappings → dicts, tuples →
    lists.

    Parameters
    ----------
    v : Any
        Value to convert.

    Returns
    -------
    Any
        A value :func:`json.dumps` accepts with ``allow_nan=False``.
    """
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return {f.name: jsonable(getattr(v, f.name)) for f in dataclasses.fields(v)}
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, float):
        if math.isnan(v):
            return None
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return v
    if isinstance(v, Mapping):
        return {k: jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    return v


def write_json(path: str | Path, obj: Any) -> Path:
    """Write ``obj`` as indented strict JSON to ``path`` via a temporary file and rename."""
    path = Path(path)
    text = json.dumps(jsonable(obj), indent=2, allow_nan=False)
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path
