"""The ``ebb`` parser and its exit codes: 0 done, 2 bad input (one line), 130 interrupted (Ctrl-C)."""
from __future__ import annotations

import sys
from typing import Any, Sequence

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
        0 on success, 2 for bad input (``ebb COMMAND: error: ...`` on one line), 130 when interrupted.
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
            with single_blas_thread():   # every subcommand (ebb_model.threads)
                return int(args.func(args) or 0)
    except Interrupted as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except EbbError as exc:
        print(f"{prog}: error: {render(str(exc), flags)}", file=sys.stderr)
        return 2
