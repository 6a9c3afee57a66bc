"""The library of candidate unmodelled effects (what the diagnosis can name).

Each :class:`Effect` is an extension of the identified beam model with its own
search variables, bounds and an "off" value at which the model reduces to the
baseline exactly.  Applying an effect to a baseline (config, parameters) gives
an :class:`AugmentedModel`: a config (structural effects are plain config
changes — end springs, a point mass, Kelvin–Voigt damping, rotary inertia, a
Winkler foundation — so the native fast path and the FMU both simulate them)
plus the signal-level and axial-force effects simulated natively by
:mod:`diagnosis.augmented` (actuator/sensor lag, axial-load drift, geometric
stiffening).

Search variables are dimensionless where that makes bounds independent of the
beam at hand (:class:`Scales` carries the beam's own scales); every effect
reports its physical parameters (:meth:`Effect.physical`) in the units of the
catalogue:

=============================  ===================  ==========================================
effect                         physical parameters  search variable (off value)
=============================  ===================  ==========================================
boundary_rotational_<side>     kr [N m/rad]         constrained end: c = EI/(kr L) (0);
                                                    free rotation: s = kr L/EI (0)
boundary_translational_<side>  kt [N/m]             constrained: c = EI/(kt L³) (0);
                                                    free: s = kt L³/EI (0)
point_mass                     mass [kg], x [m]     μ = mass/(ρA L) (0), x
kelvin_voigt                   eta [s]              eta (0)
rotary_inertia                 rhoI [kg m]          r² = rhoI/(ρA L²) (0)
foundation                     kf [N/m²]            κ = kf L⁴/EI (0)
actuator_lag                   tau [s]              tau (0)
sensor_lag[<sensor>]           tau [s]              tau (0)
axial_drift                    rate [N/s]           rate (0, two-sided)
geometric_stiffening           EA [N]               EA (0); only with both ends axially fixed
=============================  ===================  ==========================================
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable, Mapping

import numpy as np

from ebb_model.beam import End, PointMass
from ebb_model.config import BeamConfig

__all__ = ["Scales", "Effect", "AugmentedModel", "Catalogue", "candidate_effects", "pair_effect", "on_top_of",
           "EFFECT_NAMES", "PAIR_SEPARATOR"]

#: Names of the effect families of the catalogue.
EFFECT_NAMES: tuple[str, ...] = (
    "boundary_rotational_left", "boundary_rotational_right",
    "boundary_translational_left", "boundary_translational_right",
    "point_mass", "kelvin_voigt", "rotary_inertia", "foundation",
    "actuator_lag", "sensor_lag", "axial_drift", "geometric_stiffening",
)


@dataclass(frozen=True)
class Scales:
    """Scales of the baseline beam and record that set the effects' search bounds.

    Attributes
    ----------
    EI, rhoA, N, length
        Identified baseline values and beam length.
    omega_low, omega_high
        Lowest and highest modal angular frequency [rad/s] inside the excited band.
    duration
        Length of the fitted record [s].
    stretch_max
        Largest ``∫ w_x² dx`` of the baseline response over the record (for the
        geometric-stiffening bound); 0 when unknown.
    """

    EI: float
    rhoA: float
    N: float
    length: float
    omega_low: float
    omega_high: float
    duration: float
    stretch_max: float = 0.0


@dataclass(frozen=True)
class AugmentedModel:
    """A baseline model with one effect applied, ready for :func:`diagnosis.augmented.simulate_effects`."""

    config: BeamConfig
    params: dict[str, float]
    actuator_tau: float = 0.0
    sensor_tau: Mapping[str, float] = field(default_factory=dict)
    drift_rate: float = 0.0
    stretching_EA: float = 0.0


@dataclass(frozen=True, eq=False)
class Effect:
    """A candidate unmodelled effect.

    Attributes
    ----------
    name
        Catalogue family (one of :data:`EFFECT_NAMES`).
    target
        Sensor name for ``sensor_lag``; ``None`` otherwise.
    variables
        Names of the search variables.
    lower, upper, off
        Bounds and "off" value of each search variable (``off`` lies on a bound
        for one-sided effects, inside for two-sided ones such as drift).
    description
        One line for reports.
    """

    name: str
    target: str | None
    variables: tuple[str, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    off: tuple[float, ...]
    description: str
    _apply: Callable[[BeamConfig, dict[str, float], np.ndarray], AugmentedModel] = field(repr=False)
    _physical: Callable[[np.ndarray], dict[str, float]] = field(repr=False)

    @property
    def label(self) -> str:
        """Unique label, e.g. ``sensor_lag[y2]``."""
        return f"{self.name}[{self.target}]" if self.target else self.name

    @property
    def dim(self) -> int:
        """Number of search variables."""
        return len(self.variables)

    def apply(self, config: BeamConfig, params: Mapping[str, float], s: np.ndarray) -> AugmentedModel:
        """The baseline ``(config, params)`` with this effect at search values ``s``."""
        s = np.asarray(s, dtype=float)
        if s.shape != (self.dim,):
            raise ValueError(f"{self.label}: expected {self.dim} values, got shape {s.shape}")
        return self._apply(config, dict(params), s)

    def physical(self, s: np.ndarray) -> dict[str, float]:
        """Physical parameters (catalogue units) of search values ``s``."""
        return self._physical(np.asarray(s, dtype=float))


# ---------------------------------------------------------------------------
# builders, one per family
# ---------------------------------------------------------------------------
def _with_end(config: BeamConfig, side: str, end: End) -> BeamConfig:
    return replace(config, beam=replace(config.beam, **{side: end}))


def _boundary(config: BeamConfig, sc: Scales, side: str, dof: str) -> Effect:
    end: End = getattr(config.beam, side)
    L, EI = sc.length, sc.EI
    power = 1 if dof == "rotational" else 3
    unit = EI / L ** power              # kr in EI/L, kt in EI/L³
    key = "kr" if dof == "rotational" else "kt"
    fixed = end.rotation_fixed if dof == "rotational" else end.translation_fixed
    base = getattr(end, key)

    if fixed:
        # compliance c = unit/k: 0 is the constrained end, c = 1 is a very soft spring
        def stiffness(s: np.ndarray) -> float:
            return math.inf if s[0] <= 0 else unit / s[0]
        var, hi, what = f"compliance_{key}", (2.0 if dof == "rotational" else 0.5), "compliance of the constraint"
    else:
        def stiffness(s: np.ndarray) -> float:
            return base + unit * s[0]
        var, hi, what = f"{key}_scaled", 500.0, "spring to ground"

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        if s[0] == 0.0:
            return AugmentedModel(cfg, params)
        e: End = getattr(cfg.beam, side)
        kt, kr = e.kt, e.kr
        if key == "kr":
            kr = stiffness(s)
        else:
            kt = stiffness(s)
        return AugmentedModel(_with_end(cfg, side, End.of("elastic", kt, kr)), params)

    def physical(s: np.ndarray) -> dict[str, float]:
        return {key: stiffness(s)}

    return Effect(f"boundary_{dof}_{side}", None, (var,), (0.0,), (hi,), (0.0,),
                  f"{dof} {what} at the {side} end ({end.kind})", apply, physical)


def _point_mass(config: BeamConfig, sc: Scales) -> Effect:
    L = sc.length
    unit = sc.rhoA * L

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        if s[0] == 0.0:
            return AugmentedModel(cfg, params)
        m = PointMass("_diagnosis_mass", float(s[1]), float(s[0] * unit))
        return AugmentedModel(replace(cfg, masses=tuple(cfg.masses) + (m,)), params)

    return Effect("point_mass", None, ("mass_ratio", "x"), (0.0, 0.02 * L), (1.0, 0.98 * L), (0.0, 0.5 * L),
                  "attached point mass (sensor, shaker, load cell, clamp block)", apply,
                  lambda s: {"mass": float(s[0] * unit), "x": float(s[1])})


def _parameter_effect(name: str, param: str, unit: float, hi: float, var: str, description: str) -> Effect:
    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        p = dict(params)
        p[param] = p.get(param, 0.0) + float(s[0]) * unit
        return AugmentedModel(cfg, p)

    return Effect(name, None, (var,), (0.0,), (hi,), (0.0,), description, apply,
                  lambda s: {param: float(s[0] * unit)})


def _actuator_lag(sc: Scales) -> Effect:
    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        return AugmentedModel(cfg, params, actuator_tau=float(s[0]))

    return Effect("actuator_lag", None, ("tau",), (0.0,), (3.0 / sc.omega_high,), (0.0,),
                  "first-order lag between the measured force and the force the beam feels", apply,
                  lambda s: {"tau": float(s[0])})


def _sensor_lag(sc: Scales, sensor: str) -> Effect:
    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        return AugmentedModel(cfg, params, sensor_tau={sensor: float(s[0])})

    return Effect("sensor_lag", sensor, ("tau",), (0.0,), (3.0 / sc.omega_high,), (0.0,),
                  f"first-order lag of sensor {sensor}", apply, lambda s: {"tau": float(s[0])})


def _drift(sc: Scales) -> Effect:
    euler = sc.EI * math.pi ** 2 / sc.length ** 2
    r = euler / max(sc.duration, 1e-12)

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        return AugmentedModel(cfg, params, drift_rate=float(s[0]))

    return Effect("axial_drift", None, ("rate",), (-r,), (r,), (0.0,),
                  "slow drift of the axial load over the record (e.g. thermal)", apply,
                  lambda s: {"rate": float(s[0])})


def _stretching(sc: Scales) -> Effect:
    euler = sc.EI * math.pi ** 2 / sc.length ** 2
    # the stretching force may reach ten Euler loads at the largest response of the record
    hi = 10.0 * euler * 2.0 * sc.length / sc.stretch_max if sc.stretch_max > 0 else 1e12 * sc.EI

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        return AugmentedModel(cfg, params, stretching_EA=float(s[0]))

    return Effect("geometric_stiffening", None, ("EA",), (0.0,), (hi,), (0.0,),
                  "mid-plane stretching: amplitude-dependent axial force EA/(2L)∫w_x²dx", apply,
                  lambda s: {"EA": float(s[0])})


#: Joins the labels of two effects acting at once (``foundation+actuator_lag``).
PAIR_SEPARATOR = "+"


def pair_effect(first: Effect, second: Effect) -> Effect:
    """Two effects at once: ``second`` applied to the model ``first`` made; search variables side by side.

    The physical parameters are keyed ``"<label>.<parameter>"`` (both effects may have a ``tau``).
    """
    if first.name == second.name:
        raise ValueError(f"a pair needs two different effects, got {first.label} twice")
    k = first.dim

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        m1 = first.apply(cfg, params, s[:k])
        m2 = second.apply(m1.config, m1.params, s[k:])
        return AugmentedModel(m2.config, m2.params, actuator_tau=m1.actuator_tau or m2.actuator_tau,
                              sensor_tau={**m1.sensor_tau, **m2.sensor_tau},
                              drift_rate=m1.drift_rate or m2.drift_rate,
                              stretching_EA=m1.stretching_EA or m2.stretching_EA)

    def physical(s: np.ndarray) -> dict[str, float]:
        return ({f"{first.label}.{n}": v for n, v in first.physical(s[:k]).items()}
                | {f"{second.label}.{n}": v for n, v in second.physical(s[k:]).items()})

    return Effect(f"{first.label}{PAIR_SEPARATOR}{second.label}", None,
                  tuple(f"{first.label}.{v}" for v in first.variables)
                  + tuple(f"{second.label}.{v}" for v in second.variables),
                  first.lower + second.lower, first.upper + second.upper, first.off + second.off,
                  f"{first.description}, and {second.description}", apply, physical)


def on_top_of(first: Effect, s_first: np.ndarray, second: Effect) -> Effect:
    """``second`` acting on the model with ``first`` held at ``s_first`` (the score test of a second effect at
    the refit of the first); variables, bounds and label are ``second``'s."""
    pair = pair_effect(first, second)
    s_first = np.asarray(s_first, dtype=float)

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        return pair.apply(cfg, params, np.concatenate([s_first, s]))

    return replace(second, _apply=apply)


@dataclass(frozen=True)
class Catalogue:
    """What :func:`candidate_effects` builds the candidates from — picklable, unlike the effects themselves
    (their maps are closures), so worker processes rebuild the same effects from it.
    """

    config: BeamConfig
    scales: Scales
    identified: tuple[str, ...] = ()

    def effects(self) -> tuple[Effect, ...]:
        """The candidates, in catalogue order."""
        return candidate_effects(self.config, self.scales, identified=self.identified)

    def effect(self, label: str) -> Effect:
        """The candidate called ``label`` (two labels joined by :data:`PAIR_SEPARATOR`: the pair)."""
        if PAIR_SEPARATOR in label:
            first, second = label.split(PAIR_SEPARATOR)
            return pair_effect(self.effect(first), self.effect(second))
        return next(e for e in self.effects() if e.label == label)


def candidate_effects(config: BeamConfig, scales: Scales, *, identified: tuple[str, ...] = ()
                      ) -> tuple[Effect, ...]:
    """The catalogue's effects that can be tested on this set-up.

    Parameters
    ----------
    config
        Baseline set-up (ends, sensors, masses).
    scales
        Beam and record scales (:class:`Scales`) fixing the search bounds.
    identified
        Names of the baseline unknowns: an effect whose parameter is already
        identified (e.g. ``eta``) is not a candidate.

    Returns
    -------
    tuple of Effect
    """
    sc = scales
    L, EI, rhoA = sc.length, sc.EI, sc.rhoA
    out: list[Effect] = []
    for side in ("left", "right"):
        for dof in ("rotational", "translational"):
            out.append(_boundary(config, sc, side, dof))
    out.append(_point_mass(config, sc))
    if "eta" not in identified:
        out.append(_parameter_effect("kelvin_voigt", "eta", 1.0, 0.2 / sc.omega_high, "eta",
                                     "Kelvin–Voigt (strain-rate) damping on top of viscous damping"))
    if "rhoI" not in identified:
        out.append(_parameter_effect("rotary_inertia", "rhoI", rhoA * L ** 2, 0.01, "r2_scaled",
                                     "rotary inertia of the cross-section (Rayleigh beam)"))
    if "kf" not in identified:
        out.append(_parameter_effect("foundation", "kf", EI / L ** 4, 2000.0, "kf_scaled",
                                     "Winkler elastic foundation"))
    out.append(_actuator_lag(sc))
    for s in config.sensors:
        out.append(_sensor_lag(sc, s.name))
    out.append(_drift(sc))
    if config.beam.left.translation_fixed and config.beam.right.translation_fixed:
        out.append(_stretching(sc))
    return tuple(out)
