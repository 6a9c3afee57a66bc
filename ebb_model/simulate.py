"""Simulation of discrete systems: a compiled recursion over arrays.

Two kernels:

* the **modal** recursion for :class:`~ebb_model.theta.modal_form.ModalStateSpace`:
  2×2 real blocks, ``O(n)`` work per sample — the fast path, compiled C specialised for the model's input,
  tap and output counts (:mod:`ebb_model.exact.recursion`);
* the **dense** kernel for a general :class:`~ebb_model.statespace.DiscreteStateSpace`
  (``O(n²)`` per sample, numba, cached on disk after the first call), used when no modal form is available.

A compiled loop earns its place here: the recursion ``x[k+1] = A x[k] + B u[k]`` is
inherently sequential, so NumPy cannot vectorise it, and a Python loop over
20,000 samples costs ~100 ms (``scipy.signal.dlsim``) against ~1 ms compiled.
"""
from __future__ import annotations

import csv
import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numba
import numpy as np

from .arrays import as_matrix
from .acquisition.bandlimited import lead_in
from .acquisition.channel_delay import delay_outputs, with_channel_delays
from .io.output import atomic_path
from .config import BeamConfig
from .space.discretisation import discretise
from .exact.exact_modal import exact_model
from .theta.modal_form import ModalStateSpace, modal_from_beam, modal_from_theta
from .parameter_values import resolve_parameters
from .exact.recursion import FASTMATH, run_modal_recursion
from .statespace import DiscreteStateSpace
from .theta.theta_scheme import discretise_time

__all__ = ["SimulationResult", "simulate", "fast_model", "simulate_config", "simulate_batch"]


@numba.njit(cache=True, nogil=True, fastmath=FASTMATH)
def _dense_kernel(A, B, C, D, x0, u, y):  # pragma: no cover - compiled
    n = A.shape[0]
    ns, ni = u.shape
    no = C.shape[0]
    x = x0.copy()
    xn = np.empty(n)
    for k in range(ns):
        for o in range(no):
            acc = 0.0
            for j in range(n):
                acc += C[o, j] * x[j]
            for i in range(ni):
                acc += D[o, i] * u[k, i]
            y[k, o] = acc
        for r in range(n):
            acc = 0.0
            for j in range(n):
                acc += A[r, j] * x[j]
            for i in range(ni):
                acc += B[r, i] * u[k, i]
            xn[r] = acc
        x[:] = xn


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Sampled outputs of a simulation.

    Attributes
    ----------
    outputs
        Outputs, shape (n_samples, n_outputs).
    output_names
        Names of the output columns.
    dt
        Sample time [s].
    time
        Sample times ``k dt`` [s], shape (n_samples,): formed when first read (an identification simulates
        thousands of candidates and reads none).
    """

    outputs: np.ndarray
    output_names: tuple[str, ...]
    dt: float

    @functools.cached_property
    def time(self) -> np.ndarray:
        """Sample times ``k dt`` [s]."""
        return np.arange(self.outputs.shape[0]) * self.dt

    def __iter__(self):
        """Unpack as ``t, y = result``."""
        return iter((self.time, self.outputs))

    def to_dict(self) -> dict[str, np.ndarray]:
        """Columns by name, ``time`` first."""
        return {"time": self.time} | {n: self.outputs[:, i] for i, n in enumerate(self.output_names)}

    def to_csv(self, path: str | Path, time: np.ndarray | None = None) -> None:
        """Write ``time`` (default :attr:`time`; e.g. the input file's own column) and one column per output
        (written atomically)."""
        times = self.time if time is None else time
        with atomic_path(path) as tmp, tmp.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["time", *self.output_names])
            for t, row in zip(times, self.outputs):
                w.writerow([repr(float(t)), *(repr(float(v)) for v in row)])


def simulate(system: DiscreteStateSpace | ModalStateSpace, u: np.ndarray,
             x0: np.ndarray | None = None) -> SimulationResult:
    """Simulate a discrete system from rest (or from ``x0``) for the input samples ``u``.

    Parameters
    ----------
    system
        A dense or modal discrete system.
    u
        Input samples, shape (n_samples, n_inputs) (1-D allowed for one input);
        ``u[k]`` is held over ``[t_k, t_{k+1})``.
    x0
        Initial state (block state ``(nb, 2)`` flattened for modal systems).
        Default: at rest — zero, or ``−Γ₁ u[0]`` for a first-order-hold
        realisation (``system.hold``, see :mod:`ebb_model.theta.theta_scheme`).  A system that reads its input
        ``system.advance`` samples ahead (the band-limited force) starts that many samples before the record, under
        the record's first sample held (:func:`ebb_model.acquisition.bandlimited.lead_in`): ``x0`` is its state there.

    Returns
    -------
    SimulationResult
        ``y[k] = C x[k] + D u[k]`` at ``t_k = k dt``.
    """
    lead = system.advance if np.size(u) else 0        # outputs before the record (lead_in), dropped
    if isinstance(system, ModalStateSpace):
        u = lead_in(as_matrix(u, "input", shape=(None, system.D.shape[1])), system.advance)
        if x0 is not None:
            z = np.asarray(x0, dtype=float).reshape(system.nblocks, 2)
        elif system.hold is not None and u.shape[0]:
            z = -(system.hold @ u[0])
        else:
            z = np.zeros((system.nblocks, 2))
        y = run_modal_recursion(system.T, system.G, system.Cm, system.D, u, system.delays, z,
                                D_taps=system.feedthrough_taps())[lead:]
        y = delay_outputs(y, system.output_delays)
    else:
        u = lead_in(as_matrix(u, "input", shape=(None, system.ninputs)), system.advance)
        y = np.empty((u.shape[0], system.noutputs))
        if x0 is not None:
            x = np.asarray(x0, dtype=float).reshape(system.nstates)
        elif system.hold is not None and u.shape[0]:
            x = -(system.hold @ u[0])
        else:
            x = np.zeros(system.nstates)
        _dense_kernel(np.ascontiguousarray(system.A), np.ascontiguousarray(system.B),
                      np.ascontiguousarray(system.C), np.ascontiguousarray(system.D), x, u, y)
        y = delay_outputs(y[lead:], system.output_delays)
    return SimulationResult(y, tuple(system.output_names), system.dt)


def fast_model(config: BeamConfig, params: Mapping[str, float] | None = None
               ) -> ModalStateSpace | DiscreteStateSpace:
    """Assemble the fastest reliable realisation of the beam for ``params``.

    ``scheme = "exact"``: :func:`ebb_model.exact.exact_modal.exact_model`.  ``scheme = "theta"``: the seed's
    scheme, by the proportional-damping modal route when it applies (checked numerically), otherwise from the
    eigenvectors of one sub-step (:func:`~ebb_model.theta.modal_form.modal_from_theta`).  Either falls back to the
    dense system (same scheme, ``O(n²)`` per sample) when no well-conditioned block-diagonal form exists, so
    this never raises for want of one.  Stability is **not** checked here (see :func:`ebb_model.assemble`).
    """
    ts = config.time
    p = resolve_parameters(config, params)
    if ts.scheme == "exact":
        return exact_model(config, p)
    beam = discretise(config, p)
    modal = modal_from_beam(beam, ts.dt, ts.theta, ts.substeps, ts.input_hold)
    if modal is None:
        modal = modal_from_theta(beam, ts.dt, ts.theta, ts.substeps, ts.input_hold)
    if modal is None:
        return with_channel_delays(discretise_time(beam, ts.dt, ts.theta, ts.substeps, ts.input_hold), config)
    return with_channel_delays(modal, config)


def simulate_config(config: BeamConfig, u: np.ndarray,
                    params: Mapping[str, float] | None = None) -> SimulationResult:
    """Assemble the beam for ``params`` and simulate it on the fast path."""
    return simulate(fast_model(config, params), u)


def simulate_batch(config: BeamConfig, params: Sequence[Mapping[str, float]] | np.ndarray,
                   u: np.ndarray, *, names: Sequence[str] | None = None) -> np.ndarray:
    """Simulate a batch of parameter sets with the same input.

    Parameters
    ----------
    config
        The set-up (nominal values fill parameters not given).
    params
        Either a sequence of mappings, or an array (n_sets, len(names)).
    u
        Input samples (n_samples, n_inputs).
    names
        Parameter names of the array columns (required with an array).

    Returns
    -------
    numpy.ndarray
        Outputs, shape (n_sets, n_samples, n_outputs).
    """
    if isinstance(params, np.ndarray):
        if names is None:
            raise ValueError("names are required when params is an array")
        if params.ndim != 2 or params.shape[1] != len(names):
            raise ValueError(f"params has shape {params.shape}, expected (n_sets, {len(names)})")
        sets = [dict(zip(names, map(float, row))) for row in params]
    else:
        sets = [dict(p) for p in params]
    u = as_matrix(u, "input", shape=(None, len(config.actuators)))
    out = np.empty((len(sets), u.shape[0], len(config.sensors)))
    for i, p in enumerate(sets):
        out[i] = simulate(fast_model(config, p), u).outputs
    return out
