"""Output places: every file and directory a command writes is checked before the work and written atomically.

One layer answers the four questions a place to write raises, for every command (``simulate``, ``build-fmu``,
``identify`` and its checkpoint, ``export``, ``diagnose``, ``demo``):

* **What is written.** A symbolic link is followed: the file it points to is written (atomically when that is a
  regular file) and the link is kept. A character device or a FIFO (``/dev/null``, a terminal, a named pipe) is
  written through — opened and written, never replaced by a regular file. A directory where a file is expected,
  a block device or a socket is refused.
* **Before the work.** :func:`check_output_file`, :func:`check_new_output_dir` and :func:`check_writable_dir`
  check the place before the first computation: the directory exists, :func:`os.access` allows writing, a probe
  file can really be created and removed there (a read-only file system, ``/sys``, a permission) and at least
  :data:`MIN_FREE_BYTES` are free (:func:`shutil.disk_usage`).
* **Never half-written.** :func:`atomic_path` yields a temporary path beside the target (``.NAME.XXXXXXXX.part``)
  and renames it over the target when the block succeeds; on any failure — an error, Ctrl-C, a full disk
  (``ENOSPC``) or a file size limit (``EFBIG``) in the middle of writing — the temporary file is removed and the
  target left as it was. :func:`staged_dir` does the same for a whole result directory.
* **One kind of error.** Every :class:`OSError` of writing becomes an :class:`~ebb_model.errors.OutputError`
  naming the path and the reason (one line on the command line, exit code 2).

Directories are created with one rule for their mode: a plain ``mkdir`` (mode ``0o777 & ~umask``, ``0755``
with the usual umask ``022``) — a command's result directory, its subdirectories and a staged directory
renamed into place alike (:func:`make_dir`, :func:`staged_dir`).
"""
from __future__ import annotations

import os
import shutil
import stat
import tempfile
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Final

from ..errors import OutputError

__all__ = ["MIN_FREE_BYTES", "atomic_path", "check_new_output_dir", "check_output_file", "check_writable_dir",
           "make_dir", "staged_dir"]

#: Free space a place to write must offer before a command starts (1 MiB: room for a result file, not a
#: promise that every result fits — a disk that fills up later is still cleaned up after).
MIN_FREE_BYTES: Final = 1 << 20


def _reason(exc: OSError) -> str:
    return exc.strerror or type(exc).__name__


def _label(name: str | None, path: Path) -> str:
    """How messages name a place: the caller's keyword (in backquotes, shown as its flag by the CLI) and path."""
    return f"`{name}` {path}" if name else str(path)


def _stat(path: Path) -> os.stat_result | None:
    """``os.stat`` following links; ``None`` for an absent path or a link to nothing."""
    try:
        return os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        return None
    except OSError as exc:
        raise OutputError(f"{path}: cannot be examined ({_reason(exc)})", path=path) from None


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "directory"), (stat.S_ISBLK, "block device"), (stat.S_ISSOCK, "socket")):
        if test(mode):
            return name
    return "special file"


def _written_through(path: Path, st: os.stat_result | None, label: str) -> bool:
    """Whether ``path`` is a character device or FIFO (written through); refuse what is neither that nor a file."""
    if st is None or stat.S_ISREG(st.st_mode):
        return False
    if stat.S_ISCHR(st.st_mode) or stat.S_ISFIFO(st.st_mode):
        return True
    what = "a file" if stat.S_ISDIR(st.st_mode) else "a file, a character device or a FIFO"
    raise OutputError(f"{label}: is a {_kind(st.st_mode)}, expected {what}", path=path)


def _same_file(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` are one file (device and inode: links and case folded by the file system)."""
    try:
        return os.path.samefile(a, b)
    except OSError:                       # one of them absent or unreadable: not the same existing file
        return False


def _check_place(d: Path, label: str) -> None:
    """``d`` exists, a probe file can be created and removed in it, ``os.access`` agrees, enough space is free."""
    if not d.is_dir():
        raise OutputError(f"{label}: directory {d} does not exist", path=d)
    try:
        fd, probe = tempfile.mkstemp(prefix=".ebb-probe-", dir=d)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputError(f"{label}: cannot write in {d} ({_reason(exc)})", path=d) from None
    if not os.access(d, os.W_OK | os.X_OK):
        raise OutputError(f"{label}: directory {d} is not writable", path=d)
    free = shutil.disk_usage(d).free
    if free < MIN_FREE_BYTES:
        raise OutputError(f"{label}: only {free // 1024} KiB free in {d} (at least {MIN_FREE_BYTES >> 20} MiB "
                          "needed)", path=d)


def check_output_file(target: str | Path, *, name: str | None = "out",
                      inputs: Sequence[str | os.PathLike[str]] = ()) -> Path:
    """Check, before any work, that ``target`` can be written as one file.

    Parameters
    ----------
    target : str or Path
        The file to write: absent, a regular file (replaced), a symbolic link (its target is written), a
        character device or a FIFO (written through).
    name : str, optional
        The caller's keyword for it, named in messages.
    inputs : sequence of paths, optional
        The files the same call reads: ``target`` must be none of them, by any path (a link, another spelling
        of the same directory, a case-insensitive file system's other case) — writing it would destroy the input.

    Returns
    -------
    Path
        ``target``.

    Raises
    ------
    OutputError
        ``target`` is a directory or another special file, its directory does not exist, is read-only or not
        writable, or has less than :data:`MIN_FREE_BYTES` free; a device or FIFO that is not writable; one of
        ``inputs``.
    """
    p = Path(target)
    label = _label(name, p)
    st = _stat(p)
    if st is not None and stat.S_ISREG(st.st_mode):
        for source in inputs:
            if _same_file(p, Path(source)):
                raise OutputError(f"{label}: is the input {source}; writing it would destroy that input — give "
                                  "another output path", path=p)
    if _written_through(p, st, label):
        if not os.access(p, os.W_OK):
            raise OutputError(f"{label}: is not writable", path=p)
        return p
    _check_place(Path(os.path.realpath(p)).parent, label)
    return p


def check_new_output_dir(out: str | Path, *, name: str | None = "out_dir") -> Path:
    """Check, before any work, that ``out`` can become a new result directory: absent or empty, writable.

    Parameters
    ----------
    out : str or Path
        The directory (a symbolic link to a directory counts as that directory).
    name : str, optional
        The caller's keyword for it, named in messages.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    OutputError
        ``out`` is a file, a non-empty directory, its parent does not exist, or the place is not writable or
        has less than :data:`MIN_FREE_BYTES` free.
    """
    out = Path(out)
    label = _label(name, out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"{label}: is a file, expected a directory (absent or empty)", path=out)
    if out.is_dir():
        if any(out.iterdir()):
            raise OutputError(f"{label}: exists and is not empty; choose a new directory", path=out)
        _check_place(out, label)
        return out
    parent = Path(os.path.realpath(out)).parent
    if not parent.is_dir():
        raise OutputError(f"{label}: parent directory does not exist", path=out)
    _check_place(parent, label)
    return out


def check_writable_dir(d: str | Path, *, name: str | None = None) -> Path:
    """Check, before any work, that the existing directory ``d`` can take more files (as :func:`check_output_file`).

    ``name``, when given, is the caller's keyword for ``d``, named in messages.

    Raises
    ------
    OutputError
        ``d`` is not a directory, not writable, or has less than :data:`MIN_FREE_BYTES` free.
    """
    d = Path(d)
    _check_place(Path(os.path.realpath(d)), _label(name, d))
    return d


def make_dir(path: str | Path, *, exist_ok: bool = False, parents: bool = False) -> Path:
    """Create the directory ``path`` (a link to nothing: the directory it names) with a plain ``mkdir``.

    The mode is ``0o777 & ~umask``: the one rule of every directory the commands create (``parents``: missing
    parents too, by the same rule).

    Raises
    ------
    OutputError
        The directory cannot be created.
    """
    p = Path(path)
    try:
        Path(os.path.realpath(p)).mkdir(exist_ok=exist_ok, parents=parents)
    except OSError as exc:
        raise OutputError(f"{p}: cannot create the directory ({_reason(exc)})", path=p) from None
    return p


@contextmanager
def atomic_path(target: str | Path, *, suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path to write; when the block ends normally it becomes ``target``.

    Parameters
    ----------
    target : str or Path
        The file to write. A regular file (or an absent one) is replaced by renaming the temporary file over it;
        a symbolic link is followed (its target replaced, the link kept); a character device or FIFO receives
        the temporary file's bytes and is never replaced.
    suffix : str, optional
        Ending of the temporary name, for writers that insist on one (``np.savez`` appends ``.npz`` otherwise,
        ``savefig`` infers the format from it).

    Yields
    ------
    Path
        A path that does not exist yet: ``.NAME.XXXXXXXX.part`` + ``suffix`` beside the file written (in the
        temporary directory for a device or FIFO).

    Raises
    ------
    OutputError
        Any :class:`OSError` while writing or renaming (``ENOSPC``, ``EFBIG``, ``EROFS`` …), naming ``target``.

    Notes
    -----
    On any exception raised in the block — including ``KeyboardInterrupt`` — or by the rename, the temporary file
    is removed and the target is left as it was. The rename is :func:`os.replace`, atomic on POSIX file systems.
    """
    target = Path(target)
    through = _written_through(target, _stat(target), str(target))
    real = target if through else Path(os.path.realpath(target))
    where = Path(tempfile.gettempdir()) if through else real.parent
    tmp = where / f".{real.name}.{uuid.uuid4().hex[:8]}.part{suffix}"
    try:
        yield tmp
        if through:   # opening a device or FIFO for writing neither replaces nor truncates it
            with open(tmp, "rb") as src, open(target, "wb") as dst:
                shutil.copyfileobj(src, dst)
        else:
            os.replace(tmp, real)
    except OSError as exc:
        raise OutputError(f"{target}: cannot write ({_reason(exc)}); no partial file is left", path=target,
                          errno=exc.errno) from None
    finally:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass


@contextmanager
def staged_dir(out: str | Path) -> Iterator[Path]:
    """Yield a new directory beside ``out`` to fill; when the block ends normally it is renamed onto ``out``.

    ``out`` must be absent or empty (:func:`check_new_output_dir`); the staged directory is made by
    :func:`make_dir`'s rule. On any exception in the block or the rename the staged directory is removed.

    Raises
    ------
    OutputError
        Any :class:`OSError` while creating, filling or renaming, naming ``out``.
    """
    out = Path(out)
    real = Path(os.path.realpath(out))
    tmp = real.parent / f".{real.name}.{uuid.uuid4().hex[:8]}.part"
    try:
        os.mkdir(tmp)
        yield tmp
        os.replace(tmp, real)    # onto an absent or empty directory
    except OutputError as exc:   # a file inside: name it where it was going to be
        raise OutputError(f"{str(exc).replace(str(tmp), str(out))}; nothing was kept", path=out,
                          errno=exc.errno) from None
    except OSError as exc:
        raise OutputError(f"{out}: cannot write ({_reason(exc)}); nothing was kept", path=out,
                          errno=exc.errno) from None
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
