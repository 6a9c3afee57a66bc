"""Candidates ordered by a value, exact ties by a rule (:func:`tie_ordered`).

Two candidates can be one model: a gain on the only force and a gain on the only sensor, a lag on either side of a
single input–output path.  Their refits then differ by the rounding of two simulations (measured 1.4e-11 relative
for the two lags of ``tests/test_evidence.py``'s record), and sorting them by that difference orders them by
round-off — another machine, another BLAS, another order, another effect named first.  Values within
:data:`TIE_RTOL` of each other are one value here, and the tie is ordered by label.
"""
from __future__ import annotations

from typing import Callable, Iterable

__all__ = ["tie_ordered", "TIE_RTOL"]

#: Relative difference below which two candidates' values are a tie: above the rounding of two equivalent refits
#: (1.4e-11), far below what a record can tell (a held-out error's scatter is about 1/sqrt(n) of it, 1e-2).
TIE_RTOL = 1e-9


def tie_ordered(labels: Iterable[str], value: Callable[[str], float], rtol: float = TIE_RTOL) -> list[str]:
    """``labels`` by ``value``, ascending; a run of values each within ``rtol`` (relative) of the run's first is a
    tie, ordered by label."""
    out: list[str] = []
    group: list[str] = []
    for lab in sorted(labels, key=value):
        if group:
            first, v = value(group[0]), value(lab)
            if abs(v - first) > rtol * max(abs(first), abs(v), 1e-300):
                out += sorted(group)
                group = []
        group.append(lab)
    return out + sorted(group)
