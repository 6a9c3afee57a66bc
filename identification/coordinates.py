"""The beam's own coordinates for local fits: frequency, level, damping per mass, load per stiffness.

A uniform beam's response depends on EI, ρA, c and N through the frequency scale ``EI/ρA``, the load ratio
``N/EI`` and the damping per mass ``c/ρA`` — and on one more number only, the level: EI, ρA, c and N scaled by
``s`` together scale every output by ``1/s`` and move no frequency.  In the config's own coordinates that level
is a long diagonal valley across EI and ρA whose floor a finite-difference Jacobian cannot follow: its
columns in EI and in ρA are each dominated by the frequency shift (on a lightly damped record a relative change
of 1e-7 in EI/ρA moves the high modes by a tenth of their bandwidth over the record), and the level's column,
their small difference, is lost in their truncation error — a polish started 4 % off the level stops there
with ``xtol`` (measured: χ² 2.9× the optimum's, every method of ``least_squares`` alike).

:class:`BeamCoordinates` fits in ``(log EI/ρA, log ρA, c/ρA, N/EI)`` instead (each where its parameters are
unknowns; the other unknowns as they are): the level is one coordinate, and its column is the exact
``−y`` direction.  The search box is the original box's bounding box in these coordinates; a point of it outside
the original box is clipped back into it (:meth:`BeamCoordinates.to_physical`), so every evaluated candidate
respects the config's bounds.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .least_squares import Box

__all__ = ["BeamCoordinates"]


@dataclass(frozen=True, eq=False)
class BeamCoordinates:
    """The map between the unknowns ``x`` (config's units) and the fitting coordinates ``t`` (module docstring).

    Parameters
    ----------
    names
        The unknowns, in order.
    lower, upper
        Their bounds.
    """

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray

    def _index(self, name: str) -> int | None:
        return self.names.index(name) if name in self.names else None

    @property
    def active(self) -> bool:
        """Whether the map differs from the identity: EI and ρA both unknown and both bounded away from 0."""
        i, j = self._index("EI"), self._index("rhoA")
        return i is not None and j is not None and self.lower[i] > 0 and self.lower[j] > 0

    def to_internal(self, x: np.ndarray) -> np.ndarray:
        """Unknowns → fitting coordinates (rows of a batch alike)."""
        x = np.array(x, dtype=float)
        if not self.active:
            return x
        t = x.copy()
        i, j = self._index("EI"), self._index("rhoA")
        assert i is not None and j is not None
        EI, rhoA = x[..., i], x[..., j]
        t[..., i] = np.log(EI / rhoA)
        t[..., j] = np.log(rhoA)
        c, n = self._index("c"), self._index("N")
        if c is not None:
            t[..., c] = x[..., c] / rhoA
        if n is not None:
            t[..., n] = x[..., n] / EI
        return t

    def to_physical(self, t: np.ndarray) -> np.ndarray:
        """Fitting coordinates → unknowns, clipped into the bounds (rows of a batch alike)."""
        t = np.array(t, dtype=float)
        if not self.active:
            return t
        x = t.copy()
        i, j = self._index("EI"), self._index("rhoA")
        assert i is not None and j is not None
        rhoA = np.exp(t[..., j])
        EI = np.exp(t[..., i]) * rhoA
        x[..., i], x[..., j] = EI, rhoA
        c, n = self._index("c"), self._index("N")
        if c is not None:
            x[..., c] = t[..., c] * rhoA
        if n is not None:
            x[..., n] = t[..., n] * EI
        return np.clip(x, self.lower, self.upper)

    def box(self) -> Box:
        """The bounds' bounding box in the fitting coordinates."""
        if not self.active:
            return Box(self.lower, self.upper)
        corners = np.array(np.meshgrid(*zip(self.lower, self.upper), indexing="ij")).reshape(len(self.names), -1).T
        t = self.to_internal(corners)
        return Box(t.min(axis=0), t.max(axis=0))

    @classmethod
    def of(cls, names: Sequence[str], lower: np.ndarray, upper: np.ndarray) -> "BeamCoordinates":
        """The coordinates of unknowns ``names`` with bounds ``lower``, ``upper``."""
        return cls(tuple(names), np.asarray(lower, float), np.asarray(upper, float))
