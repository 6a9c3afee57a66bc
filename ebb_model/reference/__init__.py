"""Independent reference solutions and the blind data generator.

* :mod:`.analytic` -- exact natural frequencies of the axially loaded
  Euler–Bernoulli beam from the characteristic equations.
* :mod:`.hermite_fe` -- cubic Hermite finite-element model of the damped,
  axially loaded beam (optionally with rotary inertia and a Winkler
  foundation) with elastic supports, point masses, point forces and point
  sensors.
* :mod:`.newmark_dense` -- dense Newmark time integrator of that model.
* :mod:`.newmark_banded` -- compiled banded Newmark integrator with actuator
  and sensor lags, axial-load drift and geometric stiffening.
* :mod:`.withheld` -- the catalogue of unmodelled effects and
  :class:`WithheldEffect`.
* :mod:`.excitation` -- band-limited multisine / chirp inputs.
* :mod:`.synthetic` -- :func:`synthesize`: synthetic "measured" records with a
  withheld effect, independent of the finite-difference model.
* :mod:`.record` -- :class:`SyntheticRecord`, the generator's result (CSV export).
"""
from __future__ import annotations

from .analytic import U_MAX, analytic_frequencies_hz, analytic_omegas, critical_buckling_U, solve_characteristic
from .characteristic import characteristic_function
from .excitation import EXCITATION_KINDS, band_limited_input
from .hermite_fe import (
    CLAMPED,
    FREE,
    PINNED,
    SENSOR_KINDS,
    HermiteBeam,
    element_matrices,
    hermite_beam,
    hermite_shape_functions,
)
from .newmark_dense import newmark_simulate
from .synthetic import SyntheticRecord, synthesize
from .withheld import EFFECT_CATALOGUE, EFFECT_NAMES, EffectSpec, WithheldEffect

__all__ = [
    "U_MAX",
    "analytic_frequencies_hz",
    "analytic_omegas",
    "characteristic_function",
    "critical_buckling_U",
    "solve_characteristic",
    "CLAMPED",
    "FREE",
    "PINNED",
    "SENSOR_KINDS",
    "HermiteBeam",
    "element_matrices",
    "hermite_beam",
    "hermite_shape_functions",
    "newmark_simulate",
    "EXCITATION_KINDS",
    "band_limited_input",
    "SyntheticRecord",
    "synthesize",
    "EFFECT_CATALOGUE",
    "EFFECT_NAMES",
    "EffectSpec",
    "WithheldEffect",
]
