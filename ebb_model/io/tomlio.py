"""Writing configs as TOML (the standard library reads TOML but does not write it).

Only what :meth:`ebb_model.config.BeamConfig.to_dict` produces is needed: tables of scalars, inline tables
(parameters), arrays of numbers and strings, and arrays of tables (actuators, sensors, masses); floats are
written with ``repr`` (round-trip exact) and infinities as ``inf``.
"""
from __future__ import annotations

import math
from typing import Any, Mapping

__all__ = ["dumps"]


def _scalar(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_scalar(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_key(k)} = {_scalar(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def _key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else _scalar(str(k))


def _is_table_array(v: Any) -> bool:
    return isinstance(v, (list, tuple)) and bool(v) and all(isinstance(x, Mapping) for x in v)


def _table(lines: list[str], path: str, table: Mapping[str, Any]) -> None:
    scalars = {k: v for k, v in table.items() if not isinstance(v, Mapping) and not _is_table_array(v)}
    for k, v in scalars.items():
        lines.append(f"{_key(k)} = {_scalar(v)}")
    for k, v in table.items():
        if k in scalars:
            continue
        sub = f"{path}.{_key(k)}" if path else _key(k)
        if isinstance(v, Mapping):
            if v and all(isinstance(x, Mapping) and not any(isinstance(y, Mapping) for y in x.values())
                         for x in v.values()):
                lines += ["", f"[{sub}]"] + [f"{_key(n)} = {_scalar(x)}" for n, x in v.items()]
            else:
                lines += ["", f"[{sub}]"]
                _table(lines, sub, v)
        else:
            for item in v:
                lines += ["", f"[[{sub}]]"]
                _table(lines, sub, item)


def dumps(data: Mapping[str, Any]) -> str:
    """``data`` as TOML text (see the module docstring for what is supported)."""
    lines: list[str] = []
    _table(lines, "", data)
    return "\n".join(lines).lstrip("\n") + "\n"
