r"""The acquisition's anti-alias filter: an analog low-pass on a sensor's channel, before the sampler.

A real acquisition filters each channel in continuous time before it samples it, so a mode above the Nyquist
frequency reaches the record attenuated by the filter's gain *at the mode's own frequency* (a digital filter
after sampling could only act at the alias's frequency, where the mode's image already sits in band).  A sensor
declares its channel's filter in the config::

    [[sensors]]
    name = "y1"
    x = 0.4
    kind = "acceleration"
    antialias = { order = 4, corner = 1250.0 }    # Butterworth, -3 dB corner in Hz

The filter is the unit-DC-gain Butterworth low-pass ``H(s) = Π_k (−p_k)/(s − p_k)`` with poles
``p_k = ω_c e^{iπ(2k + n − 1)/(2n)}``, ``k = 1 … n``.  Its group delay at DC, ``Σ_k −1/p_k``, is what a
record lags the beam by in the band (:attr:`AntiAlias.group_delay`).

The force's channel may declare its filter too (``[[actuators]] antialias = {…}``): the record then holds the
force through it, while the beam felt the force itself, so a sensor filtered alike relates to the recorded force
exactly as the unfiltered beam does (``H G H⁻¹ = G``: the two filters cancel, :func:`effective_filters`) — the
usual case of one acquisition recording every channel.  A sensor without that filter, or with another one, would
need the force's filter undone (``1/H`` is not realisable): the config is refused, naming the channels
(:func:`channel_problems`).

The model takes it exactly in time (:func:`filtered_poles`): in series after the beam the sensor's transfer is
``H(s) G(s)``, and in partial fractions over the beam's poles ``s_i`` and the filter's ``p_j``

.. math::

    H(s)\,G(s) = \sum_i \frac{H(s_i)\,R_i}{s - s_i} + \sum_j \frac{r_j\,G(p_j)}{s - p_j},

with ``R_i`` the beam's residues, ``r_j`` the filter's and ``G(p_j)`` the whole beam (every mode and the
feedthrough) at the filter's pole.  So the filtered model stays diagonal: the beam's poles with their output
weights scaled by ``H(s_i)``, and ``n`` more first-order poles per filtered sensor, driven by the inputs — the
same exact input integrals (:func:`ebb_model.exact.sample_integrals.input_weights`) discretise them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

__all__ = ["AntiAlias", "MAX_ORDER", "channel_problems", "effective_filters", "filtered_poles",
           "series_statespace"]

#: The highest filter order taken (an acquisition's analog anti-alias filters are of order 2–8; higher Butterworth
#: orders crowd their poles onto the circle, where the partial fractions lose accuracy).
MAX_ORDER = 10


@dataclass(frozen=True)
class AntiAlias:
    """A Butterworth low-pass of ``order`` with its −3 dB corner at ``corner`` [Hz], unit gain at DC."""

    order: int
    corner: float

    @property
    def poles(self) -> np.ndarray:
        """The analog poles [rad/s], ``(order,)``, in conjugate pairs (a real pole last for an odd order)."""
        n, wc = self.order, 2.0 * math.pi * self.corner
        upper = [wc * np.exp(1j * math.pi * (2 * k + n - 1) / (2 * n)) for k in range(1, n // 2 + 1)]
        poles = [p for z in upper for p in (z, np.conj(z))]
        if n % 2:
            poles.append(complex(-wc, 0.0))
        return np.asarray(poles, dtype=complex)

    def response(self, s: np.ndarray | complex) -> np.ndarray:
        """``H(s)`` at the points ``s`` [rad/s]."""
        s = np.asarray(s, dtype=complex)
        p = self.poles
        return np.prod(-p[:, None] / (s.reshape(-1)[None, :] - p[:, None]), axis=0).reshape(s.shape)

    @property
    def residues(self) -> np.ndarray:
        """``r_j`` of ``H(s) = Σ_j r_j/(s − p_j)`` (distinct poles), one per pole of :attr:`poles`."""
        p = self.poles
        gain = np.prod(-p)
        return np.asarray([gain / np.prod(np.delete(p[j] - p, j)) for j in range(p.size)])

    @property
    def group_delay(self) -> float:
        """The group delay at DC [s], ``Σ −1/p_k``: how far the record lags the beam in the band."""
        return float(np.sum(-1.0 / self.poles).real)

    def to_dict(self) -> dict[str, Any]:
        """The config's table (``antialias = {order, corner}``)."""
        return {"order": self.order, "corner": self.corner}

    def describe(self) -> str:
        """One phrase: order, corner, group delay."""
        return (f"Butterworth order {self.order}, corner {self.corner:.6g} Hz "
                f"(group delay {self.group_delay * 1e6:.4g} µs)")


def channel_problems(actuators: Sequence[Any], sensors: Sequence[Any]) -> list[tuple[str, str]]:
    """``(field, message)`` of each channel whose filter the model cannot represent: the force channels' filters
    (when any) must be one and the same, and every sensor must carry that same filter (it cancels); empty when
    the channels are consistent."""
    forces = {a.antialias for a in actuators}
    if forces <= {None}:
        return []
    if len(forces) > 1:
        return [("actuators", "the force channels' anti-alias filters differ (or some have none): the model can "
                              "take one acquisition's filter on every force channel")]
    (common,) = forces
    return [(f"sensors.{s.name}.antialias",
             f"the forces are recorded through a Butterworth order {common.order}, corner {common.corner:g} Hz, "
             f"that this sensor's channel {'lacks' if s.antialias is None else 'does not share'}: the model cannot "
             "undo a filter on the force; declare the same filter on the sensor (one acquisition) or none on the "
             "forces") for s in sensors if s.antialias != common]


def effective_filters(config: Any) -> list[AntiAlias | None]:
    """Each sensor's filter as the model applies it: its own, or ``None`` where it cancels against the force
    channels' identical filter (:func:`channel_problems` guarantees that every sensor then has it)."""
    forces = {a.antialias for a in config.actuators}
    cancelled = next(iter(forces)) if len(forces) == 1 else None
    return [None if cancelled is not None and s.antialias == cancelled else s.antialias for s in config.sensors]


def filtered_poles(poles: np.ndarray, inputs: np.ndarray, C: np.ndarray, D: np.ndarray,
                   filters: Sequence[AntiAlias | None]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """The beam in pole coordinates with each sensor's filter in series (module docstring).

    Parameters
    ----------
    poles, inputs, C, D
        The beam diagonalised: ``ż = diag(poles) z + inputs u``, ``y = C z + D u`` (``C`` already on ``z``).
    filters
        One per output: its anti-alias filter or ``None``.

    Returns
    -------
    poles, inputs, C, D, added
        The same for the filtered outputs; the filters' poles are appended after the beam's (``added`` of them,
        plus a silent real pole when the filters bring an odd number of real poles: real poles are realised in
        pairs).  A filtered output has no feedthrough (``H(∞) = 0``).
    """
    poles = np.asarray(poles, dtype=complex)
    active = [(i, f) for i, f in enumerate(filters) if f is not None]
    if not active:
        return poles, inputs, C, D, 0
    n, m = inputs.shape
    new_poles, new_inputs, rows = [], [], []
    C = np.array(C, dtype=complex)
    D_out = np.array(D, dtype=complex)
    for i, f in active:
        p, r = f.poles, f.residues
        # the whole beam at each filter pole: G_i(p) = Σ_b C[i, b] inputs[b]/(p − s_b) + D[i]
        G = (C[i][None, :] / (p[:, None] - poles[None, :])) @ inputs + D[i][None, :]      # (order, m)
        new_poles.append(p)
        new_inputs.append(G)
        rows.append((i, r))
        C[i] = C[i] * f.response(poles)
        D_out[i] = 0.0
    extra = np.concatenate(new_poles)
    if np.count_nonzero(extra.imag == 0) % 2:
        # a silent partner for a lone real pole (no input, no output)
        extra = np.concatenate([extra, [extra[extra.imag == 0][0]]])
        new_inputs.append(np.zeros((1, m), dtype=complex))
    added = extra.size
    C_new = np.zeros((C.shape[0], n + added), dtype=complex)
    C_new[:, :n] = C
    at = n
    for i, r in rows:
        C_new[i, at:at + r.size] = r
        at += r.size
    return (np.concatenate([poles, extra]), np.vstack([inputs, *new_inputs]), C_new, D_out, added)


def series_statespace(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray,
                      filters: Sequence[AntiAlias | None]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The real continuous system ``(A, B, C, D)`` with each output's filter in series (its own states, driven by
    that output), for the dense route; an output without a filter is unchanged."""
    A_out, B_out, C_out, D_out = np.array(A, float), np.array(B, float), np.array(C, float), np.array(D, float)
    for i, f in enumerate(filters):
        if f is None:
            continue
        Af, bf, cf = _companion(f)
        nf, n0 = Af.shape[0], A_out.shape[0]
        A_new = np.zeros((n0 + nf, n0 + nf))
        A_new[:n0, :n0] = A_out
        A_new[n0:, n0:] = Af
        A_new[n0:, :n0] = np.outer(bf, C_out[i])
        B_new = np.vstack([B_out, np.outer(bf, D_out[i])])
        C_new = np.hstack([C_out, np.zeros((C_out.shape[0], nf))])
        C_new[i] = 0.0
        C_new[i, n0:] = cf
        D_out = D_out.copy()
        D_out[i] = 0.0
        A_out, B_out, C_out = A_new, B_new, C_new
    return A_out, B_out, C_out, D_out


def _companion(f: AntiAlias) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A real realisation ``(A_f, b_f, c_f)`` of ``H(s)``: a cascade of its first- and second-order sections,
    each of unit DC gain (well scaled for any corner)."""
    sections: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    for p in f.poles:
        if p.imag > 0:       # ω²/(s² + 2σ s + ω²), σ = −Re p, ω = |p|: states (y, ẏ/ω)
            w, sig = abs(p), -p.real
            sections.append((np.array([[0.0, w], [-w, -2 * sig]]), np.array([0.0, w]), np.array([1.0, 0.0])))
        elif p.imag == 0:    # a/(s + a)
            a = -p.real
            sections.append((np.array([[-a]]), np.array([a]), np.array([1.0])))
    n = sum(s[0].shape[0] for s in sections)
    A = np.zeros((n, n))
    b = np.zeros(n)
    at = 0
    prev_c: np.ndarray | None = None
    prev_at = 0
    for As, bs, cs in sections:
        k = As.shape[0]
        A[at:at + k, at:at + k] = As
        if prev_c is None:
            b[at:at + k] = bs
        else:                                   # this section is driven by the previous one's output
            A[at:at + k, prev_at:prev_at + prev_c.size] = np.outer(bs, prev_c)
        prev_c, prev_at = cs, at
        at += k
    c = np.zeros(n)
    assert prev_c is not None
    c[prev_at:prev_at + prev_c.size] = prev_c
    return A, b, c
