"""The ``ebb`` parser and its exit codes: 0 done, 2 bad input (one line), 130 interrupted (Ctrl-C), 141 the
reader of the output closed its pipe (``ebb modes CFG | head -2``; 128 + SIGPIPE, as a shell's own tools)."""
from __future__ import annotations

import contextlib
import logging
import os
import sys
from typing import Any, Iterator, Sequence

from ebb_model.threads import single_blas_thread

from . import diagnosis, fmu, identification, model
from .messages import FlagParser, render

__all__ = ["build_parser", "main"]


def build_parser() -> FlagParser:
    """The ``ebb`` argument parser with every subcommand (and their flags: :attr:`FlagParser.flags`)."""
    parser = FlagParser(prog="ebb", description="Euler-Bernoulli beam under axial load: "
                                     "model, FMU, identification and sim-to-real gap diagnosis.",
                        epilog="New here? Start with `ebb demo` (about a minute on 2 cores): the whole workflow on an "
                               "embedded example, with every file it writes. Then `ebb COMMAND --help`.")
    sub = parser.add_subparsers(dest="command", required=True)
    for layer in (model, fmu, identification, diagnosis):
        layer.add_parsers(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ebb`` console script; returns the exit code.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success, 2 for bad input (``ebb COMMAND: error: ...`` on one line), 130 when interrupted, 141 when
        the output's reader closed the pipe (quietly).
    """
    import warnings

    from ebb_model.errors import ConfigWarning, DataWarning, EbbError, Interrupted

    parser = build_parser()
    args = parser.parse_args(argv)
    prog = f"ebb {args.command}"
    flags = parser.flags

    def one_line(message: Warning | str, category: type[Warning], *_a: Any, **_k: Any) -> None:
        print(f"{prog}: warning: {render(str(message), flags)}", file=sys.stderr)

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always", DataWarning)
            warnings.simplefilter("default", ConfigWarning)    # once: a config is loaded more than once
            warnings.showwarning = one_line
            with single_blas_thread(), _dask_says_no_more_than_warnings():   # every subcommand
                code = int(args.func(args) or 0)
                sys.stdout.flush()     # a reader gone is found here, not by the interpreter's flush at exit
                return code
    except Interrupted as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        if not _stdout_closed():
            raise                          # another pipe (a worker's, say): not the reader's doing
        return 141
    except EbbError as exc:
        print(f"{prog}: error: {render(str(exc), flags)}", file=sys.stderr)
        return 2


def _stdout_closed() -> bool:
    """Whether standard output's reader has gone (its pipe reports an error to a poll: Linux and macOS); then
    it points to the null device from here on, so that the interpreter's own flush at exit finds nothing to say."""
    import select

    try:
        fd = sys.stdout.fileno()
        poller = select.poll()
        poller.register(fd, select.POLLOUT)
        closed = any(ev & select.POLLERR for _fd, ev in poller.poll(0))
    except (AttributeError, OSError, ValueError):   # no poll here, or no file behind stdout
        return False
    if closed:
        os.dup2(os.open(os.devnull, os.O_WRONLY), fd)
    return closed


@contextlib.contextmanager
def _dask_says_no_more_than_warnings() -> Iterator[None]:
    """Dask's connections log nothing below WARNING inside the block: a scheduler lost mid-run is the command's
    one line (:func:`identification.cluster.raise_if_scheduler_lost`), not also the client's "Batched Comm
    Closed" with its traceback, which it logs at INFO when its send fails (measured: 1 run in 12 under load).
    The loggers of the connections themselves: ``distributed`` sets its own level to INFO when it is imported
    (inside the block), not theirs."""
    logs = [logging.getLogger(name) for name in ("distributed.batched", "distributed.core", "distributed.comm")]
    levels = [log.level for log in logs]
    for log in logs:
        log.setLevel(logging.WARNING)
    try:
        yield
    finally:
        for log, level in zip(logs, levels):
            log.setLevel(level)
