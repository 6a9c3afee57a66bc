r"""Which grid a record needs: each mode's discretisation error in units of its half-power bandwidth.

With damping ratios of a few tenths of a per cent a mode 0.2 % off in frequency is half a half-power
bandwidth ``2ζf`` off, and a lightly damped record shows that as hundreds of noise variances.  So the
yardstick of a grid is not the relative frequency error but the error in bandwidths; a mode is resolved when
it is below :data:`BANDWIDTH_FRACTION`.

Errors are measured against a reference of the same model family that is far more accurate: the
Richardson-extrapolated undamped modes (:func:`ebb_model.space.richardson_pair.richardson_modes`) on grids of ``2R + 1``
and ``4R + 3`` nodes, ``R = max(n, 250)`` (fourth order in ``h``: far below any θ-scheme grid's error, and
below the exact scheme's up to about ``R`` nodes).  The model's own frequencies are

* ``scheme = "exact"``: its Richardson modes (exact in time, so the error is spatial);
* ``scheme = "theta"``: the config grid's FD modes, advanced by the θ-scheme, whose undamped period error
  is known in closed form, ``cos(ω̃τ) = (1 − (½ − θ)(ωτ)²) / (1 + θ(ωτ)²)``.

The recommended grid is found by scaling the error with its order (``h⁴`` exact, ``h²`` and ``τ²`` θ) and
then *checked* the same way, refining further until it passes with a 20 % margin (the damping ratios, and
so the bandwidths, move a little with the grid too).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Mapping

import numpy as np

from ..config import BeamConfig
from ..config.types import MAX_NODES
from .discretisation import discretise
from ..modal.parameter_modes import family_modes
from .richardson_pair import extrapolated, lowest_modes
from ..modal.modal import discrete_frequencies
from ..parameter_values import resolve_parameters

__all__ = ["GridAdvice", "grid_advice", "mode_errors", "BANDWIDTH_FRACTION", "ZETA_FLOOR"]

#: A mode is resolved by the grid when its frequency error is below this fraction of its half-power bandwidth.
BANDWIDTH_FRACTION = 0.05
#: Damping ratio assumed for the bandwidth of an undamped (or nearly undamped) mode.
ZETA_FLOOR = 1e-3
#: Smallest base grid ``R`` of the reference pair (``2R + 1``, ``4R + 3`` nodes).
REFERENCE_NODES = 250


@dataclass(frozen=True)
class GridAdvice:
    """Per mode: frequency [Hz], damping ratio and discretisation error in half-power bandwidths; the config's
    grid and the smallest grid found that resolves every listed mode (``nodes_needed = None``: none up to
    :data:`MAX_NODES`)."""

    frequencies_hz: np.ndarray
    damping_ratios: np.ndarray
    error_bandwidths: np.ndarray
    nodes: int
    substeps: int
    nodes_needed: int | None
    substeps_needed: int

    @property
    def adequate(self) -> bool:
        """Whether the config's grid resolves every listed mode."""
        return bool(np.max(self.error_bandwidths, initial=0.0) <= BANDWIDTH_FRACTION)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {"frequencies_hz": [float(v) for v in self.frequencies_hz],
                "error_bandwidths": [float(v) for v in self.error_bandwidths], "nodes": self.nodes,
                "substeps": self.substeps, "nodes_needed": self.nodes_needed,
                "substeps_needed": self.substeps_needed, "adequate": self.adequate,
                "bandwidth_fraction": BANDWIDTH_FRACTION}

    def summary(self) -> str:
        """One line: adequate, or the grid to use."""
        k = self.frequencies_hz.size
        top = f"modes 1-{k} (to {self.frequencies_hz[-1]:.4g} Hz)"
        if self.adequate:
            return f"grid: adequate for {top} (errors below {BANDWIDTH_FRACTION:.0%} of a half-power bandwidth)"
        worst = f"worst error {np.max(self.error_bandwidths):.2g} bandwidths"
        if self.nodes_needed is None:
            return f"grid: too coarse for {top} ({worst}), and no grid up to {MAX_NODES} nodes resolves them"
        need = f"[beam] nodes >= {self.nodes_needed}"
        if self.substeps_needed > self.substeps:
            need += f" and [time] substeps >= {self.substeps_needed}"
        return f"grid: too coarse for {top} ({worst}); use {need}"


def _reference_omega(config: BeamConfig, p: Mapping[str, float], k: int) -> np.ndarray:
    """Undamped ω of the first ``k`` modes, Richardson over ``2R + 1`` and ``4R + 3`` nodes."""
    n = max(config.beam.nodes, REFERENCE_NODES)
    coarse = discretise(replace(config, beam=replace(config.beam, nodes=2 * n + 1)), p)
    fine = discretise(replace(config, beam=replace(config.beam, nodes=4 * n + 3)), p)
    # the values alone (no shapes: a few values by bisection on these large grids), the fade over the k modes
    w2 = extrapolated(lowest_modes(fine, k, vectors=False), lowest_modes(coarse, k, vectors=False), coarse.x, fine.x, k)
    return np.sqrt(np.abs(w2))


def _space_omega(config: BeamConfig, p: Mapping[str, float], k: int) -> np.ndarray:
    """Undamped ω of the model's first ``k`` modes on the config's grid (exact: Richardson; θ: plain FD)."""
    if config.time.scheme == "exact":                 # exactly the model's modes (its family's, memoised)
        w2 = family_modes(config, p).frequencies2[:k]
    else:
        w2 = lowest_modes(discretise(config, p), k, vectors=False)
    return np.sqrt(np.abs(w2))


def _theta_time_factor(omega: np.ndarray, tau: float, theta: float) -> np.ndarray:
    """``ω̃/ω`` of the undamped θ-scheme (closed form; ``ω̃τ ≤ π``)."""
    x = (omega * tau) ** 2
    c = np.clip((1.0 - (0.5 - theta) * x) / (1.0 + theta * x), -1.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(omega > 0, np.arccos(c) / (omega * tau), 1.0)


def _errors(config: BeamConfig, p: Mapping[str, float], w_ref: np.ndarray, width: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """Spatial and temporal frequency errors, in bandwidths, of the config's grid (temporal 0 for exact)."""
    k = w_ref.size
    w = _space_omega(config, p, k)
    e_space = np.abs(w / w_ref - 1.0) / width
    if config.time.scheme == "exact":
        return e_space, np.zeros(k)
    tau = config.time.dt / config.time.substeps
    return e_space, np.abs(_theta_time_factor(w, tau, config.time.theta) - 1.0) / width


@dataclass(frozen=True)
class _ModeTable:
    """The first modes' frequencies [Hz], damping ratios, half-power bandwidths (relative), the reference's
    undamped ω and the config grid's spatial and temporal errors in bandwidths."""

    f: np.ndarray
    zeta: np.ndarray
    width: np.ndarray
    w_ref: np.ndarray
    e_space: np.ndarray
    e_time: np.ndarray


def _mode_table(config: BeamConfig, p: Mapping[str, float], k: int | None, f_max: float | None) -> _ModeTable:
    """:class:`_ModeTable` of the first ``k`` modes, or of those up to ``f_max`` [Hz] (at least one)."""
    f, zeta = discrete_frequencies(config, p)
    k = int(np.count_nonzero(f <= f_max)) if k is None else k
    k = min(max(k, 1), f.size)
    width = 2.0 * np.maximum(np.nan_to_num(zeta[:k], nan=0.0), ZETA_FLOOR)
    w_ref = _reference_omega(config, p, k)
    e_space, e_time = _errors(config, p, w_ref, width)
    return _ModeTable(f[:k], zeta[:k], width, w_ref, e_space, e_time)


def mode_errors(config: BeamConfig, params: Mapping[str, float] | None, *, k: int | None = None,
                f_max: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The first ``k`` modes' (or those up to ``f_max`` [Hz]) frequencies [Hz], damping ratios, estimated relative
    frequency errors against a converged grid (the reference of the module docstring, space and time) and those
    errors in half-power bandwidths — the yardstick :func:`grid_advice` judges a grid by."""
    t = _mode_table(config, resolve_parameters(config, params), k, f_max)
    err = t.e_space + t.e_time
    return t.f, t.zeta, err * t.width, err


def grid_advice(config: BeamConfig, params: Mapping[str, float] | None = None, *, n_modes: int = 10,
                band_hz: float | None = None) -> GridAdvice:
    """How well the config's grid resolves the modes up to ``band_hz`` (default: the first ``n_modes``),
    and which grid would (see the module docstring)."""
    p = resolve_parameters(config, params)
    t = _mode_table(config, p, None if band_hz is not None else n_modes, band_hz)
    f, zeta, width, w_ref, e_space = t.f, t.zeta, t.width, t.w_ref, t.e_space
    err = t.e_space + t.e_time
    n, m = config.beam.nodes, config.time.substeps
    if np.max(err) <= BANDWIDTH_FRACTION:
        return GridAdvice(f, zeta, err, n, m, n, m)
    # 20 % margin: the damping ratios (bandwidths) move a little with the grid too
    order, allowance = (4, 0.8 * BANDWIDTH_FRACTION) if config.time.scheme == "exact" else (2, 0.4 * BANDWIDTH_FRACTION)
    substeps = m
    if config.time.scheme == "theta":       # closed form: the fewest sub-steps whose period error is allowed
        while substeps < 4096 and np.max(_errors(replace(config, time=replace(config.time, substeps=substeps)),
                                                 p, w_ref, width)[1]) > allowance:
            substeps *= 2
    nodes: int | None = _scaled(n, float(np.max(e_space)) / allowance, order)
    while nodes is not None:                 # check, and refine until it passes
        trial = replace(config, beam=replace(config.beam, nodes=nodes))
        if np.max(_errors(trial, p, w_ref, width)[0]) <= allowance:
            break
        nodes = int(np.ceil(1.25 * (nodes + 1))) - 1
        if nodes > MAX_NODES:
            nodes = None
    return GridAdvice(f, zeta, err, n, m, nodes, substeps)


def _scaled(nodes: int, excess: float, order: int) -> int:
    """Nodes at which an error ``excess`` times the allowed one at ``nodes`` (order ``h^order``) is allowed."""
    if excess <= 1.0:
        return nodes + 1
    return min(int(np.ceil((nodes + 1) * excess ** (1.0 / order))) - 1, MAX_NODES)
