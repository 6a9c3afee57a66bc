"""The value objects of a beam config: geometry, time settings, parameters, and the :class:`BeamConfig`.

Immutable and validated when made by :func:`ebb_model.config.validation.config_from_dict` (the TOML layout is
described in :mod:`ebb_model.config`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any, Mapping

from ..beam import PARAMETER_NAMES, Actuator, End, PointMass, PointSpring, Sensor, WeakSegment
from ..errors import ParameterError
from ..parameter_values import resolve_parameters

__all__ = ["ParameterSpec", "BeamGeometry", "TimeSettings", "BeamConfig", "SCHEMES", "INPUT_HOLDS",
           "DEFAULT_INPUT"]


@dataclass(frozen=True)
class ParameterSpec:
    """A physical parameter: nominal value, optional search bounds, identify flag, and the standard deviation of
    a Gaussian prior about the nominal value (what the user knows before the data: ``None``, no prior — only
    the bounds)."""

    value: float
    bounds: tuple[float, float] | None = None
    identify: bool = False
    prior_std: float | None = None


@dataclass(frozen=True)
class BeamGeometry:
    """Length [m], number of interior grid points and the two ends."""

    length: float
    nodes: int
    left: End
    right: End


#: Most interior grid points a config may have: the standalone C FMU's dense solvers and the grid advice stop
#: there too, and the modal analysis of ``ebb modes`` takes tens of seconds at this size (its time grows as
#: nodes³).
MAX_NODES = 1000
#: Time-stepping schemes: the seed's FD + θ-scheme, and the accurate realisation of :mod:`ebb_model.exact.exact_modal`.
SCHEMES = ("theta", "exact")
#: Reconstructions of the input between samples (``[time] input``); ``cubic`` and ``bandlimited`` (the samples'
#: band-limited interpolant up to 0.4 fs, :mod:`ebb_model.acquisition.bandlimited`) are the exact scheme's only.
INPUT_HOLDS = ("cubic", "foh", "zoh", "bandlimited")
#: Default ``[time] input`` per scheme: the cubic through four samples for the exact scheme (a band-limited
#: force is smooth; the straight line is 2 % off in amplitude at fs/13), the seed's straight line for θ.
DEFAULT_INPUT = {"exact": "cubic", "theta": "foh"}


@dataclass(frozen=True)
class TimeSettings:
    """Sample time ``dt`` [s], ``theta`` of the three-level scheme, sub-steps per sample, input hold, scheme.

    ``scheme = "exact"`` (default) is :mod:`ebb_model.exact.exact_modal` (two-grid Richardson modes integrated
    exactly over each sample; ``theta`` and ``substeps`` do not apply); ``scheme = "theta"`` is the seed's
    FD + θ-scheme (``theta`` and ``substeps`` apply, with its Bistritz stability analysis).
    ``input_hold`` (``[time] input``) is the force between samples, :data:`DEFAULT_INPUT` per scheme.
    """

    dt: float
    theta: float = 0.25
    substeps: int = 1
    input_hold: str = "cubic"
    scheme: str = "exact"


@dataclass(frozen=True)
class BeamConfig:
    """A complete, validated beam set-up.  Immutable; use :meth:`with_parameters`."""

    beam: BeamGeometry
    time: TimeSettings
    parameters: Mapping[str, ParameterSpec]
    actuators: tuple[Actuator, ...]
    sensors: tuple[Sensor, ...]
    masses: tuple[PointMass, ...] = ()
    springs: tuple[PointSpring, ...] = ()
    weak_segments: tuple[WeakSegment, ...] = ()
    extra: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))

    # ------------------------------------------------------------------ access
    def parameter_values(self) -> dict[str, float]:
        """Nominal parameter values ``{"EI": ..., "rhoA": ..., ...}``."""
        return {k: self.parameters[k].value for k in PARAMETER_NAMES}

    @property
    def input_names(self) -> tuple[str, ...]:
        """Actuator names, in order (the model's inputs)."""
        return tuple(a.name for a in self.actuators)

    @property
    def output_names(self) -> tuple[str, ...]:
        """Sensor names, in order (the model's outputs)."""
        return tuple(s.name for s in self.sensors)

    def with_parameters(self, **values: float) -> "BeamConfig":
        """Return a copy with new nominal parameter values (validated)."""
        unknown = sorted(set(values) - set(PARAMETER_NAMES))
        if unknown:
            raise ParameterError(
                [f"parameters.{k}: unknown parameter; allowed: {', '.join(PARAMETER_NAMES)}" for k in unknown]
            )
        merged = resolve_parameters(self, {k: float(v) for k, v in values.items()})
        params = {k: replace(self.parameters[k], value=merged[k]) for k in PARAMETER_NAMES}
        return replace(self, parameters=MappingProxyType(params))

    # ----------------------------------------------------------- serialisation
    def __getstate__(self) -> dict[str, Any]:
        """The fields, the read-only mappings as dicts (mapping proxies do not pickle)."""
        return {k: dict(v) if isinstance(v, MappingProxyType) else v for k, v in self.__dict__.items()}

    def __setstate__(self, state: Mapping[str, Any]) -> None:
        for k, v in state.items():
            object.__setattr__(self, k, MappingProxyType(v) if k in ("parameters", "extra") else v)

    def to_dict(self) -> dict[str, Any]:
        """JSON/TOML-serialisable dict; :func:`config_from_dict` inverts it.

        Infinite spring stiffnesses are written as the string ``"inf"``
        (JSON has no infinity).
        """

        def num(v: float) -> float | str:
            return "inf" if math.isinf(v) else v

        beam: dict[str, Any] = {
            "length": self.beam.length,
            "nodes": self.beam.nodes,
            "left": self.beam.left.kind,
            "right": self.beam.right.kind,
        }
        for side, end in (("left", self.beam.left), ("right", self.beam.right)):
            if end.kind == "elastic":
                beam[f"{side}_kt"] = num(end.kt)
                beam[f"{side}_kr"] = num(end.kr)
        params: dict[str, Any] = {}
        for k in PARAMETER_NAMES:
            p = self.parameters[k]
            d: dict[str, Any] = {"value": p.value}
            if p.bounds is not None:
                d["bounds"] = list(p.bounds)
            if p.identify:
                d["identify"] = True
            if p.prior_std is not None:
                d["prior_std"] = p.prior_std
            params[k] = d
        time = {"dt": self.time.dt, "theta": self.time.theta, "substeps": self.time.substeps,
                "scheme": self.time.scheme}
        if self.time.input_hold != DEFAULT_INPUT[self.time.scheme]:   # the default follows the scheme
            time["input"] = self.time.input_hold
        out: dict[str, Any] = {
            "beam": beam,
            "time": time,
            "parameters": params,
            "actuators": [{"name": a.name, "x": a.x,
                           **({} if a.antialias is None else {"antialias": a.antialias.to_dict()}),
                           **({"delay": a.delay} if a.delay else {})}
                          for a in self.actuators],
            "sensors": [{"name": s.name, "x": s.x, "kind": s.kind,
                         **({} if s.antialias is None else {"antialias": s.antialias.to_dict()}),
                         **({"delay": s.delay} if s.delay else {})}
                        for s in self.sensors],
        }
        if self.masses:
            out["masses"] = [{"name": m.name, "x": m.x, "mass": m.mass} for m in self.masses]
        if self.springs:
            out["springs"] = [{"name": k.name, "x": k.x, "k": k.k} for k in self.springs]
        if self.weak_segments:
            out["weak_segments"] = [{"name": w.name, "x": w.x, "length": w.length, "factor": w.factor}
                                    for w in self.weak_segments]
        for k, v in self.extra.items():
            out[k] = v
        return out
