r"""Models for control design: the modes in a band, the others as a static correction (residual flexibility).

The simulation keeps every mode of the grid: sampled exactly, the modes above the Nyquist frequency still add
their (small, quasi-static) share to every sample.  A control designer's discrete model must not show them as
poles: a mode at 14 kHz sampled at 2 kHz folds to an alias inside the band, a lightly damped "resonance" that
the beam does not have.  :func:`in_band` keeps the blocks of the modal form whose continuous natural frequency
lies at or below ``f_max`` and replaces each dropped block by its gain at ``z = 1``:

.. math::  D \leftarrow D + \sum_{b\ \text{dropped}} C_b (I - T_b)^{-1} \sum_j G_{b,j},

so the DC gain is the full model's exactly and, below the cut, the response differs from it by what a dropped
mode adds beyond its static deflection: for a mode at ``f_b`` with static gain ``R_b`` about
``|R_b| r²/(1 − r²)``, ``r = f/f_b`` (:func:`static_correction_bound`).  States are named by mode
(``mode1_re``, ``mode1_im``, … in ascending frequency).

Below the cut the top modes are the grid's more than the beam's: on a 50-node grid sampled at 10 kHz the modes
from 3 kHz on are 1–3 % off the converged beam's.  A design model keeps only the modes its grid resolves —
frequency error against a converged grid (:func:`ebb_model.space.grid_advice.mode_errors`) within ``error_limit``
half-power bandwidths, by default :data:`~ebb_model.space.grid_advice.BANDWIDTH_FRACTION`, the yardstick the grid
advice judges a grid by — and puts the others into the static correction too (:func:`mode_resolution` says
which, with each kept mode's error estimate, and the grid that would keep them all).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Mapping

import numpy as np

from ..config import BeamConfig
from ..errors import ConfigError
from ..space.grid_advice import BANDWIDTH_FRACTION
from ..theta.modal_form import ModalStateSpace
from ..statespace import DiscreteStateSpace

__all__ = ["ModeResolution", "in_band", "design_model", "design_modal_model", "design_resolution",
           "mode_resolution", "static_correction_bound"]


@dataclass(frozen=True)
class ModeResolution:
    """The modes up to a design model's cut, ascending: frequency [Hz], damping ratio, estimated relative
    frequency error against a converged grid and that error in half-power bandwidths; a mode is kept when its
    error is within ``error_limit`` bandwidths (:attr:`kept`)."""

    frequencies_hz: np.ndarray
    damping_ratios: np.ndarray
    relative_errors: np.ndarray
    error_bandwidths: np.ndarray
    cut_hz: float
    error_limit: float
    nodes: int

    @property
    def kept(self) -> np.ndarray:
        """Which modes the design model keeps (bool, one per mode)."""
        return self.error_bandwidths <= self.error_limit

    def to_dict(self) -> dict[str, Any]:
        """JSON values: every mode up to the cut with its error estimate and whether it is kept."""
        return {"cut_hz": self.cut_hz, "error_limit_bandwidths": self.error_limit, "nodes": self.nodes,
                "modes": [{"mode": i + 1, "frequency_hz": float(f), "damping_ratio": float(z),
                           "relative_error_estimate": float(e), "error_bandwidths": float(b), "kept": bool(k)}
                          for i, (f, z, e, b, k) in enumerate(zip(self.frequencies_hz, self.damping_ratios,
                                                                  self.relative_errors, self.error_bandwidths,
                                                                  self.kept))],
                "summary": self.summary()}

    def summary(self) -> str:
        """One line: how many modes are kept, and why the others are not."""
        n, kept = self.frequencies_hz.size, self.kept
        head = f"{int(kept.sum())} of the {n} modes up to {self.cut_hz:.4g} Hz kept"
        if kept.all():
            return head + f" (each resolved by the {self.nodes}-node grid within {self.error_limit:g} of a " \
                          "half-power bandwidth)"
        f, e = self.frequencies_hz[~kept], np.abs(self.relative_errors[~kept])
        return (head + f"; {int((~kept).sum())} ({f.min():.4g}–{f.max():.4g} Hz, frequency errors "
                f"{100 * e.min():.2g}–{100 * e.max():.2g} %) are not resolved by the {self.nodes}-node grid within "
                f"{self.error_limit:g} of a half-power bandwidth and are in the static correction (the grid that "
                f"keeps them: `ebb modes CONFIG --band {self.cut_hz:.4g}`)")


def design_resolution(config: BeamConfig, params: Mapping[str, float] | None = None, *,
                      f_max: float | None = None) -> ModeResolution | None:
    """:func:`mode_resolution` for a design model that chooses its modes by it (the exact scheme, a finite cut);
    ``None`` otherwise (the θ-scheme's model and ``f_max = math.inf`` keep every mode)."""
    if config.time.scheme != "exact" or (f_max is not None and math.isinf(f_max)):
        return None
    return mode_resolution(config, params, f_max=f_max)


def mode_resolution(config: BeamConfig, params: Mapping[str, float] | None = None, *, f_max: float | None = None,
                    error_limit: float = BANDWIDTH_FRACTION, modes: int | None = None) -> ModeResolution:
    """Which modes up to ``f_max`` (default the Nyquist frequency) the config's grid resolves within
    ``error_limit`` half-power bandwidths, with each one's error estimate (module docstring); ``modes``: how many
    modes lie below the cut when the caller has counted them already.

    Raises
    ------
    ConfigError
        ``error_limit`` not positive.
    """
    from ..space.grid_advice import mode_errors

    if not error_limit > 0:
        raise ConfigError(f"the modes' error limit must be > 0 half-power bandwidths, got {error_limit!r}")
    cut = 0.5 / config.time.dt if f_max is None else f_max
    if modes == 0:
        empty = np.zeros(0)
        return ModeResolution(empty, empty, empty, empty, float(cut), float(error_limit), config.beam.nodes)
    f, zeta, rel, bw = mode_errors(config, params, k=modes, f_max=cut)
    if modes is None and f[0] > cut:                  # no mode below the cut (mode_errors lists one at least)
        return ModeResolution(f[:0], zeta[:0], rel[:0], bw[:0], float(cut), float(error_limit), config.beam.nodes)
    return ModeResolution(f, zeta, rel, bw, float(cut), float(error_limit), config.beam.nodes)


def _block_dc(modal: ModalStateSpace) -> np.ndarray:
    """Each block's gain at ``z = 1`` from the inputs to the outputs, (nb, p, m) (the feedthrough excluded)."""
    m = modal.D.shape[1]
    G = sum(modal.G[:, :, j * m:(j + 1) * m] for j in range(modal.delays + 1))      # (nb, 2, m)
    eye = np.eye(2)
    x = np.linalg.solve(eye[None] - modal.T, G)                                     # (nb, 2, m)
    return np.einsum("pbi,bim->bpm", modal.Cm, x)


def in_band(modal: ModalStateSpace, f_max: float, resolved: np.ndarray | None = None) -> ModalStateSpace:
    """The blocks of ``modal`` with natural frequency at or below ``f_max`` [Hz], in ascending frequency, the
    others as a static correction of ``D`` (module docstring); ``resolved`` (bool, one per mode up to ``f_max``,
    ascending: :attr:`ModeResolution.kept`) drops the modes the grid does not resolve there too.

    Raises
    ------
    ConfigError
        ``modal`` does not know its modes' frequencies, or ``f_max`` is not positive.
    """
    if modal.frequencies_hz is None:
        raise ConfigError("in_band: the modal form does not know its modes' frequencies (exact scheme only)")
    if not f_max > 0:
        raise ConfigError(f"in_band: the cut-off frequency must be > 0 Hz, got {f_max!r}")
    f = modal.frequencies_hz
    modes = f.size - modal.filters                        # the anti-alias filters' blocks are kept as they are
    keep = np.flatnonzero(f[:modes] <= f_max)
    keep = keep[np.argsort(f[keep], kind="stable")]
    if resolved is not None:
        resolved = np.asarray(resolved, dtype=bool)
        if resolved.size != keep.size:
            raise ConfigError(f"in_band: {resolved.size} resolution flags for the {keep.size} modes up to "
                              f"{f_max:.4g} Hz")
        keep = keep[resolved]
    keep = np.concatenate([keep, np.arange(modes, f.size)])
    drop = np.setdiff1d(np.arange(f.size), keep)
    D = modal.D + _block_dc(modal)[drop].sum(axis=0) if drop.size else modal.D.copy()
    return replace(modal, T=modal.T[keep], G=modal.G[keep], Cm=modal.Cm[:, keep], D=D,
                   hold=None if modal.hold is None else modal.hold[keep], to_nodal=None,
                   frequencies_hz=f[keep])


def static_correction_bound(modal: ModalStateSpace, f_max: float, f_hz: np.ndarray) -> np.ndarray:
    """What the static correction of :func:`in_band` may miss at ``f_hz`` (below the cut), per output and input:
    ``Σ_b |R_b| r²/(1 − r²)`` over the dropped modes, ``r = f/f_b`` — the undamped continuous mode's response
    beyond its static deflection.  Shape (len(f_hz), p, m)."""
    if modal.frequencies_hz is None:
        raise ConfigError("static_correction_bound: the modal form does not know its modes' frequencies")
    f_hz = np.atleast_1d(np.asarray(f_hz, dtype=float))
    drop = modal.frequencies_hz > f_max
    drop[drop.size - modal.filters:] = False              # the filters' blocks are never dropped
    R = np.abs(_block_dc(modal)[drop])                                             # (nd, p, m)
    r2 = (f_hz[:, None] / modal.frequencies_hz[drop][None, :]) ** 2                 # (nf, nd)
    return np.einsum("fb,bpm->fpm", r2 / (1.0 - r2), R)


def design_modal_model(config: BeamConfig, params: Mapping[str, float] | None = None, *,
                       f_max: float | None = None, error_limit: float = BANDWIDTH_FRACTION,
                       resolution: ModeResolution | None = None) -> ModalStateSpace | DiscreteStateSpace:
    """:func:`design_model` before its realisation as one StateSpace: the modal form in the band when the model
    has one (its frequency response is cheap, :func:`ebb_model.modal.modal.frequency_response`), else the whole model.

    Raises
    ------
    ConfigError, ParameterError, StabilityError
        As :func:`design_model`.
    """
    from ..assemble import assemble, check_stable
    from ..acquisition.bandlimited import causal_config
    from ..exact.exact_modal import exact_model
    from ..parameter_values import resolve_parameters

    config = causal_config(config)                # a design model is driven sample by sample
    if f_max is not None and not f_max > 0:
        raise ConfigError(f"the cut-off frequency must be > 0 Hz, got {f_max!r}")
    cut = 0.5 / config.time.dt if f_max is None else f_max
    if math.isinf(cut) or config.time.scheme != "exact":
        return assemble(config, params)
    p = resolve_parameters(config, params)
    model = exact_model(config, p)
    check_stable(config, p, model.spectral_radius())
    if isinstance(model, DiscreteStateSpace) or model.frequencies_hz is None:
        return model
    if resolution is None and math.isinf(error_limit):
        return in_band(model, cut)
    n_band = int(np.count_nonzero(model.frequencies_hz[:model.nblocks - model.filters] <= cut))
    if resolution is None or resolution.kept.size != n_band:   # (a neighbour's: a mode crossed the cut)
        limit = error_limit if resolution is None else resolution.error_limit
        resolution = mode_resolution(config, p, f_max=cut, error_limit=limit, modes=n_band)
    return in_band(model, cut, resolution.kept)


def design_model(config: BeamConfig, params: Mapping[str, float] | None = None, *,
                 f_max: float | None = None, error_limit: float = BANDWIDTH_FRACTION,
                 resolution: ModeResolution | None = None) -> DiscreteStateSpace:
    """The beam as a discrete StateSpace for control design: the modes up to ``f_max`` (default: the Nyquist
    frequency ``1/(2 dt)``; ``math.inf``: every mode) that the grid resolves within ``error_limit`` half-power
    bandwidths (``math.inf``: every one; ``resolution``: as :func:`mode_resolution` found them — at these
    parameters or at neighbouring ones, whose choice of modes is kept when it counts as many below the cut), the
    rest as a static correction (:func:`in_band`).

    The θ-scheme's model, and an exact model whose modes cannot be diagonalised, are returned whole (their
    blocks carry no continuous frequencies).

    Raises
    ------
    ConfigError
        ``f_max`` not positive.
    ParameterError, StabilityError
        As :func:`ebb_model.assemble.assemble`.
    """
    model = design_modal_model(config, params, f_max=f_max, error_limit=error_limit, resolution=resolution)
    return model if isinstance(model, DiscreteStateSpace) else model.to_statespace()
