"""API messages in the command line's words.

The API names what a message is about in its own vocabulary, in backquotes: a keyword argument
(```reduce_order`: must lie in 1 … 34``) or an API function (``run `identify` with `polish` K``). The command
line shows the flag and the command instead (``--reduce-order``, ```ebb identify```), so the API never
mentions flags and the command line never mentions Python keywords.
"""
from __future__ import annotations

import argparse
import re
from collections.abc import Mapping

__all__ = ["COMMANDS", "KEYWORD_ALIASES", "flag_table", "render"]

#: API function → subcommand.
COMMANDS: Mapping[str, str] = {
    "modes_report": "modes", "simulate_files": "simulate", "build_fmu": "build-fmu", "identify": "identify",
    "export_points": "export", "diagnose": "diagnose", "run_demo": "demo",
}
#: API keyword → destination of its flag, where the two differ.
KEYWORD_ALIASES: Mapping[str, str] = {
    "out_dir": "out", "out_csv": "out", "input_csv": "input", "band_hz": "band", "params": "param",
    "result_dir": "dir", "fmu_path": "fmu",
}
_QUOTED = re.compile(r"`([A-Za-z_][A-Za-z0-9_]*)`")


def flag_table(parser: argparse.ArgumentParser) -> dict[str, str]:
    """``{destination: flag}`` of every optional argument of every subcommand of ``parser``."""
    flags: dict[str, str] = {}
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    for sub in subs:
        for p in sub.choices.values():
            for action in p._actions:
                long = [s for s in action.option_strings if s.startswith("--")]
                if long and action.dest != "help":
                    flags.setdefault(action.dest, long[0])
    return flags


def render(message: str, flags: Mapping[str, str]) -> str:
    """``message`` with backquoted API keywords shown as flags and API functions as ``ebb`` commands.

    Parameters
    ----------
    message : str
        An API message.
    flags : mapping
        ``{destination: flag}`` (:func:`flag_table`).

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
