"""Where the diagnosis' independent fits run: worker processes, a Dask cluster, or this one.

Every fit is deterministic and each process (or Dask worker) runs it with one BLAS thread, so a result does not
depend on where it ran — only the wall time does.
"""
from __future__ import annotations

import multiprocessing
import signal
from concurrent.futures import Executor, ProcessPoolExecutor
from typing import Any, Callable, Sequence

from ebb_model.threads import single_blas_thread

__all__ = ["DaskExecutor", "refit_pool", "side_by_side"]


def _refit_worker() -> None:
    """Worker initialiser: one BLAS thread per process (the refits are the parallelism; more threads only
    oversubscribe the cores), and Ctrl-C is the main process's to handle."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    single_blas_thread()


def _in_one_blas_thread(task: Callable[..., Any], *args: Any) -> Any:
    """``task(*args)`` with one BLAS thread (on a Dask worker, which has no initialiser of ours)."""
    single_blas_thread()
    return task(*args)


class DaskExecutor(Executor):
    """The refits' executor on a Dask cluster: a scheduler address, ``"local:K"`` (a local cluster of ``K``
    single-threaded worker processes, started here and closed with the executor —
    :func:`identification.cluster.local_cluster`) or a connected ``distributed.Client`` (left open).

    Raises
    ------
    ConfigError
        A malformed ``local:K`` address.
    """

    def __init__(self, address: Any):
        from identification.cluster import connect

        self.client, self._cluster, self._own = connect(address)

    @property
    def workers(self) -> int:
        """Workers of the cluster (at least 1)."""
        return max(1, len(self.client.scheduler_info().get("workers", {})))

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Any:
        """A Dask future of ``fn(*args)`` run with one BLAS thread (``.result()`` as a concurrent one)."""
        if kwargs:
            raise TypeError("DaskExecutor.submit takes positional arguments only")
        return self.client.submit(_in_one_blas_thread, fn, *args, pure=False)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Close the client and the local cluster this executor started (a given client is left open)."""
        from identification.cluster import disconnect

        disconnect(self.client, self._cluster, self._own)


def refit_pool(workers: int, dask: Any = None) -> Executor | None:
    """The refits' executor: ``dask`` (a :class:`DaskExecutor` address or client) when given, else ``workers``
    local processes (``spawn``: no inherited locks or threads); ``None`` for one worker and no Dask."""
    if dask is not None:
        return DaskExecutor(dask)
    if workers <= 1:
        return None
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                               initializer=_refit_worker)


def side_by_side(executor: Executor | None, task: Callable[..., Any], args: Sequence[tuple]) -> list[Any]:
    """``[task(*a) for a in args]``, on the executor's processes when given and there are two or more."""
    if executor is None or len(args) < 2:
        return [task(*a) for a in args]
    return [f.result() for f in [executor.submit(task, *a) for a in args]]
