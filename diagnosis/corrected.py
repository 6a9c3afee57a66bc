"""The diagnosed model as a product: the baseline with the verdict's effect, refitted, as StateSpace and FMU.

``ebb diagnose`` writes ``DIR/corrected/`` next to ``gap.json`` when its verdict names an effect:

* ``corrected.toml`` — the config with the refitted values: baseline unknowns, and the effect where it is a
  config change (end spring, point mass, Kelvin–Voigt damping, rotary inertia, foundation);
* ``corrected.npz`` — a python-control StateSpace (:mod:`identification.export_statespace`) of the linear
  time-invariant corrected model: the beam, plus the first-order lag of ``actuator_lag`` / ``sensor_lag`` as
  states in series (the same exact discretisation the diagnosis simulates with,
  :func:`diagnosis.augmented.first_order_lag`), so that it reproduces the diagnosis' refit to round-off;
* ``corrected.fmu`` — the pythonfmu FMU of the corrected beam (config changes included; a lag is not part of
  the FMU's model: ``corrected.json`` says so);
* ``corrected.json`` — effect and baseline parameters with units, held-out gap before/after, and which file
  carries what.

Axial drift and geometric stiffening are not time-invariant: they get ``corrected.toml`` (refitted baseline) and
``corrected.json`` only.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ebb_model import DiscreteStateSpace, assemble
from ebb_model.atomic import atomic_path
from ebb_model.jsonio import write_json

from .augmented import lag_coefficients
from .effects import AugmentedModel

__all__ = ["corrected_statespace", "export_corrected"]


def _actuator_lag(sys: DiscreteStateSpace, tau: float) -> DiscreteStateSpace:
    """``sys`` driven through ``1/(τ s + 1)`` on every input (lag first, in series)."""
    a, b0, b1 = lag_coefficients(sys.dt / tau)
    m, n = sys.ninputs, sys.nstates
    eye = np.eye(m)
    # lag: w[k+1] = a w + (a b0 + b1) u[k], f = w + b0 u  (w = f − b0 u)
    A = np.block([[a * eye, np.zeros((m, n))], [sys.B, sys.A]])
    B = np.vstack([(a * b0 + b1) * eye, b0 * sys.B])
    C = np.hstack([sys.D, sys.C])
    D = b0 * sys.D
    gamma1 = sys.hold if sys.hold is not None else np.zeros((n, m))
    hold = np.vstack([-(1.0 - b0) * eye, gamma1])        # at rest: steady lag (f[0] = u[0]), beam as before
    states = tuple(f"lag({u})" for u in sys.input_names) + tuple(sys.state_names)
    return DiscreteStateSpace(A, B, C, D, sys.dt, sys.input_names, sys.output_names, states, hold)


def _sensor_lag(sys: DiscreteStateSpace, sensor: str, tau: float) -> DiscreteStateSpace:
    """``sys`` with output ``sensor`` through ``1/(τ s + 1)`` (in series)."""
    a, b0, b1 = lag_coefficients(sys.dt / tau)
    i = sys.output_names.index(sensor)
    n, m = sys.nstates, sys.ninputs
    ci, di = sys.C[i], sys.D[i]
    A = np.block([[sys.A, np.zeros((n, 1))], [(a * b0 + b1) * ci[None, :], np.array([[a]])]])
    B = np.vstack([sys.B, (a * b0 + b1) * di[None, :]])
    C = np.hstack([sys.C, np.zeros((sys.noutputs, 1))])
    D = sys.D.copy()
    C[i] = np.concatenate([b0 * ci, [1.0]])
    D[i] = b0 * di
    gamma1 = sys.hold if sys.hold is not None else np.zeros((n, m))
    # at rest: the lag starts steady at the sensor's first sample, y[0] = C_i ξ0 + D_i u0 with ξ0 = −Γ1 u0
    hold = np.vstack([gamma1, ((1.0 - b0) * (ci @ gamma1 - di))[None, :]])
    return DiscreteStateSpace(A, B, C, D, sys.dt, sys.input_names, sys.output_names,
                              tuple(sys.state_names) + (f"lag({sensor})",), hold)


def corrected_statespace(model: AugmentedModel) -> DiscreteStateSpace | None:
    """The corrected model as one discrete system, or ``None`` when it is not time-invariant (drift, stretching).

    Raises
    ------
    StabilityError
        The corrected beam is unstable.
    """
    if model.drift_rate != 0.0 or model.stretching_EA != 0.0:
        return None
    sys = assemble(model.config, model.params)
    if model.actuator_tau > 0.0:
        sys = _actuator_lag(sys, model.actuator_tau)
    for sensor, tau in model.sensor_tau.items():
        if tau > 0.0:
            sys = _sensor_lag(sys, sensor, tau)
    return sys


def export_corrected(model: AugmentedModel, out_dir: str | Path, summary: Mapping[str, Any], *,
                     fmu: bool = True, standalone: bool = False) -> list[Path]:
    """Write the corrected model into ``out_dir`` (created); returns the written files (see the module docstring).

    The model files are the export targets of identified models (:data:`identification.export.TARGETS`):
    ``statespace`` (when the corrected model is time-invariant), ``fmu`` and (``standalone``) the standalone C FMU
    (:mod:`fmu_build.standalone`, no Python at run time, ``corrected_standalone.fmu``).  ``summary`` (effect,
    parameters with units, held-out gap) is written to ``corrected.json`` with the list of files and what each
    one carries.
    """
    from ebb_model.tomlio import dumps as toml_dumps
    from identification.export import export_target
    from identification.export_targets import ExportItem

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cfg = model.config.with_parameters(**model.params)
    written = [out / "corrected.toml"]
    with atomic_path(written[0]) as tmp:
        tmp.write_text(toml_dumps(cfg.to_dict()))
    carries: dict[str, str] = {"corrected.toml": "config with the refitted values (structural effects included)"}
    sys = corrected_statespace(model)
    lags = model.actuator_tau > 0.0 or any(t > 0.0 for t in model.sensor_tau.values())
    without_lag = " (without the lag: a signal effect outside the FMU's model)" if lags else ""
    targets = {"statespace": ("corrected.npz", "StateSpace of the corrected model"
                              + (" (lag states in series)" if lags else "")) if sys is not None else None,
               "fmu": ("corrected.fmu", "FMU of the corrected beam" + without_lag) if fmu else None,
               "standalone": ("corrected_standalone.fmu", "standalone C FMU of the corrected beam (no Python at "
                              "run time)" + without_lag) if standalone else None}
    item = ExportItem("corrected", "corrected", cfg, model.params,
                      sys if sys is not None else assemble(model.config, model.params))
    for name, what in targets.items():
        if what is not None:
            written.extend(export_target(name)(item, out))
            carries[what[0]] = what[1]
    if sys is None:
        carries["note"] = ("axial drift and geometric stiffening are not time-invariant: no StateSpace; the FMU "
                           "carries the refitted beam without them")
    written.append(write_json(out / "corrected.json", dict(summary) | {"files": carries}))
    return written
