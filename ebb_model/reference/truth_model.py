r"""The truth model of the blind data generator: the withheld effects applied, and the choice of integrator.

:mod:`ebb_model.reference.synthetic` simulates its "measured" records with a
cubic Hermite finite-element model of the beam
(:mod:`ebb_model.reference.hermite_fe`).  This module holds how that truth is
set up from a :class:`~ebb_model.config.BeamConfig`, the physical parameters
and the withheld effects (:mod:`ebb_model.reference.withheld`; the table of
implementations is in :mod:`ebb_model.reference.synthetic`):

* :class:`Truth` -- the truth's model and integrator settings: end springs,
  point masses, springs to ground, ``eta``, ``rhoI``, ``kf`` of the finite-element model, and the
  axial drift, stretching stiffness, lags and local nonlinear element of the
  integrator;
* :func:`apply_effects` -- applies the effects to the config's values;
* :func:`build_beam` -- assembles the Hermite finite-element model and checks
  that the (drifting) axial force does not buckle it within the record;
* :func:`uses_exact` -- chooses the integrator: exact in time
  (:mod:`ebb_model.reference.exact_fe`) for a linear time-invariant truth,
  else Newmark (:mod:`ebb_model.reference.newmark_banded`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence, cast

import numpy as np
import scipy.linalg as sla

from ..config import BeamConfig
from ..errors import ConfigError, ParameterError, StabilityError
from .hermite_fe import HermiteBeam, hermite_beam
from .withheld import WithheldEffect

__all__ = ["LOCAL_ELEMENTS", "Truth", "apply_effects", "build_beam", "uses_exact"]

#: The generator's local nonlinear elements (outside the diagnosis catalogue); one at a time.
LOCAL_ELEMENTS: tuple[str, ...] = ("cubic_spring", "dry_friction", "contact_stop")


@dataclass(frozen=True)
class Truth:
    """The truth's model and integrator settings: the config's and parameters', with the effects applied.

    Attributes
    ----------
    left, right, masses, springs, weak, eta, rhoI, kf
        End springs ``(kt, kr)``, point masses ``(mass, x)``, springs to ground ``(k, x)``, weak segments
        ``(start, end, factor)`` and the parameters of :func:`hermite_beam`.
    rate, ea, act_tau, sen_tau, lag_sensor
        Axial drift rate, ``EA``, actuator and sensor lag time constants, lagged sensor (-1: none).
    local_x, k3, friction, slip, stop_k, stop_gap
        Position of the local nonlinear element — a cubic spring, dry friction or a contact stop (``None``:
        none) —, its ``k3``, friction force and slip velocity, the stop's stiffness and gap.
    """

    left: tuple[float, float]
    right: tuple[float, float]
    masses: list[tuple[float, float]]
    springs: list[tuple[float, float]]
    weak: list[tuple[float, float, float]]
    eta: float
    rhoI: float
    kf: float
    rate: float
    ea: float
    act_tau: float
    sen_tau: float
    lag_sensor: int
    local_x: float | None
    k3: float
    friction: float
    slip: float
    stop_k: float = 0.0
    stop_gap: float = 0.0

    @property
    def local(self) -> bool:
        """Whether the local nonlinear element acts (a zero-sized one is the plain beam)."""
        return self.k3 != 0.0 or self.friction != 0.0 or self.stop_k != 0.0


def _check_not_buckled(beam: HermiteBeam, dn_min: float, N: float, where: str) -> None:
    """Raise :class:`StabilityError` if ``K + dn_min G`` has a negative eigenvalue (w.r.t. ``M``)."""
    K = beam.K + dn_min * cast(np.ndarray, beam.K_axial)  # hermite_beam sets it (the caller checks)
    lam = sla.eigh(K, beam.M, eigvals_only=True, subset_by_index=[0, 0])[0]
    scale = float(np.max(np.abs(np.diag(K)) / np.diag(beam.M)))
    if lam < -1e-9 * scale:
        raise StabilityError(
            f"{where}: the axial force reaches {N + dn_min:g} N, beyond the buckling load of this beam; "
            "the truth is not a small-deflection vibration any more"
        )


def _end_spring(current: float, added: float) -> float:
    """A fixed DOF (``inf``) becomes the spring; a free or elastic DOF gets it added."""
    return added if math.isinf(current) else current + added


def apply_effects(config: BeamConfig, p: Mapping[str, float], effects: Sequence[WithheldEffect]) -> Truth:
    """Apply the withheld ``effects`` (table of :mod:`ebb_model.reference.synthetic`) to ``config`` and ``p``.

    Parameters
    ----------
    config, p, effects
        Beam set-up, checked parameters and effects (as :func:`~ebb_model.reference.synthetic.synthesize`
        checks them).

    Returns
    -------
    Truth

    Raises
    ------
    ConfigError
        ``sensor_lag`` of a sensor not in the config; cubic spring with dry friction.
    ParameterError
        A point mass or local element outside the beam; ``dry_friction.slip <= 0``.
    """
    L = float(config.beam.length)
    ends = {
        "left": [config.beam.left.kt, config.beam.left.kr],
        "right": [config.beam.right.kt, config.beam.right.kr],
    }
    masses = [(m.mass, m.x) for m in config.masses]
    springs = [(sp.k, sp.x) for sp in config.springs]
    weak = [(*w.ends, w.factor) for w in config.weak_segments]
    eta, rhoI, kf = p["eta"], p["rhoI"], p["kf"]
    rate = ea = act_tau = sen_tau = k3 = friction = stop_k = stop_gap = 0.0
    slip = 1.0
    local_x: float | None = None
    lag_sensor = -1
    for e in effects:
        v = e.values
        if e.name.startswith("boundary_"):
            side = "left" if e.name.endswith("_left") else "right"
            i = 1 if "_rotational_" in e.name else 0
            ends[side][i] = _end_spring(ends[side][i], v["kr" if i else "kt"])
        elif e.name == "point_mass":
            if not 0.0 <= v["x"] <= L:
                raise ParameterError(f"effect point_mass.x = {v['x']:g} m lies outside the beam [0, {L:g}] m")
            masses.append((v["mass"], v["x"]))
        elif e.name == "grounded_spring":
            if not 0.0 <= v["x"] <= L:
                raise ParameterError(f"effect grounded_spring.x = {v['x']:g} m lies outside the beam [0, {L:g}] m")
            springs.append((v["k"], v["x"]))
        elif e.name == "stiffness_loss":
            a, b = v["x"] - v["length"] / 2, v["x"] + v["length"] / 2
            if not (0.0 <= a and b <= L and v["length"] > 0.0 and 0.0 < v["factor"] <= 1.0):
                raise ParameterError(f"effect stiffness_loss: the segment {a:g} … {b:g} m must lie inside the beam "
                                     f"[0, {L:g}] m with 0 < factor <= 1 (got {v['factor']:g})")
            weak.append((a, b, v["factor"]))
        elif e.name == "kelvin_voigt":
            eta += v["eta"]
        elif e.name == "rotary_inertia":
            rhoI += v["rhoI"]
        elif e.name == "foundation":
            kf += v["kf"]
        elif e.name == "actuator_lag":
            act_tau = v["tau"]
        elif e.name == "sensor_lag":
            names = config.output_names
            if e.sensor not in names:
                raise ConfigError(
                    f"effect sensor_lag: unknown sensor {e.sensor!r}; the config has {', '.join(names)}"
                )
            lag_sensor = names.index(e.sensor) if v["tau"] > 0.0 else -1
            sen_tau = v["tau"]
        elif e.name == "axial_drift":
            rate = v["rate"]
        elif e.name == "geometric_stiffening":
            ea = v["EA"]
        elif e.name in LOCAL_ELEMENTS:
            if local_x is not None:
                raise ConfigError(f"effect: {', '.join(LOCAL_ELEMENTS)} are not combined (one local element)")
            if not 0.0 <= v["x"] <= L:
                raise ParameterError(f"effect {e.name}.x = {v['x']:g} m lies outside the beam [0, {L:g}] m")
            local_x = v["x"]
            if e.name == "cubic_spring":
                k3 = v["k3"]
            elif e.name == "contact_stop":
                stop_k, stop_gap = v["k"], v["gap"]
            else:
                if not v["slip"] > 0.0:
                    raise ParameterError(f"effect dry_friction.slip must be > 0, got {v['slip']:g}")
                friction, slip = v["force"], v["slip"]
        else:  # pragma: no cover - the catalogue and this dispatch are kept in step by the tests
            raise ConfigError(f"effect {e.name!r} is not implemented by the generator")
    # each end's list is its (kt, kr) pair
    return Truth(left=cast("tuple[float, float]", tuple(ends["left"])),
                 right=cast("tuple[float, float]", tuple(ends["right"])), masses=masses, springs=springs, weak=weak,
                 eta=eta, rhoI=rhoI, kf=kf, rate=rate, ea=ea, act_tau=act_tau, sen_tau=sen_tau, lag_sensor=lag_sensor,
                 local_x=local_x, k3=k3, friction=friction, slip=slip, stop_k=stop_k, stop_gap=stop_gap)


def build_beam(config: BeamConfig, p: Mapping[str, float], truth: Truth, n_elements: int, n_samples: int,
               dt: float) -> HermiteBeam:
    """Assemble the truth's finite-element model and check that the record does not buckle it.

    Parameters
    ----------
    config, p, truth
        Beam set-up, parameters and effect settings.
    n_elements
        Number of cubic Hermite elements.
    n_samples, dt
        Length and sample interval of the record (for the axial drift).

    Returns
    -------
    HermiteBeam

    Raises
    ------
    StabilityError
        The (drifting) axial force exceeds the buckling load.
    """
    beam = hermite_beam(
        float(config.beam.length), int(n_elements), EI=p["EI"], rhoA=p["rhoA"], N=p["N"], c=p["c"], eta=truth.eta,
        left=truth.left, right=truth.right, point_masses=truth.masses, rhoI=truth.rhoI, kf=truth.kf,
        point_springs=truth.springs, weak_segments=truth.weak,
    )
    assert beam.K_axial is not None
    dn_min = min(0.0, truth.rate * (n_samples - 1) * dt)
    _check_not_buckled(beam, dn_min, p["N"], "axial_drift" if dn_min < 0.0 else "parameters.N")
    return beam


def uses_exact(integrator: str, truth: Truth) -> bool:
    """Whether the truth is integrated exactly (``True``) or by Newmark (``False``).

    Parameters
    ----------
    integrator
        ``"auto"``, ``"exact"`` or ``"newmark"``.
    truth
        Effect settings (the time-varying and nonlinear effects need Newmark).

    Raises
    ------
    ConfigError
        A local element combined with axial drift or geometric stiffening.
    ParameterError
        ``"exact"`` for a truth that is not linear time-invariant.
    """
    varying = {"axial_drift": truth.rate != 0.0, "geometric_stiffening": truth.ea != 0.0,
               "cubic_spring": truth.k3 != 0.0, "dry_friction": truth.friction != 0.0,
               "contact_stop": truth.stop_k != 0.0}
    time_varying = [name for name, on in varying.items() if on]
    if truth.local and (truth.rate != 0.0 or truth.ea != 0.0):
        raise ConfigError(f"effect: {'/'.join(LOCAL_ELEMENTS)} are not combined with axial_drift or "
                          "geometric_stiffening")
    if integrator == "exact" and time_varying:
        raise ParameterError(f"integrator 'exact' needs a linear time-invariant truth; {time_varying[0]} is not "
                             "(use 'newmark' or 'auto')")
    return integrator == "exact" or (integrator == "auto" and not time_varying)
