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
    """Context manager (and, called at process start, a lasting limit): one BLAS thread."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def one_blas_thread(func: F) -> F:
    """Decorator: ``func`` runs with one BLAS thread (restored afterwards)."""
    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with single_blas_thread():
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
