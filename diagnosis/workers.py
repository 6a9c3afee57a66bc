"""Where the diagnosis' independent fits run: worker processes, or this one.

Every fit is deterministic and each process uses one BLAS thread, so a result does not depend on where it
ran — only the wall time does.
"""
from __future__ import annotations

import multiprocessing
import signal
from concurrent.futures import Executor, ProcessPoolExecutor
from typing import Any, Callable, Sequence

from ebb_model.threads import single_blas_thread

__all__ = ["refit_pool", "side_by_side"]


def _refit_worker() -> None:
    """Worker initialiser: one BLAS thread per process (the refits are the parallelism; more threads only
    oversubscribe the cores), and Ctrl-C is the main process's to handle."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    single_blas_thread()


def refit_pool(workers: int) -> ProcessPoolExecutor | None:
    """Worker processes for the refits (``spawn``: no inherited locks or threads); ``None`` for ``workers <= 1``."""
    if workers <= 1:
        return None
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                               initializer=_refit_worker)


def side_by_side(executor: Executor | None, task: Callable[..., Any], args: Sequence[tuple]) -> list[Any]:
    """``[task(*a) for a in args]``, on the executor's processes when given and there are two or more."""
    if executor is None or len(args) < 2:
        return [task(*a) for a in args]
    return [f.result() for f in [executor.submit(task, *a) for a in args]]
