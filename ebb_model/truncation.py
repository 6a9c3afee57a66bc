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
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Mapping

import numpy as np

from .config import BeamConfig
from .errors import ConfigError
from .modal_form import ModalStateSpace
from .statespace import DiscreteStateSpace

__all__ = ["in_band", "design_model", "design_modal_model", "static_correction_bound"]


def _block_dc(modal: ModalStateSpace) -> np.ndarray:
    """Each block's gain at ``z = 1`` from the inputs to the outputs, (nb, p, m) (the feedthrough excluded)."""
    m = modal.D.shape[1]
    G = sum(modal.G[:, :, j * m:(j + 1) * m] for j in range(modal.delays + 1))      # (nb, 2, m)
    eye = np.eye(2)
    x = np.linalg.solve(eye[None] - modal.T, G)                                     # (nb, 2, m)
    return np.einsum("pbi,bim->bpm", modal.Cm, x)


def in_band(modal: ModalStateSpace, f_max: float) -> ModalStateSpace:
    """The blocks of ``modal`` with natural frequency at or below ``f_max`` [Hz], in ascending frequency, the
    others as a static correction of ``D`` (module docstring).

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
    keep = np.flatnonzero(f <= f_max)
    keep = keep[np.argsort(f[keep], kind="stable")]
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
    R = np.abs(_block_dc(modal)[drop])                                             # (nd, p, m)
    r2 = (f_hz[:, None] / modal.frequencies_hz[drop][None, :]) ** 2                 # (nf, nd)
    return np.einsum("fb,bpm->fpm", r2 / (1.0 - r2), R)


def design_modal_model(config: BeamConfig, params: Mapping[str, float] | None = None, *,
                       f_max: float | None = None) -> ModalStateSpace | DiscreteStateSpace:
    """:func:`design_model` before its realisation as one StateSpace: the modal form in the band when the model
    has one (its frequency response is cheap, :func:`ebb_model.modal.frequency_response`), else the whole model.

    Raises
    ------
    ConfigError, ParameterError, StabilityError
        As :func:`design_model`.
    """
    from .assemble import assemble, check_stable
    from .exact_modal import exact_model
    from .parameter_values import resolve_parameters

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
    return in_band(model, cut)


def design_model(config: BeamConfig, params: Mapping[str, float] | None = None, *,
                 f_max: float | None = None) -> DiscreteStateSpace:
    """The beam as a discrete StateSpace for control design: the modes up to ``f_max`` (default: the Nyquist
    frequency ``1/(2 dt)``; ``math.inf``: every mode), the rest as a static correction (:func:`in_band`).

    The θ-scheme's model, and an exact model whose modes cannot be diagonalised, are returned whole (their
    blocks carry no continuous frequencies).

    Raises
    ------
    ConfigError
        ``f_max`` not positive.
    ParameterError, StabilityError
        As :func:`ebb_model.assemble.assemble`.
    """
    model = design_modal_model(config, params, f_max=f_max)
    return model if isinstance(model, DiscreteStateSpace) else model.to_statespace()
