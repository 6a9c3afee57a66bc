"""The common result of every file reader: named raw channels before mapping and units.

Each reader (CSV, NPZ, MAT, LVM, UFF58) turns a file into a :class:`RawTable`;
the loader then picks the time vector and the configured signals from it,
converts units and checks values.  Keeping this intermediate value small makes
every format obey the same rules and produce the same error messages.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Sequence

import numpy as np

__all__ = ["RawTable", "printed_resolution"]


@dataclass(frozen=True)
class RawTable:
    """Channels of one file, as stored.

    Parameters
    ----------
    source
        The file (for messages).
    kind
        What a channel is called in messages: ``"column"``, ``"variable"``,
        ``"record"``.
    names
        Channel labels in file order (CSV header, LVM heading, NPZ/MAT
        variable, UFF record ``id1``).
    columns
        The raw arrays, one per channel (any shape; checked when used).
    units
        Unit declared by the file for each channel, or ``None``.
    resolution
        Quantum of the printed values of each channel (``10**-decimals`` for a
        text column, ``0.0`` for binary floats): used to recognise a time
        column that is uniform to its printed precision.
    time
        A time vector implied by the format (LVM without X column, UFF58
        abscissa); ``None`` when time is one of the channels.
    time_key
        Default time channel (a name or index) when ``time`` is ``None``.
    time_tolerance
        Maximum error of the stored ``time`` values (``0.0`` if exact).
    unusable
        For each channel, why it cannot be a signal (e.g. "is a frequency
        response, not a time history"), or ``None``; empty = all usable.
    """

    source: str
    kind: str
    names: tuple[str, ...]
    columns: tuple[np.ndarray, ...]
    units: tuple[str | None, ...]
    resolution: tuple[float, ...]
    time: np.ndarray | None = None
    time_key: str | int = "time"
    time_tolerance: float = 0.0
    unusable: tuple[str | None, ...] = ()

    def why_unusable(self, i: int) -> str | None:
        """Reason why channel ``i`` cannot be used, or ``None``."""
        return self.unusable[i] if i < len(self.unusable) else None

    def index(self, key: str | int) -> int | None:
        """Channel index of a name or index; ``None`` if there is no such channel."""
        if isinstance(key, (bool, np.bool_)):
            return None
        if isinstance(key, (int, np.integer)):
            k = int(key)
            return k if 0 <= k < len(self.names) else None
        try:
            return self.names.index(str(key))
        except ValueError:
            return None

    def label(self, i: int) -> str:
        """``"column 'Force'"`` or ``"column 2 ('Force')"``-style label for messages."""
        return f"{self.kind} {self.names[i]!r}"


_NUMBER = re.compile(r"^[+-]?(?:\d*)(?:\.(\d*))?(?:[eEdD]([+-]?\d+))?$")


def printed_resolution(tokens: Sequence[str]) -> float:
    """Largest quantum ``10**(exponent - decimals)`` among printed numbers.

    ``"0.000312"`` has quantum 1e-6, ``"3.12500E-4"`` 1e-9, ``"19"`` 1.
    Tokens that are not plain numbers (``"NaN"``) and zeros printed without
    decimals (``"0"``, as ``%g`` writes them) say nothing about the precision
    and are ignored; ``0.0`` if no token is left.
    """
    res = 0.0
    for tok in tokens:
        m = _NUMBER.match(tok.strip())
        if not m or not any(c.isdigit() for c in tok):
            continue
        if not m.group(1) and float(tok.replace("d", "e").replace("D", "e")) == 0.0:
            continue
        decimals = len(m.group(1) or "")
        exponent = int(m.group(2) or 0)
        res = max(res, 10.0 ** (exponent - decimals))
    return res
