"""Units of measured signals: a fixed vocabulary and the conversion to SI.

Every signal of the model is in SI: actuator forces in N, sensor outputs in
m, m/s or m/s2 according to the sensor's ``kind``.  A file may hold other
units (a load cell in lbf, an accelerometer in g); the loader converts them
with the exact factors below.  The vocabulary is fixed (scipy/pyFRF habit):
an unknown unit is an error that lists the allowed ones, and a unit of the
wrong quantity (``g`` for a force) is an error too.

Exact definitions used
----------------------
* 1 lbf = 0.45359237 kg × 9.80665 m/s² = 4.4482216152605 N
  (international avoirdupois pound, standard gravity; NIST SP 811, B.8).
* 1 g_n = 9.80665 m/s² (3rd CGPM, 1901).
* 1 in = 0.0254 m (international yard and pound agreement, 1959).
"""
from __future__ import annotations

from types import MappingProxyType
from typing import Mapping

from ebb_model.beam import SENSOR_UNITS
from ebb_model.errors import DataError

__all__ = [
    "LBF",
    "STANDARD_GRAVITY",
    "UNITS",
    "SI_UNITS",
    "canonical_unit",
    "quantity_of",
    "to_si_factor",
    "si_unit",
]

#: One pound-force in newtons (exact).
LBF = 4.4482216152605
#: Standard acceleration of gravity in m/s² (exact).
STANDARD_GRAVITY = 9.80665

#: unit -> (quantity, factor to the SI unit of that quantity)
UNITS: Mapping[str, tuple[str, float]] = MappingProxyType({
    "N": ("force", 1.0),
    "kN": ("force", 1e3),
    "lbf": ("force", LBF),
    "m": ("displacement", 1.0),
    "mm": ("displacement", 1e-3),
    "um": ("displacement", 1e-6),
    "in": ("displacement", 0.0254),
    "m/s": ("velocity", 1.0),
    "mm/s": ("velocity", 1e-3),
    "in/s": ("velocity", 0.0254),
    "m/s2": ("acceleration", 1.0),
    "mm/s2": ("acceleration", 1e-3),
    "g": ("acceleration", STANDARD_GRAVITY),
    "V": ("voltage", 1.0),
    "mV": ("voltage", 1e-3),
})

#: SI unit of each quantity (sensor units as in :data:`ebb_model.beam.SENSOR_UNITS`).
SI_UNITS: Mapping[str, str] = MappingProxyType({"force": "N", **SENSOR_UNITS, "voltage": "V"})

# Spellings met in file headers (LabVIEW writes "Pounds", "Newtons", "Volts").
# Matched case-insensitively, after the exact vocabulary.
_ALIASES: Mapping[str, str] = MappingProxyType({
    "newton": "N", "newtons": "N",
    "kilonewton": "kN", "kilonewtons": "kN",
    "lb": "lbf", "lbs": "lbf", "pound": "lbf", "pounds": "lbf", "pound-force": "lbf",
    "meter": "m", "meters": "m", "metre": "m", "metres": "m",
    "millimeter": "mm", "millimeters": "mm", "millimetre": "mm", "millimetres": "mm",
    "µm": "um", "μm": "um", "micron": "um", "microns": "um",
    "inch": "in", "inches": "in",
    "m/s^2": "m/s2", "m/s**2": "m/s2", "m/s²": "m/s2", "m s-2": "m/s2",
    "mm/s^2": "mm/s2", "mm/s**2": "mm/s2", "mm/s²": "mm/s2",
    "gs": "g", "g's": "g",
    "volt": "V", "volts": "V", "millivolt": "mV", "millivolts": "mV",
})


def _allowed(quantity: str | None = None) -> str:
    names = [u for u, (q, _) in UNITS.items() if quantity is None or q == quantity]
    return ", ".join(names)


def canonical_unit(unit: str, *, where: str = "unit") -> str:
    """Return the vocabulary spelling of ``unit`` (``"Pounds"`` -> ``"lbf"``).

    Raises
    ------
    DataError
        If the unit is unknown; the message lists the allowed units.
    """
    if not isinstance(unit, str):
        raise DataError(f"{where}: unit must be a string, got {unit!r}; allowed: {_allowed()}")
    u = unit.strip()
    if u in UNITS:
        return u
    alias = _ALIASES.get(u.lower())
    if alias is not None:
        return alias
    raise DataError(f"{where}: unknown unit {unit!r}; allowed: {_allowed()}")


def quantity_of(unit: str, *, where: str = "unit") -> str:
    """The physical quantity measured in ``unit`` (``"force"``, ``"acceleration"``, ...)."""
    return UNITS[canonical_unit(unit, where=where)][0]


def si_unit(quantity: str) -> str:
    """SI unit string of a quantity (``"acceleration"`` -> ``"m/s2"``)."""
    return SI_UNITS[quantity]


def to_si_factor(unit: str, quantity: str, *, where: str = "unit") -> float:
    """Factor that converts values in ``unit`` to the SI unit of ``quantity``.

    Parameters
    ----------
    unit
        Unit of the values in the file (vocabulary of :data:`UNITS`, or a
        header spelling such as ``"Pounds"``).
    quantity
        What the signal is in the model: ``"force"`` for an actuator, the
        sensor's ``kind`` for a sensor.
    where
        Prefix of the error message (file, column, signal).

    Raises
    ------
    DataError
        Unknown unit (listing the allowed ones), or a unit of another
        quantity (listing the units allowed for this one).
    """
    u = canonical_unit(unit, where=where)
    q, factor = UNITS[u]
    if q != quantity:
        raise DataError(f"{where}: unit {unit!r} is a unit of {q}, but the signal is a {quantity}; "
                        f"allowed: {_allowed(quantity)}")
    return factor
