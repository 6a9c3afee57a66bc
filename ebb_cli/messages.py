"""API messages in the command line's words.

The API names what a message is about in its own vocabulary, in backquotes: a keyword argument
(```reduce_order`: must lie in 1 … 34``) or an API function (``run `identify` with `polish` K``). The command
line shows the flag and the command instead (``--reduce-order``, ```ebb identify```), so the API never
mentions flags and the command line never mentions Python keywords.
"""
from __future__ import annotations

import argparse
import functools
import re
from collections.abc import Mapping
from typing import Any, Protocol

__all__ = ["COMMANDS", "KEYWORD_ALIASES", "FlagParser", "Subcommands", "add_target_argument", "render"]

#: API function → subcommand.
COMMANDS: Mapping[str, str] = {
    "modes_report": "modes", "simulate_files": "simulate", "build_fmu": "build-fmu", "identify": "identify",
    "export_points": "export", "diagnose": "diagnose", "run_demo": "demo",
}
#: API keyword → destination of its flag, where the two differ.
KEYWORD_ALIASES: Mapping[str, str] = {
    "out_dir": "out", "out_csv": "out", "input_csv": "input", "band_hz": "band", "params": "param",
    "result_dir": "dir", "fmu_path": "fmu", "targets": "target",
}
_QUOTED = re.compile(r"`([A-Za-z_][A-Za-z0-9_]*)`")


class Subcommands(Protocol):
    """What a layer's ``add_parsers`` is given: the object ``add_subparsers`` returns (its public method)."""

    def add_parser(self, name: str, **kwargs: Any) -> FlagParser:  # noqa: D102 - as argparse's
        ...


class FlagParser(argparse.ArgumentParser):
    """An :class:`argparse.ArgumentParser` that records the long flag of every optional argument by its
    destination, its subcommands' and mutually exclusive groups' included (:attr:`flags`, shared by them).

    Only argparse's public interface is used: the returned actions of ``add_argument`` and the
    ``parser_class`` of ``add_subparsers``.
    """

    def __init__(self, *args: Any, flags: dict[str, str] | None = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        #: ``{destination: flag}`` of every optional argument, for :func:`render`.
        self.flags: dict[str, str] = {} if flags is None else flags

    def _record(self, action: argparse.Action) -> argparse.Action:
        long = [s for s in action.option_strings if s.startswith("--")]
        if long and action.dest != "help":
            self.flags.setdefault(action.dest, long[0])
        return action

    def add_argument(self, *args: Any, **kwargs: Any) -> argparse.Action:   # noqa: D102 - as argparse's
        return self._record(super().add_argument(*args, **kwargs))

    def add_mutually_exclusive_group(self, **kwargs: Any) -> Any:          # noqa: D102 - as argparse's
        group = super().add_mutually_exclusive_group(**kwargs)
        add = group.add_argument
        group.add_argument = lambda *a, **k: self._record(add(*a, **k))      # type: ignore[method-assign]
        return group

    # returns a Subcommands, typed Any: argparse's own return type depends on the parser_class given (a caller's is
    # kept), which a single signature cannot state
    def add_subparsers(self, **kwargs: Any) -> Any:                         # noqa: D102 - as argparse's
        kwargs.setdefault("parser_class", functools.partial(FlagParser, flags=self.flags))
        return super().add_subparsers(**kwargs)


def render(message: str, flags: Mapping[str, str]) -> str:
    """``message`` with backquoted API keywords shown as flags and API functions as ``ebb`` commands.

    Parameters
    ----------
    message : str
        An API message.
    flags : mapping
        ``{destination: flag}`` (:attr:`FlagParser.flags`).

    Returns
    -------
    str
        The message in the command line's words; backquoted names that are neither stay as they are.
    """
    def word(m: re.Match[str]) -> str:
        name = m.group(1)
        if name in COMMANDS:
            return f"`ebb {COMMANDS[name]}`"
        flag = flags.get(KEYWORD_ALIASES.get(name, name))
        return flag if flag is not None else m.group(0)

    return _QUOTED.sub(word, message)


def add_target_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """``--target NAME [NAME ...]``: export targets by name (the API's ``targets``), default the API's."""
    from identification.export_targets import DEFAULT_TARGETS, TARGETS

    parser.add_argument("--target", nargs="+", default=list(DEFAULT_TARGETS), metavar="NAME",
                        help=f"{what}: {' | '.join(TARGETS)} (default: {' '.join(DEFAULT_TARGETS)})")
