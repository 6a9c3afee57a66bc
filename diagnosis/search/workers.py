"""Where the diagnosis' independent fits run: worker processes, a Dask cluster, or this one.

Every fit is deterministic and each process (or Dask worker) runs it with one BLAS thread, so a result does not
depend on where it ran — only the wall time does.

A diagnosis can itself be a task on the cluster (a batch of records, :mod:`diagnosis.batch`): its fits are then
tasks of the same cluster (:func:`task_cluster`), submitted ahead of the records still queued, and while
the record's task waits for them it gives its worker's thread back (``distributed.secede``/``rejoin``), so the
other records and fits keep every worker busy — the records' uneven lengths no longer leave a worker idle while
the last one finishes.
"""
from __future__ import annotations

import signal
from concurrent.futures import Executor, ProcessPoolExecutor
from typing import Any, Callable, Iterable, Sequence

from ebb_model.processes import process_pool, stop_now
from ebb_model.threads import single_blas_thread

__all__ = ["DaskExecutor", "close_refit_pool", "refit_pool", "side_by_side", "task_cluster"]


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
        from identification.cluster import WorkerWatch, connect, disconnect, scheduler_address

        self.client, self._cluster, self._own = connect(address)
        self._address = scheduler_address(self.client)
        self._nested = _on_dask_worker()
        try:
            self._watch = WorkerWatch(self.client)
        except BaseException:
            disconnect(self.client, self._cluster, self._own)
            raise

    @property
    def workers(self) -> int:
        """Workers of the cluster (at least 1)."""
        return max(1, len(self.client.scheduler_info().get("workers", {})))

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Any:
        """A Dask future of ``fn(*args)`` run with one BLAS thread (``.result()`` as a concurrent one)."""
        if kwargs:
            raise TypeError("DaskExecutor.submit takes positional arguments only")
        # a task's own fits go ahead of the tasks still queued (Dask runs higher priorities first): the task
        # waiting for them holds its record's results back
        future = self.client.submit(_in_one_blas_thread, fn, *args, pure=False, priority=1 if self._nested else 0)
        return _Awaited(future, self.client, self._address, self._nested)

    def results(self, futures: Iterable[Any]) -> list[Any]:
        """The results of futures this executor submitted, in order (waiting once, outside the worker's thread
        pool when this is a task)."""
        from identification.cluster import raise_if_scheduler_lost

        futures = list(futures)
        try:
            if not self._nested:
                out = [f.result() for f in futures]
            else:
                out = _outside_pool(lambda: self.client.gather([f.future for f in futures]))
            self._watch.check()
        except Exception as exc:
            raise_if_scheduler_lost(self.client, exc, self._address)  # the scheduler gone: one line
            raise
        return out

    def events(self) -> tuple[str, ...]:
        """A worker lost while this executor ran fits, said (:class:`identification.cluster.WorkerWatch`)."""
        return self._watch.events()

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Close the client and the local cluster this executor started (a given client is left open)."""
        from identification.cluster import disconnect

        disconnect(self.client, self._cluster, self._own)


def task_cluster() -> Any:
    """The Dask client of the cluster this code runs on as a task (hand it to :class:`DaskExecutor`: the fits
    become tasks of the same cluster), or ``None`` when it is not a Dask task."""
    if not _on_dask_worker():
        return None
    from distributed import get_client

    return get_client()


def _on_dask_worker() -> bool:
    """Whether this code runs as a task of a Dask worker."""
    try:
        from distributed import get_worker

        get_worker()
    except (ImportError, ValueError):
        return False
    return True


def _outside_pool(wait: Callable[[], Any]) -> Any:
    """``wait()`` with this task's thread out of its worker's pool (the worker runs other tasks meanwhile); the
    thread rejoins the pool before returning (``rejoin`` waits for a free slot: the worker's thread count holds)."""
    from distributed import rejoin, secede

    secede()
    try:
        return wait()
    finally:
        rejoin()


class _Awaited:
    """A Dask future of :class:`DaskExecutor`: ``result()`` waits — outside the worker's thread pool when the
    future was submitted by a task (``nested``) — and a lost scheduler is one line
    (:func:`identification.cluster.raise_if_scheduler_lost`), not Dask's cancellation."""

    def __init__(self, future: Any, client: Any, address: str, nested: bool):
        self.future, self._client, self._address, self._nested = future, client, address, nested

    def result(self) -> Any:
        """The task's result (its exception raised)."""
        from identification.cluster import raise_if_scheduler_lost

        try:
            if not self._nested or self.future.done():
                return self.future.result()
            return _outside_pool(self.future.result)
        except Exception as exc:
            raise_if_scheduler_lost(self._client, exc, self._address)
            raise


def refit_pool(workers: int, dask: Any = None) -> Executor | None:
    """The refits' executor: ``dask`` (a :class:`DaskExecutor` address or client) when given, else ``workers``
    local processes (``spawn``: no inherited locks or threads; safe from a script's top level,
    :mod:`ebb_model.processes`); ``None`` for one worker and no Dask."""
    if dask is not None:
        return DaskExecutor(dask)
    if workers <= 1:
        return None
    return process_pool(workers, _refit_worker)


def close_refit_pool(executor: Executor, *, now: bool) -> None:
    """Close the refits' executor: after the fits in flight, or — ``now``: an interrupted or failed run —
    without waiting for them (queued fits cancelled, local worker processes terminated, so that Ctrl-C ends every
    worker within seconds, not after the longest fit; a Dask cluster cancels the tasks of a closed client)."""
    if now and isinstance(executor, ProcessPoolExecutor):
        stop_now(executor)
    else:
        executor.shutdown(cancel_futures=True)


def side_by_side(executor: Executor | None, task: Callable[..., Any], args: Sequence[tuple]) -> list[Any]:
    """``[task(*a) for a in args]``, on the executor's processes when given and there are two or more."""
    if executor is None or len(args) < 2:
        return [task(*a) for a in args]
    futures = [executor.submit(task, *a) for a in args]
    if isinstance(executor, DaskExecutor):
        return executor.results(futures)
    return [f.result() for f in futures]
