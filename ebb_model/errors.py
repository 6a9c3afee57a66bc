"""Exception hierarchy of the project.

Every error a user can provoke is one of these typed exceptions; the CLI maps
them to exit code 2.  Modelled on python-control's ``control/exception.py`` and
FMPy's ``FMICallException``: a small tree, each class saying *what kind* of
thing went wrong, the message saying *where* and *why*.
"""
from __future__ import annotations

import os
from typing import Sequence

__all__ = [
    "EbbError",
    "ConfigError",
    "ParameterError",
    "StabilityError",
    "DataError",
    "FmuError",
    "OutputError",
    "ClusterError",
    "Interrupted",
    "DataWarning",
    "ConfigWarning",
]


class EbbError(Exception):
    """Base class of all errors raised on purpose by this project."""


class ConfigError(EbbError, ValueError):
    """An invalid configuration: unknown key, bad value, impossible geometry.

    Parameters
    ----------
    problems
        One message per problem, each naming the offending field
        (e.g. ``"beam.nodes: must be an integer >= 4, got 2"``).  All problems
        are reported at once, not only the first.
    """

    def __init__(self, problems: str | Sequence[str]):
        if isinstance(problems, str):
            problems = [problems]
        self.problems: tuple[str, ...] = tuple(problems)
        if len(self.problems) == 1:
            msg = self.problems[0]
        else:
            msg = f"{len(self.problems)} problems:\n" + "\n".join(
                f"  - {p}" for p in self.problems
            )
        super().__init__(msg)


class ParameterError(ConfigError):
    """Physical parameter values that are invalid (e.g. ``EI <= 0``, NaN)."""


class StabilityError(EbbError, ValueError):
    """Parameters for which the time-stepping scheme is unstable."""


class DataError(EbbError, ValueError):
    """Malformed measurement data (NaN, mismatched lengths, missing columns...)."""


class FmuError(EbbError, RuntimeError):
    """Failure while building, loading or running an FMU.

    Parameters
    ----------
    message
        What went wrong.
    function
        The FMI function involved, if any (e.g. ``"fmi2DoStep"``).
    status
        The FMI status returned, if any.
    """

    def __init__(self, message: str, function: str | None = None, status: int | None = None):
        self.function = function
        self.status = status
        super().__init__(message)


class OutputError(EbbError):
    """A place to write that cannot take the output: a read-only or full file system, a missing directory, a
    directory where a file is expected (:mod:`ebb_model.io.output`).

    Parameters
    ----------
    message
        What went wrong, naming the path.
    path
        The file or directory concerned.
    errno
        The operating system's error number, when one caused it (e.g. ``errno.ENOSPC``).
    """

    def __init__(self, message: str, *, path: str | os.PathLike[str] | None = None, errno: int | None = None):
        self.path = path
        self.errno = errno
        super().__init__(message)


class ClusterError(EbbError, RuntimeError):
    """The Dask cluster a run evaluates on went away (its scheduler lost); the message says what was kept."""


class Interrupted(EbbError):
    """A run stopped by the user (Ctrl-C); the message says what was kept.  The CLI exits with code 130."""


class DataWarning(UserWarning):
    """Data that can be used but look suspicious (e.g. a file shorter than its header declares).

    The CLI prints each as one line, ``ebb COMMAND: warning: ...``.
    """


class ConfigWarning(UserWarning):
    """A valid config that cannot do what it seems meant to (e.g. a force on an end that does not move).

    The CLI prints each as one line, ``ebb COMMAND: warning: ...``, once.
    """
