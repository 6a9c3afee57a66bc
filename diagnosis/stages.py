"""Where a diagnosis spends its time: wall seconds per stage, each second counted once.

Stages nest (the ranking holds the refits, the modal pattern, the pairs …); a stage's own time excludes the stages
inside it, so the shares add up to the whole.  ``gap.json`` carries them (``stage_seconds``) and
``benchmarks/bench_diagnosis.py`` reports their shares over the blind family.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Callable, Iterator

__all__ = ["StageClock"]


class StageClock:
    """Exclusive wall time per named stage (``now``: the clock, seconds).

    Examples
    --------
    >>> clock = StageClock()
    >>> with clock.stage("ranking"):
    ...     with clock.stage("local refits"):
    ...         pass
    >>> sorted(clock.seconds)
    ['local refits', 'ranking']
    """

    def __init__(self, now: Callable[[], float] = time.perf_counter) -> None:
        self.seconds: dict[str, float] = {}
        self._now = now
        self._open: list[str] = []
        self._since = now()

    def _charge(self) -> None:
        now = self._now()
        if self._open:
            name = self._open[-1]
            self.seconds[name] = self.seconds.get(name, 0.0) + now - self._since
        self._since = now

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the block as stage ``name`` (the enclosing stage pauses meanwhile)."""
        self._charge()
        self._open.append(name)
        try:
            yield
        finally:
            self._charge()
            self._open.pop()
