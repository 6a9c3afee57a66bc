"""Validation problems collected so that all are reported at once, each naming its field."""
from __future__ import annotations

import math
from typing import Any, Mapping

__all__ = ["Problems"]


class Problems:
    """Collects validation problems so that all are reported at once."""

    def __init__(self) -> None:
        self.items: list[str] = []

    def add(self, where: str, msg: str) -> None:
        self.items.append(f"{where}: {msg}")

    def number(self, where: str, v: Any, *, allow_inf: bool = False) -> float | None:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            if allow_inf and isinstance(v, str) and v.strip().lower() in ("inf", "+inf", "infinity"):
                return math.inf
            self.add(where, f"must be a number, got {v!r}")
            return None
        f = float(v)
        if math.isnan(f) or (math.isinf(f) and not allow_inf):
            self.add(where, f"must be a finite number, got {v!r}")
            return None
        return f

    def unknown_keys(self, where: str, d: Mapping[str, Any], allowed: tuple[str, ...]) -> None:
        for k in d:
            if k not in allowed:
                self.add(f"{where}.{k}" if where else k, f"unknown key; allowed: {', '.join(allowed)}")
