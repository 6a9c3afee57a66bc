"""Parallel evaluation of a population: injected runners (serial, local processes, Dask).

A runner maps ``(evaluator, X)`` to ``F``; the evaluator is a picklable value,
so every backend gets the same work.  Each runner splits the population into
a few chunks per worker (:data:`CHUNKS_PER_WORKER`), handed out as workers
become free.  Per-worker state lives in the worker process, not in
the pickled evaluator: the FMU backend keeps one FMU instance per worker
process for the whole run (see :mod:`identification.fmu_backend`), created at
the worker's first candidate and freed when the worker exits (process pool
shutdown) or, on a Dask cluster that outlives the runner, by
``evaluator.close()`` run on every worker when the runner closes.  Whoever
creates a runner closes it (context manager).
"""
from __future__ import annotations

import signal
from typing import Any, Protocol

import numpy as np

from ebb_model.processes import process_pool, stop_now
from ebb_model.threads import single_blas_thread

__all__ = ["Runner", "SerialRunner", "ProcessRunner", "DaskRunner", "make_runner"]


class Evaluator(Protocol):  # pragma: no cover - typing only
    def evaluate(self, X: np.ndarray) -> np.ndarray: ...


def _evaluate_chunk(evaluator: Evaluator, X: np.ndarray) -> np.ndarray:
    with single_blas_thread():
        return evaluator.evaluate(X)


def _close_evaluator(evaluator: Any) -> None:
    evaluator.close()


class Runner:
    """Base class: ``runner(evaluator, X) -> F``; usable as a context manager."""

    workers: int = 1

    def __call__(self, evaluator: Evaluator, X: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def close(self) -> None:
        """Release workers."""

    def events(self) -> tuple[str, ...]:
        """What happened to the workers during the run worth telling its user (a lost worker), one sentence
        each."""
        return ()

    def __enter__(self) -> "Runner":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


class SerialRunner(Runner):
    """Evaluate in the calling process."""

    def __call__(self, evaluator: Evaluator, X: np.ndarray) -> np.ndarray:
        return _evaluate_chunk(evaluator, X)


#: Chunks per worker and call: small chunks keep workers busy to the end of a generation when one of
#: them is slowed down by other load or gets cheap (refused) candidates; the per-chunk overhead (pickling
#: the evaluator, IPC, the BLAS thread limit: about 1 ms) stays small against one evaluation.
CHUNKS_PER_WORKER = 6


def _chunks(X: np.ndarray, workers: int) -> list[np.ndarray]:
    k = max(1, min(CHUNKS_PER_WORKER * workers, len(X)))
    return [c for c in np.array_split(X, k) if len(c)]


def _ignore_sigint() -> None:
    """Worker initialiser: Ctrl-C reaches the whole process group; only the main process handles it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class ProcessRunner(Runner):
    """Evaluate chunks in ``workers`` local processes (``spawn``: no inherited locks or threads; safe to start
    from a script's top level, :mod:`ebb_model.processes`)."""

    def __init__(self, workers: int):
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.workers = workers
        self._pool = process_pool(workers, _ignore_sigint)

    def __call__(self, evaluator: Evaluator, X: np.ndarray) -> np.ndarray:
        futs = [self._pool.submit(_evaluate_chunk, evaluator, c) for c in _chunks(X, self.workers)]
        return np.vstack([f.result() for f in futs])

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)

    def __exit__(self, exc_type: Any, *exc: Any) -> None:
        if exc_type is None:
            self.close()
        else:       # Ctrl-C or a failure: the chunks in flight are not waited for
            stop_now(self._pool)


#: Times a call sends its evaluator again after its last copy on the cluster was lost with a worker.
_RESENDS = 3


class DaskRunner(Runner):
    """Evaluate chunks on a Dask distributed cluster.

    Parameters
    ----------
    address
        A scheduler address, ``"local:K"`` — a local cluster of ``K``
        single-threaded worker processes with the low-overhead settings of
        :func:`identification.cluster.local_cluster`, started here and closed
        with the runner — or a connected ``distributed.Client`` (left open).
    """

    def __init__(self, address: str | Any):
        from .cluster import WorkerWatch, connect, disconnect, scheduler_address

        self.client, self._cluster, self._own = connect(address)
        self._address = scheduler_address(self.client)
        try:
            self.workers = max(1, len(self.client.scheduler_info().get("workers", {})))
            self._watch = WorkerWatch(self.client)
        except BaseException:
            disconnect(self.client, self._cluster, self._own)
            raise
        self._scattered: tuple[Any, Any] | None = None  # (evaluator, its future on the workers)
        self._to_close: list[Any] = []  # evaluators with per-worker resources

    def __call__(self, evaluator: Evaluator, X: np.ndarray) -> np.ndarray:
        from distributed.client import FutureCancelledError

        try:
            for resend in range(_RESENDS + 1):
                ev = self._on_the_workers(evaluator, again=resend > 0)
                futs = [self.client.submit(_evaluate_chunk, ev, c, pure=False) for c in _chunks(X, self.workers)]
                try:
                    F = np.vstack(self.client.gather(futs))
                    break
                except FutureCancelledError as exc:
                    # the evaluator's last copy went with a lost worker: Dask's active memory manager (on by
                    # default) keeps one copy of data no task waits for, so between two calls the broadcast
                    # evaluator may live on one worker only; its chunks are cancelled ("already forgotten").
                    # Sent again; every evaluation is deterministic, so the result is the same.
                    if resend == _RESENDS or "forgotten" not in str(exc):
                        raise
            self._watch.check()
        except Exception as exc:
            # the scheduler gone: nothing sent can come back, so the run ends here (the caller keeps its checkpoint)
            from .cluster import raise_if_scheduler_lost

            raise_if_scheduler_lost(self.client, exc, self._address)
            raise
        return F

    def _on_the_workers(self, evaluator: Evaluator, *, again: bool) -> Any:
        """``evaluator``'s future on the workers: scattered to every worker when it is new (or ``again``, after its
        last copy was lost)."""
        if again or self._scattered is None or self._scattered[0] is not evaluator:
            self._scattered = None   # the lost copy's future released first; the new one under a key of its own
            self._scattered = (evaluator, self.client.scatter(evaluator, broadcast=True, hash=False))
            if callable(getattr(evaluator, "close", None)) and not any(e is evaluator for e in self._to_close):
                self._to_close.append(evaluator)
        return self._scattered[1]

    def scheduler_lost(self) -> bool:
        """Whether the client has lost its scheduler."""
        from .cluster import scheduler_lost

        return scheduler_lost(self.client)

    def events(self) -> tuple[str, ...]:
        """A lost worker, said (:class:`identification.cluster.WorkerWatch`)."""
        return self._watch.events()

    def close(self) -> None:
        self._scattered = None
        lost = self.scheduler_lost()
        try:
            for ev in self._to_close if not lost else ():   # no workers to reach without a scheduler
                self.client.run(_close_evaluator, ev)
        except OSError:
            # the scheduler went away after the check, before the client noticed (a refused or reset connection:
            # CommClosedError is an OSError): the workers' copies go with the cluster, and what the run raises about
            # the loss (ClusterError, one line) must not be masked by this traceback
            lost = True
        finally:
            self._to_close.clear()
            from .cluster import disconnect

            disconnect(self.client, self._cluster, self._own, quiet=lost)


def make_runner(*, workers: int = 1, dask: str | None = None) -> Runner:
    """The runner for ``--workers K`` or ``--dask ADDRESS`` (a scheduler address or ``local:K``)."""
    if dask:
        return DaskRunner(dask)
    if workers > 1:
        return ProcessRunner(workers)
    return SerialRunner()
