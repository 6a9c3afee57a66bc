"""The printed precision of the columns of a delimited block of numbers.

The numbers themselves are parsed by :func:`ebb_model.io.csvio.parse_block`, the one parser of delimited text.
"""
from __future__ import annotations

from .table import printed_resolution

__all__ = ["edge_lines", "column_resolutions"]


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
