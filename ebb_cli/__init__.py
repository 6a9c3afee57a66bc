"""The ``ebb`` command line: parses arguments and calls the API of the layers below, nothing more.

Each subcommand mirrors an API function (FMPy's ``cli.py`` habit) and each flag is the kebab-case form of an
API keyword. Errors raised on purpose (:class:`~ebb_model.errors.EbbError`) print one line and exit with code
2, leaving no partial output; Ctrl-C prints one line and exits with 130.

``model`` — ``modes``, ``simulate``; ``fmu`` — ``build-fmu``; ``identification`` — ``identify``, ``export``;
``diagnosis`` — ``diagnose``, ``demo``; ``messages`` — API messages in the command line's words;
``main`` — the parser and the exit codes.
"""
from __future__ import annotations

from .main import build_parser, main

__all__ = ["build_parser", "main"]
