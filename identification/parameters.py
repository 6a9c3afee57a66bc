"""The unknowns of an identification: physical parameters and uncertain positions.

Physical parameters are those of the config's ``[parameters]`` table with
``identify = true`` (bounds required).  Positions of actuators, sensors, point
masses and springs can be unknowns too (real test benches rarely give them
exactly; a support a motor moves has one per set-up), declared in the config's
``[identification]`` table::

    [identification]
    positions = { force = [0.65, 0.75], accel = [0.55, 0.70], roller = [0.02, 0.45] }   # name = [lo, hi] in m

They are named ``x_<name>`` (the config's names are unique).  A spring's stiffness or a point mass's mass can be
an unknown too (a roller's compliance, a transducer whose mass the documents do not give), named ``k_<name>`` and
``m_<name>``::

    [identification]
    sizes = { roller = [1e5, 1e9], accelerometer = [0.0, 0.1] }   # N/m for a spring, kg for a point mass

Positions and sizes change the config's points, not its parameters: an FMU cannot take them as parameters
(:meth:`ParameterSpace.moves_points`).
A candidate vector ``X`` (in the order of
:attr:`ParameterSpace.names`) maps to a config with the positions moved and a
dict of physical parameter values (:meth:`ParameterSpace.apply`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np

from ebb_model.beam import PARAMETER_NAMES, PARAMETER_UNITS
from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError
from ebb_model.parameter_values import ParameterValues, resolve_parameters

from .settings import identification_settings

__all__ = ["ParameterSpace", "parameter_space", "unit"]

#: The prefix of a point's stiffness and mass unknowns, and their units.
SIZE_UNITS = {"k_": "N/m", "m_": "kg"}


def unit(name: str) -> str:
    """The SI unit of unknown ``name``: a parameter's, a position's (m), a spring's stiffness (N/m), a point
    mass's mass (kg)."""
    if name in PARAMETER_UNITS:
        return PARAMETER_UNITS[name]
    return "m" if name.startswith("x_") else SIZE_UNITS.get(name[:2], "")


@dataclass(frozen=True)
class ParameterSpace:
    """Names, bounds and nominal values of the unknowns, in a fixed order."""

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    nominal: np.ndarray

    def __post_init__(self) -> None:
        for k in ("lower", "upper", "nominal"):
            a = np.array(getattr(self, k), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, k, a)

    @property
    def dim(self) -> int:
        """Number of unknowns."""
        return len(self.names)

    def is_position(self, name: str) -> bool:
        """Whether ``name`` is a position unknown (``x_<actuator or sensor>``)."""
        return name.startswith("x_")

    def is_size(self, name: str) -> bool:
        """Whether ``name`` is a spring's stiffness or a point mass's mass (``k_<spring>``, ``m_<mass>``)."""
        return name[:2] in SIZE_UNITS and name not in PARAMETER_UNITS

    def moves_points(self, name: str) -> bool:
        """Whether ``name`` changes the config's points (a position or a size) rather than its parameters."""
        return self.is_position(name) or self.is_size(name)

    def apply(self, config: BeamConfig, x: np.ndarray) -> tuple[BeamConfig, ParameterValues]:
        """Config with moved positions and the physical parameter values of candidate ``x``, resolved once.

        Raises
        ------
        ValueError
            ``x`` has the wrong shape.
        ParameterError
            The candidate's parameter values are not physical (see
            :func:`ebb_model.parameter_values.resolve_parameters`).
        """
        x = np.asarray(x, dtype=float)
        if x.shape != (self.dim,):
            raise ValueError(f"candidate has shape {x.shape}, expected ({self.dim},)")
        params: dict[str, float] = {}
        moves: dict[str, float] = {}
        sizes: dict[str, float] = {}
        for name, v in zip(self.names, x):
            if self.is_position(name):
                moves[name[2:]] = float(v)
            elif self.is_size(name):
                sizes[name] = float(v)
            else:
                params[name] = float(v)
        if moves or sizes:
            config = replace(
                config,
                actuators=tuple(replace(a, x=moves.get(a.name, a.x)) for a in config.actuators),
                sensors=tuple(replace(s, x=moves.get(s.name, s.x)) for s in config.sensors),
                masses=tuple(replace(m, x=moves.get(m.name, m.x), mass=sizes.get(f"m_{m.name}", m.mass))
                             for m in config.masses),
                springs=tuple(replace(k, x=moves.get(k.name, k.x), k=sizes.get(f"k_{k.name}", k.k))
                              for k in config.springs),
            )
        return config, resolve_parameters(config, params)

    def to_dict(self, x: np.ndarray) -> dict[str, float]:
        """``{name: value}`` of a candidate."""
        return {n: float(v) for n, v in zip(self.names, np.asarray(x, dtype=float))}


def parameter_space(config: BeamConfig, *, extra_positions: Mapping[str, tuple[float, float]] | None = None
                    ) -> ParameterSpace:
    """The unknowns declared by ``config`` (``identify = true`` and ``[identification].positions``).

    Raises
    ------
    ConfigError
        No unknowns, bad position bounds, or a position for an unknown name.
    """
    names: list[str] = []
    lo: list[float] = []
    hi: list[float] = []
    nom: list[float] = []
    for k in PARAMETER_NAMES:
        spec = config.parameters[k]
        if spec.identify:
            assert spec.bounds is not None  # guaranteed by the config validation
            names.append(k)
            lo.append(spec.bounds[0])
            hi.append(spec.bounds[1])
            nom.append(spec.value)
    positions = dict(identification_settings(config).positions)
    positions.update(extra_positions or {})
    points = ({a.name: a.x for a in config.actuators} | {s.name: s.x for s in config.sensors}
              | {m.name: m.x for m in config.masses} | {k.name: k.x for k in config.springs})
    problems = []
    for name, b in positions.items():
        where = f"identification.positions.{name}"
        if name not in points:
            problems.append(f"{where}: no actuator, sensor, point mass or spring of that name")
            continue
        if not isinstance(b, (list, tuple)) or len(b) != 2:
            problems.append(f"{where}: must be [lo, hi] in m")
            continue
        a, c = float(b[0]), float(b[1])
        if not (math.isfinite(a) and math.isfinite(c)) or not a < c:
            problems.append(f"{where}: lower bound must be < upper bound, got [{a:g}, {c:g}]")
            continue
        if a < 0 or c > config.beam.length:
            problems.append(f"{where}: [{a:g}, {c:g}] leaves the beam [0, {config.beam.length:g}] m")
            continue
        names.append(f"x_{name}")
        lo.append(a)
        hi.append(c)
        nom.append(min(max(points[name], a), c))
    own = {f"k_{k.name}": k.k for k in config.springs} | {f"m_{m.name}": m.mass for m in config.masses}
    for name, b in identification_settings(config).sizes.items():
        where = f"identification.sizes.{name}"
        key = next((k for k in (f"k_{name}", f"m_{name}") if k in own), None)
        if key is None:
            problems.append(f"{where}: no spring or point mass of that name")
            continue
        if (not isinstance(b, (list, tuple)) or len(b) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in b)):
            problems.append(f"{where}: must be [lo, hi] in {SIZE_UNITS[key[:2]]}")
            continue
        a, c = float(b[0]), float(b[1])
        if not (math.isfinite(a) and math.isfinite(c)) or not 0 <= a < c:
            problems.append(f"{where}: must be 0 <= lower < upper, got [{a:g}, {c:g}]")
            continue
        names.append(key)
        lo.append(a)
        hi.append(c)
        nom.append(min(max(own[key], a), c))
    if problems:
        raise ConfigError(problems)
    if not names:
        raise ConfigError("parameters: nothing to identify (set identify = true with bounds on at least "
                          "one parameter, or give [identification].positions or sizes)")
    return ParameterSpace(tuple(names), np.array(lo), np.array(hi), np.array(nom))
