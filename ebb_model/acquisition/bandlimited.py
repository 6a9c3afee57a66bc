r"""A band-limited force between samples: the reconstruction a DAQ's records call for.

What a data acquisition records is band-limited: the same anti-alias filter sits on every channel, the analysis
band ends at ``fs/2.56`` by the modal-test convention, and a shaker fed band-limited noise puts nothing above it.
The signal between the samples is then fixed by the samples up to the band edge (Whittaker–Shannon), and a
polynomial through a few samples is not it: the cubic's amplitude error grows as ``(f/fs)⁴`` and at ``0.2 fs``
leaves several noise variances on an accelerometer record at the true parameters.

The reconstruction here is ``u(t) = Σ_j u_j φ(t/T − j)`` with a Kaiser-windowed sinc

.. math::

    φ(t) = \operatorname{sinc}(t)\, \frac{I_0\!\left(β\sqrt{1 − (t/M)^2}\right)}{I_0(β)}, \quad |t| < M,

interpolating (``φ(j) = δ_j``), of half-width :data:`HALF_WIDTH` ``M = 16`` samples and ``β =`` :data:`BETA`:
a signal band-limited to :data:`BAND` ``= 0.4 fs`` is reconstructed to :data:`RECONSTRUCTION_ERROR` (relative,
measured over the band and the interval by :func:`reconstruction_error`; the images of the band fall in the
kernel's stop band, ``0.6 fs`` and above, so nothing of them comes back).

Over the sample interval ``[t_k, t_{k+1}]`` the force reads the samples ``k − M + 1 … k + M``, so a pole ``s``
advances as ``z⁺ = e^{sT} z + Σ_m W_m u_{k+m}`` with

.. math::

    W_m(s) = T \int_0^1 e^{sT(1 − σ)}\, φ(σ − m)\, dσ ,\qquad m = −M+1 … M,

computed here by composite Gauss–Legendre quadrature (:func:`pole_weights`; panels narrow enough for
``e^{sT(1−σ)}`` on each — a mode far above the Nyquist frequency gets more of them).  The reconstruction is not
causal: ``M − 1`` samples lie beyond the lookahead that the other holds read.  The model reads the record
:data:`ADVANCE` samples ahead (:func:`lead_in`: the last sample held after the record, the first before
it), which a record allows and a co-simulation host, feeding the force sample by sample, does not (the FMUs say
so and take the cubic).
"""
from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING, Callable, Sequence, cast

import numpy as np

if TYPE_CHECKING:
    from ..config import BeamConfig

__all__ = ["HALF_WIDTH", "BETA", "BAND", "ADVANCE", "TAPS", "kernel", "pole_weights",
           "dense_weights", "lead_in", "causal_config", "hold_hint", "BROADBAND_EDGE",
           "reconstruction_error", "RECONSTRUCTION_ERROR"]

#: Half-width ``M`` of the kernel in samples.
HALF_WIDTH = 16
#: Kaiser window's shape parameter: the smallest reconstruction error over ``0 … 0.4 fs`` for ``M = 16``
#: (scanned 9 … 15.5 in steps of 0.5: 5.6e-5 at 9, 2.0e-5 at 10, 1.4e-4 at 10.5).
BETA = 10.0
#: The band [cycles per sample] the reconstruction is built for: the images above ``1 − BAND`` are stopped.
BAND = 0.4
#: What the reconstruction may be off over ``0 … BAND`` (relative to the signal's amplitude), measured by
#: :func:`reconstruction_error` (1.95e-5) with a margin of 1.5 for the quadrature of that measurement.
RECONSTRUCTION_ERROR = 3e-5
#: How many samples the model reads beyond the lookahead ``u_{k+1}``.
ADVANCE = HALF_WIDTH - 1
#: The sample offsets the reconstruction over ``[t_k, t_{k+1}]`` reads, relative to the record advanced by
#: :data:`ADVANCE` (one lookahead, the rest past samples): the layout of the polynomial holds' taps.
TAPS = tuple(range(-(2 * HALF_WIDTH - 2), 2))

#: Gauss–Legendre nodes per panel; a panel spans at most :data:`_PANEL_PHASE` of ``|sT|``.
_NODES = 20
_PANEL_PHASE = 4.0
#: Most panels per interval for a pole (dyadic levels up to 2⁶); a pole beyond them (``|sT| > 256``) takes the
#: series in ``1/(sT)``.  The dense route has no series and takes up to 2¹² panels.
_MAX_LEVEL = 6
_DENSE_MAX_LEVEL = 12
#: Terms of the series in ``1/(sT)``: the remainder is below ``max|φ⁽ᴷ⁾| / |sT|ᴷ`` of ``|sT|⁻¹``, about 1e-13 of
#: the first term at ``|sT| = 256``.
_SERIES_TERMS = 8
#: Degree of the Chebyshev interpolant of ``φ`` on each unit interval the endpoint derivatives are read from (40:
#: the series at ``|sT| = 257`` within 3e-13 of 2¹³ panels; 60 amplifies round-off in the 7th derivative to 2e-9).
_CHEBYSHEV_DEGREE = 40


def kernel(t: np.ndarray | float) -> np.ndarray:
    """``φ(t)``: the Kaiser-windowed sinc (zero for ``|t| ≥ M``)."""
    t = np.asarray(t, dtype=float)
    inside = np.abs(t) < HALF_WIDTH
    w = np.zeros_like(t)
    w[inside] = np.i0(BETA * np.sqrt(1.0 - (t[inside] / HALF_WIDTH) ** 2)) / np.i0(BETA)
    return np.sinc(t) * w


@functools.lru_cache(maxsize=None)
def _endpoint_derivatives() -> tuple[np.ndarray, np.ndarray]:
    """``φ⁽ᵏ⁾(σ − m)`` at ``σ = 0`` and ``σ = 1`` from inside ``[0, 1]`` (:data:`_SERIES_TERMS` × taps each),
    ``m = −M+1 … M``: from a Chebyshev interpolant of degree :data:`_CHEBYSHEV_DEGREE` on each unit interval
    (``φ`` is analytic there — ``I₀(β√x)`` is entire in ``x`` — so one-sided at ``±M`` too)."""
    from numpy.polynomial import Chebyshev

    m = np.arange(-HALF_WIDTH + 1, HALF_WIDTH + 1)
    d0 = np.zeros((_SERIES_TERMS, m.size))
    d1 = np.zeros((_SERIES_TERMS, m.size))
    for j, mj in enumerate(m):
        # typed by the cast: mypy cannot infer a lambda with a default argument in context (python/mypy#15459)
        p = Chebyshev.interpolate(cast("Callable[[np.ndarray], np.ndarray]",
                                       lambda x, mj=mj: kernel(np.clip(x, 0.0, 1.0) - mj)), _CHEBYSHEV_DEGREE,
                                  domain=[0.0, 1.0])
        for k in range(_SERIES_TERMS):
            d0[k, j], d1[k, j] = p(0.0), p(1.0)
            p = p.deriv()
    for a in (d0, d1):
        a.setflags(write=False)
    return d0, d1


def _series(a: np.ndarray, E: np.ndarray) -> np.ndarray:
    """``∫₀¹ e^{a(1−σ)} φ(σ − m) dσ`` (taps × poles) by the series ``Σₖ (e^a φ⁽ᵏ⁾(−m) − φ⁽ᵏ⁾(1−m)) / a^{k+1}``
    (integration by parts, :data:`_SERIES_TERMS` terms)."""
    d0, d1 = _endpoint_derivatives()
    out = np.zeros((d0.shape[1], a.size), dtype=complex)
    inv = 1.0 / a
    power = inv.copy()
    for k in range(_SERIES_TERMS):
        out += (np.outer(d0[k], E) - d1[k][:, None]) * power
        power = power * inv
    return out


@functools.lru_cache(maxsize=None)
def _panel_table(level: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodes ``σ_i`` and weights of ``2^level`` Gauss–Legendre panels on [0, 1], and ``φ(σ_i − m)`` (taps ×
    nodes) for ``m = −M+1 … M`` — constants, formed once per level."""
    x, w = np.polynomial.legendre.leggauss(_NODES)
    panels = 2 ** level
    h = 1.0 / panels
    starts = np.arange(panels) * h
    sigma = (starts[:, None] + 0.5 * h * (x[None, :] + 1.0)).ravel()
    weights = np.tile(0.5 * h * w, panels)
    m = np.arange(-HALF_WIDTH + 1, HALF_WIDTH + 1)
    table = kernel(sigma[None, :] - m[:, None])
    for a in (sigma, weights, table):
        a.setflags(write=False)
    return sigma, weights, table


@functools.lru_cache(maxsize=None)
def _panel_offsets(level: int) -> tuple[np.ndarray, np.ndarray]:
    """``1 − σ_p⁺`` per panel (``σ_p⁺`` its end) and ``σ_p⁺ − σ_i`` per node of a panel (the same on every
    panel) for :func:`_panel_table`'s panels: ``1 − σ = (1 − σ_p⁺) + (σ_p⁺ − σ_i)``."""
    x, _ = np.polynomial.legendre.leggauss(_NODES)
    h = 1.0 / 2 ** level
    ends = 1.0 - h * np.arange(1, 2 ** level + 1)
    within = 0.5 * h * (1.0 - x)
    for a in (ends, within):
        a.setflags(write=False)
    return ends, within


def pole_weights(s: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """``e^{sT}`` (n,) and ``W`` (2M, n): the weights of ``u_{k+m}``, ``m = −M+1 … M`` (module docstring), per
    pole ``s`` (n,) [1/s], for the sample time ``T`` [s].

    Each pole on ``2^ℓ`` panels of :data:`_NODES` Gauss–Legendre nodes, ``2^ℓ ≥ |sT|/4`` (the exponential on a
    panel then turns by at most 4 radians: the rule is exact to round-off for it and for the kernel, which is
    smooth on each unit interval); beyond ``2^6`` panels (``|sT| > 256``) :data:`_SERIES_TERMS` terms of the series
    in ``1/(sT)`` (integration by parts; against 2¹³ panels within 1e-12, ``tests/test_bandlimited.py``).
    """
    s = np.asarray(s, dtype=complex).reshape(-1)
    a = s * T
    with np.errstate(over="ignore", invalid="ignore"):          # an unstable candidate: caught downstream
        E = np.exp(a)
    W = np.zeros((2 * HALF_WIDTH, s.size), dtype=complex)
    size = np.abs(a)
    level = np.zeros(s.size, dtype=np.int64)
    big = size > _PANEL_PHASE
    level[big] = np.ceil(np.log2(size[big] / _PANEL_PHASE)).astype(np.int64)
    for lv in np.unique(level):
        idx = np.flatnonzero(level == lv)
        if lv > _MAX_LEVEL:
            with np.errstate(over="ignore", invalid="ignore"):
                W[:, idx] = T * _series(a[idx], E[idx])
            continue
        _, weights, table = _panel_table(int(lv))
        ends, within = _panel_offsets(int(lv))
        ai = a[idx]
        with np.errstate(over="ignore", invalid="ignore"):      # an unstable candidate: caught downstream
            # e^{a(1−σ)} at panel p's node i is e^{a(1−σ_p⁺)} e^{a(σ_p⁺−σ_i)} (σ_p⁺ the panel's end): one
            # exponential per panel and one per node instead of one per panel and node (the exponentials
            # were the cost; the products agree to round-off)
            ex = (np.exp(np.outer(ends, ai))[:, None, :] * np.exp(np.outer(within, ai))[None, :, :]
                  ).reshape(-1, idx.size) * weights[:, None]       # (nodes, poles), C order
        # the real table times the real and imaginary parts side by side: one real product, a quarter of
        # the complex one's work
        W[:, idx] = T * (table @ ex.view(float)).view(complex)
    return E, W


def lead_in(u: np.ndarray, advance: int) -> np.ndarray:
    """What a recursion reading the record ``advance`` samples ahead runs on, from ``advance`` samples before the
    record (its first ``advance`` outputs are before the record, dropped): the record with its last sample held
    ``advance`` samples after it.  Every sample the reconstruction needs is then read — before the record its first
    sample held, as the recursion holds its past.

    Run from the record's first sample on the record read ``advance`` samples ahead instead (as it was before
    this lead-in), the reconstruction took ``u[advance]`` for ``u[0 … advance − 1]``: a step of the force at the
    start, whose lowest mode rang through the record (measured: a cantilever under noise to fs/2.56, two velocity
    sensors and a displacement one, 1 % noise: 3-4 noise variances in the first 0.2 s at the truth's parameters,
    1.1-1.3 until 1.4 s, with the model on a grid four times finer; 0.000 from the record's first sample held
    before it)."""
    if advance <= 0 or u.shape[0] == 0:
        return u
    return np.concatenate([u, np.repeat(u[-1:], advance, axis=0)])


def reconstruction_error(band: float = BAND, points: int = 81) -> float:
    """The largest ``|Σ_j e^{i2πνj} φ(σ − j) − e^{i2πνσ}|`` over ``ν ∈ [0, band]`` and ``σ ∈ [0, 1]`` (41 points):
    how far the reconstruction of a tone of unit amplitude at ``ν`` cycles per sample is off between samples."""
    sigma = np.linspace(0.0, 1.0, 41)[:, None]
    j = np.arange(-HALF_WIDTH - 1, HALF_WIDTH + 2)[None, :]
    table = kernel(sigma - j)
    worst = 0.0
    for nu in np.linspace(0.0, band, points):
        r = table @ np.exp(2j * math.pi * nu * j[0])
        worst = max(worst, float(np.abs(r - np.exp(2j * math.pi * nu * sigma[:, 0])).max()))
    return worst


def dense_weights(A: np.ndarray, B: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """``Φ = e^{AT}`` and ``P`` (2M, n, m): ``P_m = T ∫₀¹ e^{AT(1−σ)} B φ(σ − m) dσ``, ``m = −M+1 … M``, for a
    dense ``ẋ = A x + B u`` (the exact scheme's fallback when no diagonal form is reliable).

    The same panels as :func:`pole_weights`, ``2^ℓ ≥ ‖AT‖₁/4`` (at most 2¹²): ``e^{AT(1−σ)} B`` at a panel's
    nodes is ``S^{P−1−p} F_i`` with ``S = e^{ATh}`` and ``F_i = e^{ATh(1−x_i)} B`` — one matrix exponential per
    node of one panel, then products panel by panel.
    """
    import scipy.linalg as sla

    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    size = float(np.linalg.norm(A, 1)) * T
    level = 0 if size <= _PANEL_PHASE else min(int(math.ceil(math.log2(size / _PANEL_PHASE))), _DENSE_MAX_LEVEL)
    panels = 2 ** level
    h = 1.0 / panels
    x, w = np.polynomial.legendre.leggauss(_NODES)
    x = 0.5 * (x + 1.0)                                     # nodes on [0, 1] within a panel
    m = np.arange(-HALF_WIDTH + 1, HALF_WIDTH + 1)
    with np.errstate(over="ignore", invalid="ignore"):    # an unstable candidate: caught downstream
        Phi = sla.expm(A * T)
        S = sla.expm(A * T * h)
        Y = np.stack([sla.expm(A * T * h * (1.0 - xi)) @ B for xi in x])     # (nodes, n, m) on the last panel
        P = np.zeros((m.size,) + B.shape)
        for p in range(panels - 1, -1, -1):
            K = kernel((p + x)[None, :] * h - m[:, None]) * (0.5 * h * w)        # (taps, nodes)
            P += T * np.einsum("qi,inm->qnm", K, Y)
            if p:
                Y = np.einsum("ab,ibm->iam", S, Y)
    return Phi, P


def causal_config(config: "BeamConfig") -> "BeamConfig":
    """``config`` for a model driven sample by sample: ``input = "bandlimited"`` becomes ``"cubic"``.

    The band-limited reconstruction reads :data:`ADVANCE` samples beyond the lookahead — a record has them, a
    co-simulation host feeding the force step by step or a controller commanding it does not.  The FMUs and the
    design models (:func:`ebb_model.modal.truncation.design_model`, the exports) take the cubic through the samples
    ``k−2 … k+1`` instead: the same beam, the force between samples as a causal model can know it.  Any other
    config is returned as it is.
    """
    from dataclasses import replace

    if config.time.input_hold != "bandlimited":
        return config
    return replace(config, time=replace(config.time, input_hold="cubic"))


#: The records' force reaching this share of the sampling rate (within 20 dB of its peak, Welch) with the cubic
#: between samples gets a hint: there the cubic through four samples is 9 % off between samples (the tone test
#: of :func:`reconstruction_error`: 0.6 % at 0.1 fs, 8.9 % at 0.2 fs, 87 % at 0.4 fs), several to hundreds of
#: noise variances on an accelerometer record (``docs/model.md``).
BROADBAND_EDGE = 0.2


def hold_hint(config: "BeamConfig", inputs: Sequence[np.ndarray]) -> str | None:
    """A sentence when the records' force reaches :data:`BROADBAND_EDGE` of the sampling rate and the config takes
    the cubic between samples (the exact scheme's default), ``None`` otherwise.

    Not a switch: whether a force is band-limited is the acquisition's to say (an anti-alias filter on the force's
    channel: a DAQ), not the samples' — a record made by a model with the cubic, or a force commanded through a
    hold, is not; the hint says which setting models a DAQ's record and how far off the cubic is there.
    """
    from ..space.adequacy import excited_band

    t = config.time
    if t.scheme != "exact" or t.input_hold != "cubic" or not len(inputs):
        return None
    try:
        top = excited_band(inputs, t.dt, rel=1e-2)[1]
    except ValueError:                                    # no power: nothing to say
        return None
    if top < BROADBAND_EDGE / t.dt:
        return None
    return (f"the records' force reaches {top * t.dt:.2f} of the sampling rate ({top:.4g} Hz), where the cubic "
            f"between samples is {100 * _cubic_error(top * t.dt):.0f} % off: a force recorded through an "
            "anti-alias filter (a DAQ) is band-limited — [time] input = \"bandlimited\" models it")


def _cubic_error(nu: float) -> float:
    """The cubic through four samples' largest error between samples on a tone of unit amplitude at ``nu``
    cycles per sample (the tone test of :func:`reconstruction_error`)."""
    from ..exact.sample_integrals import INPUT_TAPS, LAGRANGE

    taps = np.array(INPUT_TAPS["cubic"], dtype=float)
    sigma = np.linspace(0.0, 1.0, 41)
    basis = np.array([np.polyval(LAGRANGE["cubic"][j][::-1], sigma) for j in range(taps.size)])
    rec = np.exp(2j * math.pi * nu * taps) @ basis
    return float(np.abs(rec - np.exp(2j * math.pi * nu * sigma)).max())
