"""Configuration of a beam experiment: TOML in, validated immutable value out.

A config describes the *structural set-up* (length, grid, ends, time step,
actuators, sensors, point masses) and the *physical parameters* with optional
bounds and an ``identify`` flag used by the identification layer::

    [beam]
    length = 1.0            # m
    nodes = 50              # interior grid points
    left = "clamped"        # clamped | pinned | free | elastic (elastic: left_kt, left_kr)
    right = "pinned"
    [time]
    dt = 1e-4               # sample time, s
    theta = 0.25            # theta of the three-level scheme
    substeps = 1            # integer sub-steps per sample
    input = "cubic"         # force between samples: "cubic" through 4 samples (exact scheme's default),
                            # "foh" straight line (theta's default), "zoh" held
    scheme = "exact"        # "exact" (default): Richardson modes, exact in time; "theta": the seed's FD + theta-scheme
    [parameters]            # EI, rhoA required; c, eta, N, rhoI, kf optional (default 0)
    EI   = { value = 10.0, bounds = [1.0, 100.0], identify = true }   # N.m2, > 0
    rhoA = { value = 1.0 }  # kg/m, > 0
    c    = 0.0              # N.s/m2, >= 0: viscous damping
    eta  = 0.0              # s, >= 0: Kelvin-Voigt damping time constant
    N    = 0.0              # N: axial force, > 0 tension
    rhoI = 0.0              # kg.m, >= 0: rotary inertia (Rayleigh beam)
    kf   = 0.0              # N/m2, >= 0: Winkler foundation stiffness
    [[actuators]]
    name = "F1"
    x = 0.3
    [[sensors]]
    name = "y1"
    x = 0.5
    kind = "displacement"
    [[masses]]              # optional point masses
    name = "m1"
    x = 0.9
    mass = 0.05
    [[springs]]             # optional springs to ground (intermediate supports)
    name = "k1"
    x = 0.6
    k = 2.0e4               # N/m, >= 0

Validation reports **every** problem at once (FMPy's ``validate_fmu`` habit),
each naming its field, in one :class:`~ebb_model.errors.ConfigError`.  Values far
beyond any physical beam are refused rather than left to overflow the model:
``length`` in 1e-9 … 1e6 m, ``dt`` at most 1000 s, parameter magnitudes at most
1e30 (``EI``, ``rhoA`` at least 1e-30), a point mass at most 1e12 times the
beam's mass per grid cell and a spring at most 1e12 times a grid cell's bending stiffness ``EI/h³``
(:func:`ebb_model.space.discretisation.discretise`).

This module is the config's public face; the value objects live in :mod:`ebb_model.config.types`, reading
and validation in :mod:`ebb_model.config.validation`.
"""
from __future__ import annotations

from .types import (DEFAULT_INPUT, INPUT_HOLDS, SCHEMES, BeamConfig, BeamGeometry, ParameterSpec,
                           TimeSettings)
# _rebuild_config: configs pickled before BeamConfig pickled itself (e.g. in checkpoints) name it here
from .validation import _rebuild_config, config_from_dict, load_config  # noqa: F401
from ..parameter_values import check_parameter_values

__all__ = [
    "ParameterSpec",
    "BeamGeometry",
    "TimeSettings",
    "BeamConfig",
    "load_config",
    "config_from_dict",
    "check_parameter_values",
    "SCHEMES",
    "INPUT_HOLDS",
    "DEFAULT_INPUT",
]
