"""The coefficient lists Bistritz's test (:mod:`ebb_model.stability.bistritz`) works on: the input checked and
read as exact rationals or floats, and the few polynomial operations of the recursion (coefficient lists, lowest
power first)."""
from __future__ import annotations

import math
import numbers
from fractions import Fraction
from typing import Any, Iterator, Sequence, Union, cast

import numpy as np

from ..checks import finite_scalar

__all__ = ["DEFAULT_TOL", "Number", "parse", "check_tol", "norm", "total", "div_z_minus_1", "symmetrise",
           "sign_changes"]

#: Default relative tolerance of the floating-point zero tests.
DEFAULT_TOL: float = 1000.0 * float(np.finfo(float).eps)

#: A coefficient: exact (:class:`~fractions.Fraction`) or a float.
Number = Union[float, Fraction]


# --------------------------------------------------------------------------
# input handling
# --------------------------------------------------------------------------

def parse(coefficients: Any) -> tuple[list[Number], bool]:
    """Validate the coefficients (highest power first).

    Returns the coefficients *lowest power first* and whether the arithmetic
    is exact (all coefficients rational: ``int``, ``Fraction``, NumPy
    integers) or floating point (anything else real).
    """
    if isinstance(coefficients, (str, bytes)):
        raise ValueError("bistritz: coefficients must be a 1-D sequence of real numbers, got a string")
    try:
        arr = np.asarray(coefficients, dtype=object)
    except Exception as exc:  # ragged nested sequences etc.
        raise ValueError(f"bistritz: coefficients must be a 1-D sequence of real numbers ({exc})") from None
    if arr.ndim != 1:
        raise ValueError(
            f"bistritz: coefficients must be a 1-D sequence (highest power first), "
            f"got an array of shape {arr.shape}"
        )
    if arr.size == 0:
        raise ValueError("bistritz: no coefficients given (empty input)")
    values: list[Any] = []
    for i, c in enumerate(arr.tolist()):
        if isinstance(c, numbers.Complex) and not isinstance(c, numbers.Real):
            if c.imag != 0:
                raise ValueError(
                    f"bistritz: coefficients must be real, coefficient {i} is {c!r}"
                )
            c = c.real
        if not isinstance(c, numbers.Real):
            raise ValueError(
                f"bistritz: coefficient {i} is not a real number: {c!r}"
            )
        values.append(c)
    exact = all(isinstance(c, numbers.Rational) for c in values)
    out: list[Number]
    if exact:
        out = [Fraction(int(c)) if isinstance(c, numbers.Integral) else Fraction(c) for c in values]
    else:
        out = []
        for i, c in enumerate(values):
            x = float(c)
            if not math.isfinite(x):
                raise ValueError(
                    f"bistritz: coefficient {i} is not finite: {c!r}"
                )
            out.append(x)
    return out[::-1], exact


def check_tol(tol: float | None) -> float:
    if tol is None:
        return DEFAULT_TOL
    return finite_scalar("bistritz: tol", tol, minimum=0.0, error=ValueError)


# --------------------------------------------------------------------------
# polynomial helpers (coefficient lists, lowest power first)
# --------------------------------------------------------------------------

def norm(p: Sequence[Number]) -> Number:
    # abs keeps each coefficient's type, float or Fraction (mypy would join the two to object)
    return max(cast("Iterator[Number]", (abs(x) for x in p)))


def total(p: Sequence[Number], exact: bool) -> Number:
    """``p(1)``: exact sum, or a correctly rounded float sum."""
    return sum(p) if exact else math.fsum(p)


def div_z_minus_1(p: Sequence[Number], zero: Number) -> list[Number]:
    """Quotient of ``p(z) / (z - 1)``, the remainder ``p(1)`` being dropped.

    From ``p = (z - 1) q``: ``q_j = -(p_0 + ... + p_j)``.
    """
    q: list[Number] = []
    acc = zero
    for x in p[:-1]:
        acc = acc - x
        q.append(acc)
    return q


def symmetrise(p: list[Number], exact: bool) -> list[Number]:
    """Enforce the exact symmetry of a float ``T_k`` (no-op when exact)."""
    if exact:
        return p
    return [(a + b) * 0.5 for a, b in zip(p, reversed(p))]


def sign_changes(values: Sequence[Number]) -> int:
    changes = 0
    previous = 0
    for v in values:
        if v == 0:
            continue
        sign = 1 if v > 0 else -1
        if previous and sign != previous:
            changes += 1
        previous = sign
    return changes
