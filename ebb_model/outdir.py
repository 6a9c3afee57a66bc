"""Output directories of the long-running commands: checked before any work, never left half-written."""
from __future__ import annotations

from pathlib import Path

from .errors import ConfigError

__all__ = ["check_new_output_dir"]


def check_new_output_dir(out: str | Path, *, name: str = "out") -> Path:
    """Check that ``out`` can become a new result directory: absent or an empty directory, parent present.

    Parameters
    ----------
    out : str or Path
        The directory.
    name : str, optional
        The caller's keyword for it, named in messages.

    Raises
    ------
    ConfigError
        ``out`` is a file, a non-empty directory, or its parent directory does not exist.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"`{name}` {out}: is a file, expected a directory (absent or empty)")
    if out.is_dir() and any(out.iterdir()):
        raise ConfigError(f"`{name}` {out}: exists and is not empty; choose a new directory")
    if not out.parent.is_dir():
        raise ConfigError(f"`{name}` {out}: parent directory does not exist")
    return out
