"""A local Dask cluster set up for model evaluations (``--dask local:K``).

An identification hands Dask few, long, opaque tasks: a chunk of candidates,
each a full simulation of 10–100 ms inside one call (an FMU's step loop or
the compiled modal recursion).  Dask's defaults serve many small tasks and
interactive diagnostics, and on a small machine two of them take CPU that
comes straight out of the evaluations, because every worker already keeps a
core busy:

* each worker's statistical profiler samples its threads' stacks every
  10 ms (``distributed.worker.profile.enabled``), which for this workload
  only ever shows the same call;
* every server — scheduler, nannies, workers — runs an event-loop health
  tick every 20 ms (``distributed.admin.tick.interval``), a system monitor
  every 500 ms and, in the nannies, a memory monitor every 100 ms.

:data:`LOW_OVERHEAD` switches the profiler off and slows those periodic
checks down (memory limits are still enforced, once a second).  Measured on
``benchmarks/bench_identify.py`` (2 cores, FMU backend, median of 3; the
speed-up of 2 workers over 1): 1.69× with Dask's defaults, 1.73× with the
profiler off, 1.73× with the slower checks, 1.78× with both.  The same
settings help a cluster started by hand: put them into the Dask
configuration of the scheduler's and the workers' machines (see docs/benchmarks.md, "Dask settings").

Whoever starts a cluster closes it; :class:`~identification.runners.DaskRunner`
does so for the cluster it starts from ``"local:K"``.

A worker lost mid-run (killed, out of memory, its machine gone) costs time, not results: Dask runs its tasks
again on the workers left (a local cluster's nanny restarts it), the evaluator scattered to every worker is
fetched from another or, when the lost worker held its last copy (Dask's active memory manager keeps one copy of
data no task waits for), sent again by the runner, and every evaluation is deterministic.  :class:`WorkerWatch`
notices the loss, so that the run can say what happened.
"""
from __future__ import annotations

import contextlib
import logging
import re
from types import MappingProxyType
from typing import Any, Iterator, Mapping

from ebb_model.errors import ClusterError, ConfigError

__all__ = ["LOW_OVERHEAD", "WorkerWatch", "connect", "disconnect", "local_cluster", "parse_local_address"]

#: Dask settings of :func:`local_cluster` (read-only; see the module docstring for what each costs).
LOW_OVERHEAD: Mapping[str, Any] = MappingProxyType({
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "500ms",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
})

_LOCAL = re.compile(r"local:(\d+)")


def parse_local_address(address: str) -> int | None:
    """Number of workers of a ``"local:K"`` address; ``None`` for a scheduler address.

    Raises
    ------
    ConfigError
        ``address`` starts with ``local`` but is not ``local:K`` with ``K >= 1``.
    """
    if address != "local" and not address.startswith("local:"):
        return None  # a scheduler address, e.g. tcp://10.0.0.5:8786 or localhost:8786
    m = _LOCAL.fullmatch(address)
    if m is None or int(m.group(1)) < 1:
        raise ConfigError(f"`dask` {address!r}: expected a scheduler address or local:K with K >= 1 workers")
    return int(m.group(1))


def local_cluster(n_workers: int, *, local_directory: str | None = None) -> Any:
    """Start a ``distributed.LocalCluster`` of ``n_workers`` single-threaded worker processes.

    Parameters
    ----------
    n_workers
        Worker processes (one thread each: an evaluation is sequential).
    local_directory
        Scratch space of the workers (Dask's default when ``None``).

    Returns
    -------
    distributed.LocalCluster
        Running cluster with :data:`LOW_OVERHEAD` applied to its scheduler,
        nannies and workers, no dashboard; the caller closes it.
    """
    import dask
    import distributed

    if n_workers < 1:
        raise ConfigError(f"local cluster: n_workers must be >= 1, got {n_workers}")
    with dask.config.set(dict(LOW_OVERHEAD)):
        # the nannies hand this configuration to the worker processes they spawn
        return distributed.LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                        dashboard_address=None, local_directory=local_directory)


def connect(address: Any) -> tuple[Any, Any, bool]:
    """A Dask client for ``address``: a scheduler address, ``"local:K"`` (a :func:`local_cluster` started here)
    or a connected ``distributed.Client`` (used as it is).  Returns ``(client, the cluster started here or None,
    whether the client is the caller's to close)``; :func:`disconnect` undoes it.

    Raises
    ------
    ConfigError
        A malformed ``local:K`` address.
    """
    from distributed import Client

    own = isinstance(address, str)
    cluster = None
    n_local = parse_local_address(address) if own else None
    if n_local is not None:
        cluster = local_cluster(n_local)
        address = cluster.scheduler_address
    try:
        client = Client(address) if own else address
    except BaseException:
        if cluster is not None:
            cluster.close()
        raise
    return client, cluster, own


def disconnect(client: Any, cluster: Any, own: bool, *, quiet: bool = False) -> None:
    """Close what :func:`connect` opened (a client it was given is left open).  A client that lost its scheduler
    (or whose caller found it gone, ``quiet``) is closed quietly: closing it cancels its reconnection, which it
    would log as an error with a traceback after the run has said what happened in one line
    (:func:`raise_if_scheduler_lost`)."""
    if not own:
        return
    try:
        with _silenced("distributed.client") if quiet or scheduler_lost(client) else contextlib.nullcontext():
            client.close()
    finally:
        if cluster is not None:
            cluster.close()


def scheduler_lost(client: Any) -> bool:
    """Whether ``client`` has lost its scheduler (its status is no longer ``running``: it is reconnecting, or
    gave up)."""
    return str(getattr(client, "status", "running")) != "running"


def scheduler_address(client: Any) -> str:
    """The address of ``client``'s scheduler, read while it is connected (a client that gave up reconnecting has
    forgotten it: keep it from the start for :func:`raise_if_scheduler_lost`)."""
    return str(getattr(getattr(client, "scheduler", None), "address", None) or "its address")


def raise_if_scheduler_lost(client: Any, exc: BaseException, address: str) -> None:
    """Raise :class:`~ebb_model.errors.ClusterError` (one line naming the scheduler at ``address``, as
    :func:`scheduler_address` read it when the run connected) from ``exc`` when ``client`` has lost its
    scheduler: the client then cancels every future it holds ("scheduler-connection-lost") and nothing sent to
    the cluster can come back; otherwise return (the caller re-raises ``exc``).  The cancellation itself says so
    too: a future can be cancelled a moment before the client marks itself reconnecting, and a call the client
    makes to the scheduler itself (a worker count, :meth:`WorkerWatch.check`) ends in Dask's ``CommClosedError``
    the moment the scheduler dies (measured once in 8 runs of a batch whose scheduler was killed: the error
    reached the user as "cannot write (CommClosedError)")."""
    from distributed.comm.core import CommClosedError

    cancelled_for_it = "scheduler-connection-lost" in f"{getattr(exc, 'reason', '')} {exc}"
    if cancelled_for_it or isinstance(exc, CommClosedError) or scheduler_lost(client):
        raise ClusterError(f"the Dask scheduler at {address} went away during the run") from exc


@contextlib.contextmanager
def _silenced(logger: str) -> Iterator[None]:
    """``logger`` says nothing below CRITICAL inside the block."""
    log = logging.getLogger(logger)
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        log.setLevel(level)


def _worker_addresses(dask_scheduler: Any) -> list[str]:
    """The addresses of the scheduler's workers now (run on the scheduler)."""
    return list(dask_scheduler.workers)


class WorkerWatch:
    """The workers of a cluster a run has lost: every worker seen at a :meth:`check` and not there at a later one
    (a restarted worker comes back under a new address).

    Parameters
    ----------
    client
        A connected ``distributed.Client``.
    """

    def __init__(self, client: Any):
        self._client = client
        self._seen: set[str] = self._now()
        self.lost: list[str] = []

    def _now(self) -> set[str]:
        return set(self._client.run_on_scheduler(_worker_addresses))

    def check(self) -> None:
        """Compare the scheduler's workers with those seen so far (one round trip to the scheduler)."""
        now = self._now()
        self.lost += sorted(self._seen - now - set(self.lost))
        self._seen |= now

    def events(self) -> tuple[str, ...]:
        """What happened, one sentence (none when no worker was lost)."""
        if not self.lost:
            return ()
        return (f"{len(self.lost)} Dask worker(s) lost during the run ({', '.join(self.lost)}): their tasks ran "
                f"again on the other workers; every evaluation is deterministic, so the results are those of a run "
                f"without the loss",)
