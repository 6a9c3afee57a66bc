"""The figures a benchmark measured, as JSON for :mod:`benchmarks.report` (``--json PATH`` on every benchmark)."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ebb_model.io.jsonio import write_json

__all__ = ["add_json_argument", "write_figures"]


def add_json_argument(parser: argparse.ArgumentParser) -> None:
    """``--json PATH``: also write the measured figures there (what ``python -m benchmarks.report`` reads)."""
    parser.add_argument("--json", type=Path, default=None,
                        help="also write the measured figures to this JSON file (read by benchmarks/report.py)")


def write_figures(path: Path | None, figures: dict[str, Any]) -> None:
    """Write ``figures`` (names to numbers, strings or lists of table rows) to ``path`` atomically; nothing when
    ``path`` is None."""
    if path is not None:
        write_json(path, figures)
