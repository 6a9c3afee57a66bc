r"""The catalogue of unmodelled effects, as understood by the blind data generator.

The shared vocabulary of issue 5 (names, parameters, units, "off" values) is
written down here once for :mod:`ebb_model.reference.synthetic`; the diagnosis
library implements the same effects independently on the finite-difference
model.  A :class:`WithheldEffect` names one effect and its parameter values;
it is validated on construction against :data:`EFFECT_CATALOGUE` (unknown
effect or parameter, missing or invalid value -> :class:`~ebb_model.errors.ConfigError`
or its subclass :class:`~ebb_model.errors.ParameterError`).

======================================  =================  =====================================
name                                    parameters         off value
======================================  =================  =====================================
``boundary_rotational_left/right``      ``kr`` [N m/rad]   ``inf`` on a rotation-fixed end, else 0
``boundary_translational_left/right``   ``kt`` [N/m]       ``inf`` on a translation-fixed end, else 0
``point_mass``                          ``mass`` [kg],     ``mass = 0``
                                        ``x`` [m]
``grounded_spring``                     ``k`` [N/m],       ``k = 0``
                                        ``x`` [m]
``stiffness_loss``                      ``x`` [m],         ``factor = 1``
                                        ``length`` [m],
                                        ``factor`` [1]
``kelvin_voigt``                        ``eta`` [s]        0
``rotary_inertia``                      ``rhoI`` [kg m]    0
``foundation``                          ``kf`` [N/m²]      0
``actuator_lag``                        ``tau`` [s]        0
``sensor_lag``                          ``tau`` [s] (+     0
                                        ``sensor`` name)
``axial_drift``                         ``rate`` [N/s]     0
``geometric_stiffening``                ``EA`` [N]         0
======================================  =================  =====================================

Effects *outside* the diagnosis catalogue (:data:`OUTSIDE_CATALOGUE`), for
checking that the diagnosis says "not in the catalogue" instead of naming the
least-bad candidate — all nonlinear, integrated with Newmark:

======================================  =================  =====================================
``cubic_spring``                        ``k3`` [N/m³],     grounded hardening spring
                                        ``x`` [m]          :math:`k_3 w(x)^3`
``dry_friction``                        ``force`` [N],     contact at ``x`` with Coulomb force
                                        ``x`` [m],         :math:`F_c \tanh(\dot w(x)/v_0)`
                                        ``slip`` [m/s]     (``slip`` = :math:`v_0` > 0)
``contact_stop``                        ``k`` [N/m],       a stop the beam hits at ``x`` once it
                                        ``x`` [m],         has moved ``gap`` towards it:
                                        ``gap`` [m]        :math:`k \max(w(x) - g, 0)` (one-sided)
======================================  =================  =====================================
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

from ..errors import ConfigError, ParameterError

__all__ = ["EffectSpec", "EFFECT_CATALOGUE", "EFFECT_NAMES", "OUTSIDE_CATALOGUE", "OUTSIDE_NAMES",
           "WithheldEffect"]


@dataclass(frozen=True)
class EffectSpec:
    """Catalogue entry of one effect.

    Attributes
    ----------
    name
        Effect name.
    parameters
        Parameter names, in order.
    units
        SI unit of each parameter.
    kinds
        Admissible range of each parameter: ``"nonneg"`` (finite, >= 0),
        ``"stiffness"`` (in ``[0, inf]``), ``"real"`` (any finite value).
    description
        One line.
    """

    name: str
    parameters: tuple[str, ...]
    units: tuple[str, ...]
    kinds: tuple[str, ...]
    description: str


def _spec(name: str, params: tuple[tuple[str, str, str], ...], description: str) -> EffectSpec:
    return EffectSpec(
        name,
        tuple(p[0] for p in params),
        tuple(p[1] for p in params),
        tuple(p[2] for p in params),
        description,
    )


#: The canonical catalogue of unmodelled effects (read-only).
EFFECT_CATALOGUE: Mapping[str, EffectSpec] = MappingProxyType(
    {
        s.name: s
        for s in (
            _spec("boundary_rotational_left", (("kr", "N.m/rad", "stiffness"),),
                  "finite rotational spring at x = 0 (replaces a fixed rotation, else added)"),
            _spec("boundary_rotational_right", (("kr", "N.m/rad", "stiffness"),),
                  "finite rotational spring at x = L (replaces a fixed rotation, else added)"),
            _spec("boundary_translational_left", (("kt", "N/m", "stiffness"),),
                  "finite translational spring at x = 0 (replaces a fixed translation, else added)"),
            _spec("boundary_translational_right", (("kt", "N/m", "stiffness"),),
                  "finite translational spring at x = L (replaces a fixed translation, else added)"),
            _spec("point_mass", (("mass", "kg", "nonneg"), ("x", "m", "real")),
                  "extra rigid point mass at x"),
            _spec("grounded_spring", (("k", "N/m", "nonneg"), ("x", "m", "real")),
                  "translational spring from the beam at x to ground (an intermediate support)"),
            _spec("stiffness_loss", (("x", "m", "real"), ("length", "m", "nonneg"), ("factor", "1", "nonneg")),
                  "EI x factor over a segment of the given length centred at x (crack, loose joint)"),
            _spec("kelvin_voigt", (("eta", "s", "nonneg"),),
                  "Kelvin-Voigt strain-rate damping eta*EI*w_xxxxt added to the model's"),
            _spec("rotary_inertia", (("rhoI", "kg.m", "nonneg"),),
                  "rotary inertia of the Rayleigh beam, -(rhoI w_xtt)_x, added to the model's"),
            _spec("foundation", (("kf", "N/m2", "nonneg"),),
                  "Winkler foundation kf*w added to the model's"),
            _spec("actuator_lag", (("tau", "s", "nonneg"),),
                  "every actuator force the beam feels is the measured force through 1/(tau s + 1)"),
            _spec("sensor_lag", (("tau", "s", "nonneg"),),
                  "the named sensor reads the true quantity through 1/(tau s + 1)"),
            _spec("axial_drift", (("rate", "N/s", "real"),),
                  "axial force N(t) = N + rate*t, t from the record start"),
            _spec("geometric_stiffening", (("EA", "N", "nonneg"),),
                  "N(t) = N + EA/(2L) * int_0^L w_x^2 dx (mid-plane stretching)"),
        )
    }
)

#: Effect names, in catalogue order.
EFFECT_NAMES: tuple[str, ...] = tuple(EFFECT_CATALOGUE)

#: Effects the generator knows that the diagnosis catalogue does not (read-only).
OUTSIDE_CATALOGUE: Mapping[str, EffectSpec] = MappingProxyType(
    {
        s.name: s
        for s in (
            _spec("cubic_spring", (("k3", "N/m3", "nonneg"), ("x", "m", "real")),
                  "grounded hardening spring: force k3*w(x)^3 at x"),
            _spec("dry_friction", (("force", "N", "nonneg"), ("x", "m", "real"), ("slip", "m/s", "nonneg")),
                  "dry-friction contact at x: force force*tanh(w_t(x)/slip) against the motion"),
            _spec("contact_stop", (("k", "N/m", "nonneg"), ("x", "m", "real"), ("gap", "m", "nonneg")),
                  "one-sided stop at x: force k*max(w(x) - gap, 0) once the beam has closed the gap "
                  "(a stop, the shaker's body, a loose guide)"),
        )
    }
)

#: Names of the effects outside the diagnosis catalogue.
OUTSIDE_NAMES: tuple[str, ...] = tuple(OUTSIDE_CATALOGUE)


def _lookup(name: object) -> EffectSpec | None:
    if not isinstance(name, str):
        return None
    return EFFECT_CATALOGUE.get(name) or OUTSIDE_CATALOGUE.get(name)


@dataclass(frozen=True)
class WithheldEffect:
    """One unmodelled effect with its parameter values, validated against the catalogue.

    Parameters
    ----------
    name
        Effect name from :data:`EFFECT_CATALOGUE` or :data:`OUTSIDE_CATALOGUE`.
    values
        ``{parameter: value}`` with exactly the catalogue's parameters of the
        effect (stored as a read-only mapping of floats).
    sensor
        Name of the lagged sensor; required for ``sensor_lag`` and not
        allowed for any other effect.  Checked against the config by
        :func:`~ebb_model.reference.synthetic.synthesize`.

    Raises
    ------
    ConfigError
        Unknown effect name, unknown or missing parameter, misplaced
        ``sensor``.
    ParameterError
        A value that is not a number or lies outside its range (e.g. a
        negative time constant, NaN).

    Examples
    --------
    ::

        WithheldEffect("actuator_lag", {"tau": 2e-3})
        WithheldEffect("sensor_lag", {"tau": 1e-3}, sensor="y1")
    """

    name: str
    values: Mapping[str, float] = field(default_factory=dict)
    sensor: str | None = None

    def __post_init__(self) -> None:
        spec = _lookup(self.name)
        if spec is None:
            raise ConfigError(
                f"effect: unknown effect {self.name!r}; allowed: {', '.join(EFFECT_NAMES + OUTSIDE_NAMES)}"
            )
        if not isinstance(self.values, Mapping):
            raise ConfigError(f"effect {self.name}: values must be a mapping, got {type(self.values).__name__}")
        problems = []
        for k in self.values:
            if k not in spec.parameters:
                problems.append(
                    f"effect {self.name}: unknown parameter {k!r}; expected {', '.join(spec.parameters)}"
                )
        for k in spec.parameters:
            if k not in self.values:
                problems.append(f"effect {self.name}: missing parameter {k!r}")
        if problems:
            raise ConfigError(problems)
        clean: dict[str, float] = {}
        bad = []
        for k, kind in zip(spec.parameters, spec.kinds):
            raw = self.values[k]
            if isinstance(raw, bool) or not isinstance(raw, (int, float)):
                bad.append(f"effect {self.name}.{k}: must be a number, got {raw!r}")
                continue
            v = float(raw)
            if math.isnan(v):
                bad.append(f"effect {self.name}.{k}: must be a number, got NaN")
            elif kind == "stiffness" and v < 0.0:
                bad.append(f"effect {self.name}.{k}: must lie in [0, inf], got {v:g}")
            elif kind != "stiffness" and math.isinf(v):
                bad.append(f"effect {self.name}.{k}: must be finite, got {v:g}")
            elif kind == "nonneg" and v < 0.0:
                bad.append(f"effect {self.name}.{k}: must be >= 0, got {v:g}")
            else:
                clean[k] = v
        if bad:
            raise ParameterError(bad)
        if self.name == "sensor_lag":
            if not isinstance(self.sensor, str) or not self.sensor:
                raise ConfigError("effect sensor_lag: sensor (the name of the lagged sensor) is required")
        elif self.sensor is not None:
            raise ConfigError(f"effect {self.name}: 'sensor' is only used by sensor_lag, got {self.sensor!r}")
        object.__setattr__(self, "values", MappingProxyType(clean))

    def __hash__(self) -> int:
        return hash((self.name, tuple(sorted(self.values.items())), self.sensor))

    @property
    def spec(self) -> EffectSpec:
        """The catalogue entry of this effect."""
        spec = _lookup(self.name)
        assert spec is not None   # validated on construction
        return spec

    def __repr__(self) -> str:
        vals = ", ".join(f"{k}={v:g}" for k, v in self.values.items())
        extra = f", sensor={self.sensor!r}" if self.sensor is not None else ""
        return f"WithheldEffect({self.name!r}, {vals}{extra})"
