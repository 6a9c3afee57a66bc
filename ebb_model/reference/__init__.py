"""Independent reference solutions for validating the finite-difference beam model.

* :mod:`.analytic` -- exact natural frequencies of the axially loaded
  Euler–Bernoulli beam from the characteristic equations.
* :mod:`.hermite_fe` -- cubic Hermite finite-element model of the damped,
  axially loaded beam with elastic supports, point masses, point forces and
  point sensors, plus a Newmark time integrator.
"""
from __future__ import annotations

from .analytic import (
    U_MAX,
    analytic_frequencies_hz,
    analytic_omegas,
    characteristic_function,
    critical_buckling_U,
    solve_characteristic,
)
from .hermite_fe import (
    CLAMPED,
    FREE,
    PINNED,
    SENSOR_KINDS,
    HermiteBeam,
    element_matrices,
    hermite_beam,
    hermite_shape_functions,
    newmark_simulate,
)

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
]
