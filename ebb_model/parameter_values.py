"""Parameter values resolved once: the config's nominal values overridden by the caller's, checked.

Every public function that takes ``params`` (a partial mapping such as ``{"N": 80.0}``) resolves it with
:func:`resolve_parameters` at its entry and passes the result down. A resolved mapping
(:class:`ParameterValues`) is complete and checked, so handing it to another function resolves to itself
without a second check.
"""
from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import Any, Protocol

from .beam import PARAMETER_NAMES
from .errors import ParameterError
from .config.problems import Problems

__all__ = ["ParameterValues", "resolve_parameters", "check_parameter_values", "range_problem", "POSITIVE",
           "NON_NEGATIVE", "MAX_MAGNITUDE", "MIN_POSITIVE"]

class Nominal(Protocol):
    """What :func:`resolve_parameters` needs of a config: its nominal values (a
    :class:`~ebb_model.config.BeamConfig` has them)."""

    def parameter_values(self) -> dict[str, float]:  # noqa: D102 - as BeamConfig's
        ...


#: Parameters that must be positive (``EI``, ``rhoA``) and those that must not be negative.
POSITIVE = ("EI", "rhoA")
NON_NEGATIVE = ("c", "eta", "rhoI", "kf")
#: Magnitudes of parameter values the model accepts: every physical beam (nanotubes to bridges) lies far
#: inside, and no matrix, pole or stability polynomial of the model overflows within them (400 random
#: combinations of 1e-30 … 1e30 with sample times 1e-9 … 1e3 s ran clean; 1e300 overflowed).
MAX_MAGNITUDE = 1e30
#: The smallest ``EI`` and ``rhoA`` accepted.
MIN_POSITIVE = 1e-30


def range_problem(name: str, value: float) -> str | None:
    """Why ``value`` is no physical value of parameter ``name`` (its sign or magnitude); ``None`` when it is."""
    if name in POSITIVE and not value > 0:
        return f"must be > 0, got {value:g}"
    if name in NON_NEGATIVE and value < 0:
        return f"must be >= 0, got {value:g}"
    if name in POSITIVE and value < MIN_POSITIVE:
        return f"must be at least {MIN_POSITIVE:g} (far below any physical beam), got {value:g}"
    if abs(value) > MAX_MAGNITUDE:
        return f"must be at most {MAX_MAGNITUDE:g} in magnitude (far beyond any physical beam), got {value:g}"
    return None


def check_parameter_values(values: Mapping[str, Any], *, where: str = "parameters") -> dict[str, float]:
    """Check physical parameter values; return them as floats.

    Raises
    ------
    ParameterError
        Naming every invalid parameter: missing, non-finite, ``EI <= 0``,
        ``rhoA <= 0``, ``c < 0``, ``eta < 0``, ``rhoI < 0``, ``kf < 0``, or a magnitude outside
        :data:`MIN_POSITIVE` … :data:`MAX_MAGNITUDE` (:func:`range_problem`).
    """
    pr = Problems()
    out: dict[str, float] = {}
    for k in values:
        if k not in PARAMETER_NAMES:
            pr.add(f"{where}.{k}", f"unknown parameter; allowed: {', '.join(PARAMETER_NAMES)}")
    for k in PARAMETER_NAMES:
        if k not in values:
            pr.add(f"{where}.{k}", "missing")
            continue
        v = values[k]
        if type(v) is not float or not math.isfinite(v):      # (the common case without building the name)
            v = pr.number(f"{where}.{k}", v)
            if v is None:
                continue
        problem = range_problem(k, v)
        if problem is not None:
            pr.add(f"{where}.{k}", problem)
        else:
            out[k] = v
    if pr.items:
        raise ParameterError(pr.items)
    return out


class ParameterValues(Mapping[str, float]):
    """A complete, checked, read-only set of physical parameter values (``EI``, ``rhoA``, …).

    Made by :func:`resolve_parameters` only. Merging (``p | {"N": 5.0}``) gives a plain ``dict``, which is
    checked again when resolved.
    """

    __slots__ = ("_values",)

    def __init__(self, values: Mapping[str, float]) -> None:
        self._values = dict(values)

    def __getitem__(self, key: str) -> float:
        return self._values[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __or__(self, other: Mapping[str, Any]) -> dict[str, Any]:
        return self._values | dict(other)

    def __repr__(self) -> str:
        return f"ParameterValues({self._values!r})"

    def __getstate__(self) -> dict[str, float]:
        return self._values

    def __setstate__(self, state: dict[str, float]) -> None:
        self._values = dict(state)


def resolve_parameters(config: Nominal, params: Mapping[str, Any] | None = None) -> ParameterValues:
    """The config's nominal parameter values overridden by ``params``, checked.

    Parameters
    ----------
    config : BeamConfig
        Gives the nominal values of the parameters ``params`` leaves out.
    params : mapping, optional
        Values to use instead (any subset of :data:`~ebb_model.beam.PARAMETER_NAMES`); a
        :class:`ParameterValues` is returned as it is.

    Returns
    -------
    ParameterValues

    Raises
    ------
    ParameterError
        Naming every invalid parameter: unknown, non-finite, ``EI <= 0``, ``rhoA <= 0``, ``c < 0``,
        ``eta < 0``, ``rhoI < 0``, ``kf < 0``.
    """
    if isinstance(params, ParameterValues):
        return params
    return ParameterValues(check_parameter_values(config.parameter_values() | dict(params or {})))
