"""One BLAS thread for the model's small dense algebra.

The model's matrices are small (tens to a few hundred unknowns): BLAS threads
only add start-up and spin-wait overhead, and on a machine whose cores are busy
(parallel candidates, worker processes, another job) OpenBLAS's spinning
threads slow an evaluation down by one to two orders of magnitude (a 60-node
evaluation of 4 ms took 0.1–2.5 s beside a busy core).  The parallelism is over
candidates, never inside one.
"""
from __future__ import annotations

from typing import Callable, TypeVar

from threadpoolctl import threadpool_limits

__all__ = ["single_blas_thread", "one_blas_thread"]

F = TypeVar("F", bound=Callable)


def single_blas_thread() -> threadpool_limits:
    """Context manager (and, called at process start, a lasting limit): one BLAS thread."""
    return threadpool_limits(limits=1, user_api="blas")


def one_blas_thread(func: F) -> F:
    """Decorator: ``func`` runs with one BLAS thread (restored afterwards)."""
    return threadpool_limits.wrap(limits=1, user_api="blas")(func)
