"""Reading text files written by people and instruments, with messages fit to print.

Every reader of a text format (TOML configs, CSV, LabVIEW ``.lvm``, UFF) goes
through :func:`read_text`, so a binary file, a file in an unexpected encoding or
an unreadable path gives one clear message naming the file — never a
``UnicodeDecodeError`` traceback, and never a screenful of the file's bytes.
:func:`printable` and :func:`quote` are the one way to echo a piece of a file in a message.
"""
from __future__ import annotations

from pathlib import Path

from ..errors import EbbError

__all__ = ["read_text", "printable", "quote"]

#: bytes inspected to tell text from binary data
_PROBE = 65536
#: C0 control characters that never occur in a text file (tab, LF, VT, FF, CR are text)
_CONTROL = frozenset(range(32)) - {9, 10, 11, 12, 13}


def _binary_offset(raw: bytes) -> int | None:
    """Offset of the first byte that marks ``raw`` as binary data, or ``None`` for text.

    A NUL byte anywhere in the probe, or control characters making up more than
    1 % of it, mark binary data (instrument text files contain neither).
    """
    head = raw[:_PROBE]
    nul = head.find(b"\0")
    if nul >= 0:
        return nul
    bad = [i for i, b in enumerate(head) if b in _CONTROL]
    if bad and len(bad) > 0.01 * len(head):
        return bad[0]
    return None


def read_text(path: str | Path, error: type[EbbError], *, what: str = "file",
              latin1_fallback: bool = False) -> str:
    """Read ``path`` as text (UTF-8, a byte-order mark tolerated).

    Parameters
    ----------
    path
        The file.
    error
        The exception type to raise (e.g. :class:`~ebb_model.errors.ConfigError`).
    what
        What the file is, for messages (``"config file"``, ``"data file"``).
    latin1_fallback
        Decode as Latin-1 when the file is not valid UTF-8 (instrument files
        written on Windows), instead of reporting the invalid byte.

    Raises
    ------
    EbbError
        Of type ``error``: unreadable path, a directory, binary data, or (without
        ``latin1_fallback``) bytes that are not UTF-8 — naming the file and the offset.
    """
    p = Path(path)
    try:
        raw = p.read_bytes()
    except IsADirectoryError:
        raise error(f"{p}: is a directory, expected a {what}") from None
    except OSError as exc:
        raise error(f"{p}: cannot read {what} ({exc.strerror or exc})") from None
    off = _binary_offset(raw)
    if off is not None:
        raise error(f"{p}: not a text {what} (binary data, e.g. byte 0x{raw[off]:02x} at offset {off})")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        if latin1_fallback:
            return raw.decode("latin-1")
        raise error(f"{p}: {what} is not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start}); "
                    "save it as UTF-8") from None


def printable(text: str, limit: int = 120) -> str:
    """``text`` fit for a one-line message: non-printable characters escaped, at most ``limit`` characters."""
    s = text if len(text) <= limit else text[: limit - 1] + "…"
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in s)


def quote(text: str, limit: int = 40) -> str:
    """``text`` quoted for a message (see :func:`printable`)."""
    return "'" + printable(text, limit).replace("'", "\\'") + "'"
