r"""Axial-force perturbations (drift, mid-plane stretching) on the exact-scheme model.

The counterpart of :func:`diagnosis.problem.augmented.simulate_axial` for ``[time] scheme = "exact"``
(:mod:`ebb_model.exact.exact_modal`), so that a candidate effect is simulated with the same accuracy as the
baseline it is compared with.  In the Richardson modes ``q = Ψ η`` of the refined grid the extra axial
force ``δN(t)`` is the modal load

.. math::

    g = -\delta N\,\Psi^T K_g \Psi\,\eta, \qquad
    \delta N = \delta N_0 + \text{rate}\,t + \frac{EA}{2L}\,\eta^T \Psi^T G \Psi\,\eta,

with the refined grid's geometric stiffness ``K_g = ∂K/∂N`` and ``G`` the matrix of ``∫ w_x² dx`` of the
piecewise-linear grid deflection (as :func:`diagnosis.problem.axial_terms.stretch_integral`).  ``g`` enters each
pole's exact one-sample update like a force, linear between samples (the measured force with the config's
input reconstruction, e.g. the cubic); its value at the
end of the sample is predicted with the value at its start and corrected once (trapezoidal accuracy in the
perturbation: ``O(dt²)`` in ``δN``'s effect, which is itself small; the linear time-invariant part stays
exact).  Only the poles the modal load drives or reads run in that loop, with and without it; what it adds to
the outputs is added to the time-invariant model's (:func:`ebb_model.simulate.fast_model`, the compiled
recursion), so with ``δN ≡ 0`` the outputs are exactly the model's (outputs within 5e-15 of the loop over every
pole, in less than half its time on the blind bench).

The perturbation acts on the modes below the Nyquist frequency (the ones a record at this ``dt``
resolves); higher modes respond to the forces only.  A sensor's anti-alias filter
(:mod:`ebb_model.acquisition.antialias`) takes the modal load like the force: its poles appended to the beam's, driven
by both.

Accuracy, measured against re-discretising with ``N + δN`` for a constant ``δN`` (clamped–pinned, 60 nodes,
``dt = 5e-4``, 2–120 Hz): displacement 4e-4 of the effect of ``δN``, acceleration 4e-2 (4e-3 at ``dt/4``:
the load taken as linear between samples is the trapezoidal rule's ``(ω dt)²`` error on the perturbation,
weighted up by the accelerometer's ``ω²``); against the Newmark FE truth with a withheld drift of 40 N/s the
residual falls from 21,639 / 15,010 to 0.19 / 12 noise variances (displacement / acceleration).
"""
from __future__ import annotations

import math
from collections.abc import Mapping

import numba
import numpy as np

from ebb_model.acquisition.antialias import effective_filters, filtered_poles
from ebb_model.acquisition.channel_delay import delay_outputs, effective_delays
from ebb_model.assemble import check_stable
from ebb_model.config import BeamConfig
from ebb_model.space.discretisation import discretise
from ebb_model.errors import StabilityError
from ebb_model.exact.exact_modal import continuous_modes
from ebb_model.acquisition.bandlimited import lead_in
from ebb_model.exact.sample_integrals import ADVANCE, INPUT_TAPS, input_weights, pole_integrals
from ebb_model.space.richardson_pair import refined_config
from ebb_model.parameter_values import resolve_parameters
from ebb_model.simulate import fast_model, simulate

from .axial_terms import geometric_stiffness, stretch_matrix

__all__ = ["simulate_axial_exact"]


@numba.njit(cache=True, nogil=True)
def _modal_load(z, vq_ptr, vq_idx, vq_val, Kg, Gm, dN0, ea_coef, eta, out):  # pragma: no cover - compiled
    """``out = −δN Kg η`` with ``η = Re(Vq z)`` (Vq sparse by rows) and ``δN = δN0 + ea_coef ηᵀ Gm η``."""
    kp = Kg.shape[0]
    for r in range(kp):
        acc = 0.0
        for p in range(vq_ptr[r], vq_ptr[r + 1]):
            acc += (vq_val[p] * z[vq_idx[p]]).real
        eta[r] = acc
    dN = dN0
    if ea_coef != 0.0:
        s = 0.0
        for r in range(kp):
            row = 0.0
            for c in range(kp):
                row += Gm[r, c] * eta[c]
            s += eta[r] * row
        dN += ea_coef * s
    for r in range(kp):
        acc = 0.0
        for c in range(kp):
            acc += Kg[r, c] * eta[c]
        out[r] = -dN * acc


@numba.njit(cache=True, nogil=True)
def _force_drive(k, drive, W, taps, u, c):  # pragma: no cover - compiled
    """The measured force's drive of pole ``c`` over sample ``k``: ``Σ_j W_j (drive u[k + j])`` (``u`` constant
    beyond the record), in the order of the taps."""
    ns, ni = u.shape
    acc = 0.0j
    for t in range(taps.size):
        kk = min(max(k + taps[t], 0), ns - 1)
        f = 0.0j
        for i in range(ni):
            f += drive[c, i] * u[kk, i]
        acc += W[t, c] * f
    return acc


@numba.njit(cache=True, nogil=True)
def _kernel(E, a0, a1, drive, W, taps, bg_ptr, bg_idx, bg_val, vq_ptr, vq_idx, vq_val, Kg, Gm, Cz, Dg, u, dt,
            offset, rate, ea_coef, y):  # pragma: no cover - compiled
    """``y`` = what the perturbation adds to the outputs: the poles it drives or reads run twice, with the modal
    load (``z``) and without (``z0``), and ``y = Re Cz (z − z0) + Dg g``."""
    npole = E.shape[0]
    ns, ni = u.shape
    kp = Kg.shape[0]
    no = Cz.shape[0]
    z = np.zeros(npole, dtype=np.complex128)
    z0 = np.zeros(npole, dtype=np.complex128)
    base = np.empty(npole, dtype=np.complex128)
    zn = np.empty(npole, dtype=np.complex128)
    eta = np.empty(kp)
    g = np.empty(kp)
    g1 = np.empty(kp)
    for k in range(ns):
        _modal_load(z, vq_ptr, vq_idx, vq_val, Kg, Gm, offset + rate * (k * dt), ea_coef, eta, g)
        for o in range(no):
            acc = 0.0
            for c in range(npole):
                acc += (Cz[o, c] * (z[c] - z0[c])).real
            for r in range(kp):
                acc += Dg[o, r] * g[r]
            y[k, o] = acc
        if k + 1 == ns:
            break
        for c in range(npole):
            fg = 0.0j
            for p in range(bg_ptr[c], bg_ptr[c + 1]):
                fg += bg_val[p] * g[bg_idx[p]]
            force = _force_drive(k, drive, W, taps, u, c)
            base[c] = E[c] * z[c] + a0[c] * fg + force
            zn[c] = base[c] + a1[c] * fg            # predictor: g at the end of the sample = g at its start
            z0[c] = E[c] * z0[c] + force
        _modal_load(zn, vq_ptr, vq_idx, vq_val, Kg, Gm, offset + rate * ((k + 1) * dt), ea_coef, eta, g1)
        for c in range(npole):                       # corrector
            fg1 = 0.0j
            for p in range(bg_ptr[c], bg_ptr[c + 1]):
                fg1 += bg_val[p] * g1[bg_idx[p]]
            z[c] = base[c] + a1[c] * fg1


def _rows(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Compressed rows ``(ptr, idx, val)`` of the non-zeros of ``A`` (decoupled modes: two per row)."""
    mask = A != 0
    ptr = np.concatenate([[0], np.cumsum(mask.sum(axis=1))]).astype(np.int64)
    rows, cols = np.nonzero(mask)
    return ptr, cols.astype(np.int64), np.ascontiguousarray(A[rows, cols], dtype=np.complex128)


def simulate_axial_exact(config: BeamConfig, params: Mapping[str, float] | None, u: np.ndarray, *,
                         offset: float = 0.0, rate: float = 0.0, EA: float = 0.0,
                         check_stability: bool = True) -> np.ndarray:
    """Outputs (n_samples, n_sensors) of the exact-scheme beam with the extra axial force ``δN(t)``.

    Arguments as :func:`diagnosis.problem.augmented.simulate_axial` (already validated there); starts at rest.

    Raises
    ------
    StabilityError
        The base model is unstable, or the perturbed simulation diverged.
    """
    p = resolve_parameters(config, params)
    cm = continuous_modes(config, p)
    dt = config.time.dt
    fine = refined_config(config)
    kp = max(1, int(np.count_nonzero(cm.frequencies2 < (math.pi / dt) ** 2)))  # below Nyquist
    psi = cm.shapes[:, :kp]
    k = cm.shapes.shape[1]
    Bg = np.linalg.solve(cm.V, np.vstack([np.zeros((k, kp)), np.eye(k, kp)]))
    fine_beam = discretise(fine, p)
    P = fine_beam.S @ psi
    Dg = np.zeros((len(config.sensors), kp))
    for o, kind in enumerate(fine_beam.sensor_kinds):
        if kind == "acceleration":
            Dg[o] = P[o]
    # the modal load is one more input of the poles (Bg, Dg): the sensors' anti-alias filters in series take it
    # with the measured force (their poles appended, outside the modal load's coordinates Vq)
    m = cm.inputs.shape[1]
    poles, inputs, Cz, D_all, _ = filtered_poles(cm.poles, np.hstack([cm.inputs, Bg]), cm.output_rows(),
                                                 np.hstack([cm.D, Dg]), effective_filters(config))
    drive, Bg, Dg = inputs[:, :m], inputs[:, m:], D_all[:, m:].real
    Vq = np.zeros((kp, poles.size), dtype=complex)
    Vq[:, :cm.poles.size] = cm.V[:kp]
    E, phi0, phi1 = pole_integrals(poles, dt)
    if check_stability:
        check_stable(config, p, float(np.max(np.abs(E))) if E.size else 0.0)
    a0, a1 = phi0 - phi1, phi1                            # the modal load: straight line between samples
    # the measured force's drive of every pole over each sample, with the config's input reconstruction (formed
    # per sample in the kernel)
    _, W = input_weights(poles, dt, config.time.input_hold)
    taps = np.array(INPUT_TAPS[config.time.input_hold], dtype=np.int64)
    Kg = psi.T @ geometric_stiffness(fine, p) @ psi
    Gm = psi.T @ stretch_matrix(fine) @ psi
    # a force read ADVANCE samples ahead starts that many samples before the record, under its first sample held
    # (ebb_model.acquisition.bandlimited.lead_in, as the model's below): those outputs are dropped, the axial force's
    # time kept
    lead = ADVANCE[config.time.input_hold] if u.shape[0] else 0
    y = np.empty((u.shape[0] + lead, len(config.sensors)))
    # the poles the modal load drives or reads (the modes below Nyquist, the filters): the rest respond to the
    # force alone, as in the time-invariant model, whose outputs the perturbation's are added to
    P = np.flatnonzero(np.any(Bg != 0, axis=1) | np.any(Vq != 0, axis=0))
    _kernel(E[P].astype(np.complex128), a0[P].astype(np.complex128), a1[P].astype(np.complex128),
            np.ascontiguousarray(drive[P], dtype=np.complex128), np.ascontiguousarray(W[:, P], dtype=np.complex128),
            taps, *_rows(Bg[P]), *_rows(Vq[:, P]), np.ascontiguousarray(Kg), np.ascontiguousarray(Gm),
            np.ascontiguousarray(Cz[:, P], dtype=np.complex128), np.ascontiguousarray(Dg),
            np.ascontiguousarray(lead_in(u, lead), dtype=float), float(dt),
            float(offset) - float(rate) * lead * float(dt), float(rate),
            float(EA) / (2.0 * config.beam.length), y)
    y = delay_outputs(y[lead:], effective_delays(config))       # the channels' converter delays, as the model's below
    y += simulate(fast_model(config, p), u).outputs
    if check_stability and not np.all(np.isfinite(y)):
        raise StabilityError("the simulation with axial drift/stretching diverged (non-finite outputs): "
                             f"rate = {rate:g} N/s, EA = {EA:g} N, offset = {offset:g} N")
    return y
