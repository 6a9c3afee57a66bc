"""The one check of a scalar argument: a finite number, optionally bounded below.

Keyword arguments of the API (a sample time, a time constant, a noise level, a stiffness) go through
:func:`finite_scalar`, so every such check accepts the same values and says the same thing:
"tau must be a finite number >= 0, got -1.0".
"""
from __future__ import annotations

import math

import numpy as np

from .errors import ParameterError

__all__ = ["finite_scalar"]


def finite_scalar(name: str, value: object, *, minimum: float | None = None, strict: bool = False,
                  numbers_only: bool = False, error: type[Exception] = ParameterError) -> float:
    """``value`` as a finite float, checked against an optional lower bound.

    Parameters
    ----------
    name : str
        How the value is called in the message (e.g. ``"dt"``, ``"actuator_lag.tau"``).
    value : object
        The value; anything :class:`float` converts (strings too, unless ``numbers_only``).
    minimum : float, optional
        Lower bound; ``value >= minimum`` (``>`` when ``strict``).
    strict : bool, optional
        Exclude ``minimum`` itself.
    numbers_only : bool, optional
        Accept Python and NumPy numbers only (no strings, no booleans).
    error : type of Exception, optional
        Exception raised (default :class:`~ebb_model.errors.ParameterError`).

    Returns
    -------
    float

    Raises
    ------
    Exception
        ``error``: "NAME must be a number, got …", "NAME must be finite, got …" or
        "NAME must be a finite number > MIN, got …".
    """
    if numbers_only and (isinstance(value, (bool, np.bool_))
                         or not isinstance(value, (int, float, np.integer, np.floating))):
        raise error(f"{name} must be a number, got {value!r}")
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise error(f"{name} must be a number, got {value!r}") from None
    if minimum is None:
        if not math.isfinite(v):
            raise error(f"{name} must be finite, got {value!r}")
    elif not math.isfinite(v) or v < minimum or (strict and v == minimum):
        raise error(f"{name} must be a finite number {'>' if strict else '>='} {minimum:g}, got {value!r}")
    return v
