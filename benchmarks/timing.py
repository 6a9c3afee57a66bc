"""Timing helper shared by the benchmark scripts (run as ``python benchmarks/<script>.py``)."""
from __future__ import annotations

import statistics
import time
from typing import Callable, Mapping

__all__ = ["median_time", "interleaved_medians"]


def median_time(fn: Callable[[], object], repeats: int) -> float:
    """Median wall time [s] of ``repeats`` calls of ``fn``."""
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def interleaved_medians(fns: Mapping[str, Callable[[], object]], repeats: int, *, run: int = 5
                        ) -> dict[str, float]:
    """Median wall time [s] of ``repeats`` calls of each callable, taken in turns of ``run`` calls each: a machine
    whose speed drifts during the measurement (another tenant, the clock) moves every median alike, so their
    ratios hold, while each callable still runs warm (its first call in a turn, after the others have run, is the
    only cold one)."""
    ts: dict[str, list[float]] = {name: [] for name in fns}
    while any(len(t) < repeats for t in ts.values()):
        for name, fn in fns.items():
            for _ in range(min(run, repeats - len(ts[name]))):
                t0 = time.perf_counter()
                fn()
                ts[name].append(time.perf_counter() - t0)
    return {name: statistics.median(t) for name, t in ts.items()}
