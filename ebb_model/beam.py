"""Physical description of the beam: geometry, ends, parameters, actuators, sensors.

These are plain immutable values.  Validation of user input happens in
:mod:`ebb_model.config`; the constructors here only normalise.

The model is the axially loaded Euler–Bernoulli beam with viscous and
Kelvin–Voigt damping, rotary inertia (Rayleigh beam) and a Winkler elastic
foundation,

.. math::

    \\rho A\\, w_{tt} - (\\rho I\\, w_{xtt})_x + c\\, w_t + \\eta EI\\, w_{xxxxt} + EI\\, w_{xxxx}
    - N w_{xx} + k_f w
    = \\sum_j f_j(t)\\, \\delta(x - a_j) - \\sum_m m_m w_{tt}(a_m, t)\\, \\delta(x - a_m),

on :math:`0 \\le x \\le L`, with :math:`N > 0` tension, SI units throughout.
``rhoI`` [kg m] and ``kf`` [N/m²] default to 0 (the Euler–Bernoulli beam
without foundation).  With rotary inertia the shear force at an end is
:math:`-EI w_{xxx} + N w_x + \\rho I w_{xtt}` (natural boundary condition of
Hamilton's principle with kinetic energy
:math:`\\tfrac12\\int \\rho A w_t^2 + \\rho I w_{xt}^2\\,dx`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .acquisition.antialias import AntiAlias

__all__ = [
    "PARAMETER_NAMES",
    "PARAMETER_UNITS",
    "PARAMETER_DESCRIPTIONS",
    "END_KINDS",
    "SENSOR_KINDS",
    "SENSOR_UNITS",
    "End",
    "Actuator",
    "Sensor",
    "PointMass",
    "PointSpring",
    "WeakSegment",
]

#: Names of the physical parameters, in the canonical order used everywhere
#: (config files, FMU variables, parameter vectors of the identification).
PARAMETER_NAMES: tuple[str, ...] = ("EI", "rhoA", "c", "eta", "N", "rhoI", "kf")

PARAMETER_UNITS: dict[str, str] = {
    "EI": "N.m2",
    "rhoA": "kg/m",
    "c": "N.s/m2",
    "eta": "s",
    "N": "N",
    "rhoI": "kg.m",
    "kf": "N/m2",
}

PARAMETER_DESCRIPTIONS: dict[str, str] = {
    "EI": "bending stiffness",
    "rhoA": "mass per unit length",
    "c": "viscous damping per unit length",
    "eta": "Kelvin-Voigt (strain-rate) damping time constant",
    "N": "axial force, positive in tension",
    "rhoI": "rotary inertia per unit length (Rayleigh beam), rho times second moment of area",
    "kf": "Winkler elastic foundation stiffness per unit length",
}

#: Boundary conditions an end can have.
END_KINDS: tuple[str, ...] = ("clamped", "pinned", "free", "elastic")

#: Quantities a sensor can measure.
SENSOR_KINDS: tuple[str, ...] = ("displacement", "velocity", "acceleration")

SENSOR_UNITS: dict[str, str] = {
    "displacement": "m",
    "velocity": "m/s",
    "acceleration": "m/s2",
}


@dataclass(frozen=True)
class End:
    """Boundary condition at one end of the beam.

    Every end is modelled as a translational spring ``kt`` [N/m] and a
    rotational spring ``kr`` [N.m/rad] to ground, each in ``[0, inf]``;
    ``inf`` means the motion is constrained.  The named kinds are the limits

    ========  ======  ======
    kind      kt      kr
    ========  ======  ======
    clamped   inf     inf
    pinned    inf     0
    free      0       0
    elastic   given   given
    ========  ======  ======

    The natural boundary conditions at the left end (x = 0) are
    ``EI w'' = kr w'`` and ``EI w''' - N w' = -kt w``; at the right end
    (x = L) the signs of the spring terms flip.
    """

    kind: str
    kt: float = math.inf
    kr: float = math.inf

    @staticmethod
    def of(kind: str, kt: float | None = None, kr: float | None = None) -> "End":
        """Build an end from its kind (and springs for ``elastic``)."""
        if kind == "clamped":
            return End("clamped", math.inf, math.inf)
        if kind == "pinned":
            return End("pinned", math.inf, 0.0)
        if kind == "free":
            return End("free", 0.0, 0.0)
        if kind == "elastic":
            return End("elastic", float(kt if kt is not None else math.inf),
                       float(kr if kr is not None else math.inf))
        raise ValueError(f"unknown end kind {kind!r}; allowed: {', '.join(END_KINDS)}")

    @property
    def translation_fixed(self) -> bool:
        """True when the end cannot translate (``kt = inf``)."""
        return math.isinf(self.kt)

    @property
    def rotation_fixed(self) -> bool:
        """True when the end cannot rotate (``kr = inf``)."""
        return math.isinf(self.kr)


@dataclass(frozen=True)
class Actuator:
    """A point force ``f(t) δ(x - a)`` [N] at position ``x`` [m]."""

    name: str
    x: float
    #: the anti-alias filter the force's record passed (:mod:`ebb_model.acquisition.antialias`; it cancels against the
    #: sensors' identical filters), or ``None``
    antialias: AntiAlias | None = None
    #: the channel's converter delay [s] (:mod:`ebb_model.acquisition.channel_delay`; the sensors' are taken after it)
    delay: float = 0.0


@dataclass(frozen=True)
class Sensor:
    """A point sensor at position ``x`` [m] measuring ``kind``."""

    name: str
    x: float
    kind: str = "displacement"
    #: the acquisition's analog anti-alias filter on this channel (:mod:`ebb_model.acquisition.antialias`), or ``None``
    antialias: AntiAlias | None = None
    #: the channel's converter delay [s]: the record is the quantity ``delay`` late
    #: (:mod:`ebb_model.acquisition.channel_delay`)
    delay: float = 0.0

    @property
    def unit(self) -> str:
        """SI unit of the measured quantity."""
        return SENSOR_UNITS[self.kind]


@dataclass(frozen=True)
class PointMass:
    """A rigid point mass ``mass`` [kg] attached at ``x`` [m] (sensor, shaker, clamp block)."""

    name: str
    x: float
    mass: float


@dataclass(frozen=True)
class PointSpring:
    """A translational spring ``k`` [N/m] from the beam at ``x`` [m] to ground (an intermediate support, a
    shaker's suspension seen through its stinger)."""

    name: str
    x: float
    k: float


@dataclass(frozen=True)
class WeakSegment:
    """A segment of length ``length`` [m] centred at ``x`` [m] whose bending stiffness is ``factor`` × EI
    (``0 < factor <= 1``): a crack, a loose joint, a damaged clamp — a local flexibility of the beam."""

    name: str
    x: float
    length: float
    factor: float

    @property
    def ends(self) -> tuple[float, float]:
        """The segment's start and end [m]."""
        return self.x - 0.5 * self.length, self.x + 0.5 * self.length
