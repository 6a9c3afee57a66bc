"""One BLAS thread for the model's small dense algebra.

The model's matrices are small (tens to a few hundred unknowns): BLAS threads
only add start-up and spin-wait overhead, and on a machine whose cores are busy
(parallel candidates, worker processes, another job) OpenBLAS's spinning
threads slow an evaluation down by one to two orders of magnitude (a 60-node
evaluation of 4 ms took 0.1–2.5 s beside a busy core).  The parallelism is over
candidates, never inside one.  (``threadpoolctl`` is imported when used: the FMU's model core does not need
it.)
"""
from __future__ import annotations

import functools
from typing import Any, Callable, TypeVar

__all__ = ["single_blas_thread", "one_blas_thread"]

F = TypeVar("F", bound=Callable)


def single_blas_thread() -> Any:
    """Context manager (and, called at process start, a lasting limit): one BLAS thread.

    A limit reaches only the BLAS libraries already loaded, and numpy and scipy each load their own OpenBLAS:
    both are loaded first.  (Measured: a spawned diagnosis worker limited before scipy was imported ran scipy's
    OpenBLAS with two threads beside the other worker — its ``eigh`` 20 ms a call against 0.7 ms in one process,
    a point mass's modal pattern fit 21 s against 3 s.)
    """
    import numpy  # noqa: F401 - loads numpy's OpenBLAS
    import scipy.linalg  # noqa: F401 - loads scipy's own
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def one_blas_thread(func: F) -> F:
    """Decorator: ``func`` runs with one BLAS thread (restored afterwards)."""
    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with single_blas_thread():
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
