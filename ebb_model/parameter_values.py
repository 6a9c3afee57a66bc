"""Parameter values resolved once: the config's nominal values overridden by the caller's, checked.

Every public function that takes ``params`` (a partial mapping such as ``{"N": 80.0}``) resolves it with
:func:`resolve_parameters` at its entry and passes the result down. A resolved mapping
(:class:`ParameterValues`) is complete and checked, so handing it to another function resolves to itself
without a second check.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any

from .config import check_parameter_values

if TYPE_CHECKING:  # pragma: no cover
    from .config import BeamConfig

__all__ = ["ParameterValues", "resolve_parameters"]


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


def resolve_parameters(config: BeamConfig, params: Mapping[str, Any] | None = None) -> ParameterValues:
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
