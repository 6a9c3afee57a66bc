r"""The scaled characteristic functions of an axially loaded Euler–Bernoulli beam's natural frequencies,
one per pair of ends (the model and the notation: :mod:`ebb_model.reference.analytic`).

Characteristic equations (non-trivial solutions of the 4 x 4 system):

* pinned–pinned: :math:`\sinh\alpha \sin\beta = 0`, closed form
  :math:`\Omega_n = n\pi\sqrt{n^2\pi^2 + U}`;
* clamped–clamped:
  :math:`2\alpha\beta(1 - \cosh\alpha\cos\beta) + (\alpha^2-\beta^2)\sinh\alpha\sin\beta = 0`;
* clamped–pinned: :math:`\alpha\sin\beta\cosh\alpha - \beta\cos\beta\sinh\alpha = 0`
  (the pole-free form of :math:`\alpha\tan\beta = \beta\tanh\alpha`);
* clamped–free:
  :math:`2\alpha^2\beta^2 + (\alpha^4+\beta^4)\cos\beta\cosh\alpha
  + \alpha\beta(\alpha^2-\beta^2)\sin\beta\sinh\alpha = 0`.

Each characteristic function is

1. divided by :math:`\alpha\beta` where this removes the trivial root
   :math:`\Omega = 0` (using the entire functions
   :math:`\operatorname{sinc}\beta = \sin\beta/\beta` and
   :math:`\tanh\alpha/\alpha`), and
2. divided by :math:`\cosh\alpha` so that nothing overflows (only
   :math:`\tanh\alpha` and :math:`\operatorname{sech}\alpha` remain);

the clamped–free function is further divided by :math:`\alpha^4 + \beta^4`.
The scaled functions are smooth and pole-free, so that :mod:`~ebb_model.reference.analytic` brackets
their roots on a uniform grid.
"""
from __future__ import annotations

from types import MappingProxyType
from typing import Callable, Mapping, Union

import numpy as np

from ..errors import ConfigError

__all__ = ["characteristic_function", "canonical_pair", "alpha_from_beta", "CHARACTERISTIC", "CharFun", "Values"]

# Read-only alias table: accepted spellings -> canonical boundary condition.
_BC_ALIASES: Mapping[str, str] = MappingProxyType(
    {
        "clamped": "clamped",
        "fixed": "clamped",
        "built-in": "clamped",
        "pinned": "pinned",
        "hinged": "pinned",
        "simply-supported": "pinned",
        "simply_supported": "pinned",
        "free": "free",
    }
)
_BC_RANK: Mapping[str, int] = MappingProxyType({"clamped": 0, "pinned": 1, "free": 2})
_SUPPORTED_PAIRS: tuple[tuple[str, str], ...] = (
    ("pinned", "pinned"),
    ("clamped", "clamped"),
    ("clamped", "pinned"),
    ("clamped", "free"),
)


#: alpha and beta: arrays, or one float64 each (a root's refinement)
Values = Union[np.ndarray, np.float64]
CharFun = Callable[[Values, Values, float], np.ndarray]
# --------------------------------------------------------------------------
# boundary-condition handling
# --------------------------------------------------------------------------
def _canonical_bc(name: str) -> str:
    """Return the canonical name (``clamped``/``pinned``/``free``) of ``name``."""
    if not isinstance(name, str):
        raise ConfigError(f"boundary condition must be a string, got {name!r}")
    key = name.strip().lower().replace(" ", "-")
    try:
        return _BC_ALIASES[key]
    except KeyError:
        raise ConfigError(
            f"unknown boundary condition {name!r}; expected one of "
            "'clamped', 'pinned', 'free'"
        ) from None


def canonical_pair(left: str, right: str) -> tuple[str, str]:
    """Order-independent canonical boundary pair, validated.

    The eigenvalues of the beam do not depend on which end is called *left*,
    so the pair is sorted clamped < pinned < free.

    Raises
    ------
    ConfigError
        (a :class:`ValueError`) for unknown names or unsupported pairs.
    """
    a, b = sorted((_canonical_bc(left), _canonical_bc(right)), key=_BC_RANK.__getitem__)
    pair = (a, b)
    if pair not in _SUPPORTED_PAIRS:
        supported = ", ".join(f"{p}-{q}" for p, q in _SUPPORTED_PAIRS)
        raise ConfigError(
            f"boundary-condition pair {left!r}-{right!r} is not supported by the "
            f"analytic reference (pairs with a rigid-body mode, such as free-free "
            f"or pinned-free, are excluded); supported pairs: {supported}"
        )
    return pair


# --------------------------------------------------------------------------
# overflow-safe elementary functions
# --------------------------------------------------------------------------
def _sech(a: Values) -> np.ndarray:
    r""":math:`\operatorname{sech} a = 2e^{-a}/(1 + e^{-2a})` for :math:`a \ge 0` (no overflow)."""
    e = np.exp(-a)
    return 2.0 * e / (1.0 + e * e)


def _tanhc(a: Values) -> np.ndarray:
    r""":math:`\tanh(a)/a`, continued by 1 at :math:`a = 0` (series for small ``a``)."""
    a = np.asarray(a, dtype=float)
    small = np.abs(a) < 1e-4
    safe = np.where(small, 1.0, a)
    a2 = a * a
    return np.where(small, 1.0 - a2 / 3.0 + 2.0 * a2 * a2 / 15.0, np.tanh(safe) / safe)


def _sinc(b: Values) -> np.ndarray:
    r""":math:`\sin(b)/b`, continued by 1 at :math:`b = 0`."""
    return np.sinc(np.asarray(b, dtype=float) / np.pi)


def alpha_from_beta(beta: Values, U: float) -> np.ndarray:
    r""":math:`\alpha = \sqrt{\beta^2 + U}` (clipped at 0 against round-off)."""
    return np.sqrt(np.maximum(beta * beta + U, 0.0))


# --------------------------------------------------------------------------
# scaled characteristic functions g(alpha, beta, U)
# --------------------------------------------------------------------------
def _g_pinned_pinned(alpha: Values, beta: Values, U: float) -> np.ndarray:
    r"""Scaled pinned–pinned determinant.

    The determinant is proportional to
    :math:`(\alpha^2+\beta^2)\sinh\alpha\sin\beta`; divided by
    :math:`(\alpha^2+\beta^2)\,\alpha\beta\cosh\alpha` it becomes
    :math:`(\tanh\alpha/\alpha)\,\operatorname{sinc}\beta`.
    """
    return _tanhc(alpha) * _sinc(beta)


def _g_clamped_clamped(alpha: Values, beta: Values, U: float) -> np.ndarray:
    r"""Scaled clamped–clamped function.

    .. math::

        \frac{2\alpha\beta(1-\cosh\alpha\cos\beta)
              + (\alpha^2-\beta^2)\sinh\alpha\sin\beta}{\alpha\beta\cosh\alpha}
        = 2(\operatorname{sech}\alpha - \cos\beta)
          + U\,\frac{\tanh\alpha}{\alpha}\,\operatorname{sinc}\beta .
    """
    return 2.0 * (_sech(alpha) - np.cos(beta)) + U * _tanhc(alpha) * _sinc(beta)


def _g_clamped_pinned(alpha: Values, beta: Values, U: float) -> np.ndarray:
    r"""Scaled clamped–pinned function.

    .. math::

        \frac{\alpha\sin\beta\cosh\alpha - \beta\cos\beta\sinh\alpha}
             {\alpha\beta\cosh\alpha}
        = \operatorname{sinc}\beta - \cos\beta\,\frac{\tanh\alpha}{\alpha}.
    """
    return _sinc(beta) - np.cos(beta) * _tanhc(alpha)


def _g_clamped_free(alpha: Values, beta: Values, U: float) -> np.ndarray:
    r"""Scaled clamped–free function.

    .. math::

        \frac{2\alpha^2\beta^2 + (\alpha^4+\beta^4)\cos\beta\cosh\alpha
              + \alpha\beta(\alpha^2-\beta^2)\sin\beta\sinh\alpha}
             {(\alpha^4+\beta^4)\cosh\alpha}
        = \cos\beta + \frac{2\alpha^2\beta^2\operatorname{sech}\alpha
              + \alpha\beta\,U\sin\beta\tanh\alpha}{\alpha^4+\beta^4}.

    (:math:`\Omega = 0` is not a root here, so no division by
    :math:`\alpha\beta` is needed.)
    """
    a2 = alpha * alpha
    b2 = beta * beta
    den = a2 * a2 + b2 * b2
    den = np.where(den > 0.0, den, 1.0)
    return np.cos(beta) + (
        2.0 * a2 * b2 * _sech(alpha) + alpha * beta * U * np.sin(beta) * np.tanh(alpha)
    ) / den


CHARACTERISTIC: Mapping[tuple[str, str], CharFun] = MappingProxyType(
    {
        ("pinned", "pinned"): _g_pinned_pinned,
        ("clamped", "clamped"): _g_clamped_clamped,
        ("clamped", "pinned"): _g_clamped_pinned,
        ("clamped", "free"): _g_clamped_free,
    }
)


def characteristic_function(left: str, right: str, U: float, Omega: np.ndarray | float) -> np.ndarray:
    r"""Evaluate the scaled characteristic function at nondimensional ``Omega``.

    Parameters
    ----------
    left, right
        Boundary conditions (``"clamped"``, ``"pinned"``, ``"free"``).
    U
        Nondimensional axial force :math:`N L^2 / EI`.
    Omega
        Nondimensional circular frequency/frequencies :math:`\Omega > 0`.

    Returns
    -------
    numpy.ndarray
        :math:`g(\alpha(\Omega), \beta(\Omega))`; its zeros for
        :math:`\Omega > 0` are the eigenvalues.  See the module docstring for
        the scaling.
    """
    g = CHARACTERISTIC[canonical_pair(left, right)]
    Om = np.asarray(Omega, dtype=float)
    root = np.sqrt(U * U + 4.0 * Om * Om)
    alpha = np.sqrt(np.maximum(0.5 * (U + root), 0.0))
    beta = np.sqrt(np.maximum(0.5 * (-U + root), 0.0))
    return g(alpha, beta, float(U))
