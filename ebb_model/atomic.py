"""Atomic file output: write a temporary file beside the target, then rename it over the target.

Every writer of a result file (CSV, JSON, ``.npz``, checkpoint, FMU) goes through :func:`atomic_path`, so a
reader never sees a half-written file and an interrupted run (an error, Ctrl-C) leaves the old file or nothing.
"""
from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_path"]


@contextmanager
def atomic_path(target: str | Path, *, suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path beside ``target``; rename it onto ``target`` when the block ends normally.

    Parameters
    ----------
    target : str or Path
        The file to write. Its directory must exist; an existing file is replaced only when the block succeeds.
    suffix : str, optional
        Ending of the temporary name, for writers that insist on one (``np.savez`` appends ``.npz`` otherwise).

    Yields
    ------
    Path
        A path in the target's directory that does not exist yet (``.NAME.XXXXXXXX.part`` + ``suffix``).

    Notes
    -----
    On any exception raised in the block — including ``KeyboardInterrupt`` — or by the rename, the temporary
    file is removed and the exception propagates; the target is left as it was. The rename is
    :func:`os.replace`, atomic on POSIX file systems.
    """
    target = Path(target)
    tmp = target.with_name(f".{target.name}.{uuid.uuid4().hex[:8]}.part{suffix}")
    try:
        yield tmp
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
