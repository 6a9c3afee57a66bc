"""Local worker processes that a user's script can start at its top level.

The pools are ``spawn`` pools (no inherited locks or threads).  A spawned child re-imports the parent's main
module by its path so that objects defined there can be unpickled — and a script that calls ``identify`` or
``diagnose`` at its top level, with no ``if __name__ == "__main__":`` guard (as a page's snippet is saved and
run), would then run again in every worker: a worker that starts its own pool, ``BrokenProcessPool`` in the
parent.  The work sent to these pools is the project's own (evaluators, fits), never the script's, so the pool
starts its workers without the main module's path (:func:`process_pool`): the children import the project's
modules only, and the script runs once.

An interrupted run must not wait for the work in flight (a diagnosis' refit can take a minute): :func:`stop_now`
cancels what is queued and terminates the workers.
"""
from __future__ import annotations

import multiprocessing
import sys
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager
from typing import Any, Callable, Iterator

__all__ = ["process_pool", "stop_now"]


@contextmanager
def _main_path_hidden() -> Iterator[None]:
    """The main module without its ``__file__`` (and module spec) while workers are started."""
    main = sys.modules.get("__main__")
    saved: dict[str, Any] = {k: main.__dict__[k] for k in ("__file__", "__spec__")
                             if main is not None and k in main.__dict__}
    try:
        for k in saved:
            if k == "__spec__":
                main.__dict__[k] = None
            else:
                del main.__dict__[k]
        yield
    finally:
        if main is not None:
            main.__dict__.update(saved)


class _ScriptSafePool(ProcessPoolExecutor):
    """A ``spawn`` pool whose workers (started on submission) never re-run the main module."""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        with _main_path_hidden():
            return super().submit(fn, *args, **kwargs)


def process_pool(workers: int, initializer: Callable[[], Any] | None = None) -> ProcessPoolExecutor:
    """A pool of ``workers`` spawned processes, each started with ``initializer`` (module docstring)."""
    return _ScriptSafePool(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                           initializer=initializer)


def stop_now(pool: ProcessPoolExecutor, grace: float = 5.0) -> None:
    """Shut ``pool`` down without waiting for its running tasks: queued ones are cancelled, the worker processes
    terminated (SIGTERM) and reaped, each given ``grace`` seconds before it is killed."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        if p.is_alive():
            p.terminate()
    for p in processes:
        p.join(timeout=grace)
        if p.is_alive():
            p.kill()
            p.join()
