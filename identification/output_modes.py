"""The modes of records without a force: a structure ringing down, or driven by a force nobody measured.

A record without a force still fixes the beam's natural frequencies, damping ratios and, with several sensors,
its mode shapes' ratios at the sensors — evidence of the kind ``[identification.modes]`` holds.  Two records:

* **Free decay** (:func:`free_decay_modes`): after a release or an uninstrumented blow every sensor reads a sum of
  damped oscillations, ``y_j(t) = Σ_k e^{−ζ_k ω_k t} (a_jk cos ω_dk t + b_jk sin ω_dk t)``.  Such a record is the
  response to an impulse at its first sample, so the records' own stabilised estimator
  (:func:`identification.record_poles.record_modes`: LSCF on overlapping bands, a stability chart) reads its
  modes from its spectrum under a unit impulse; that estimate's damping carries the exponential window's decay
  (``1/τ`` added to every pole's decay rate), which is taken out.  The poles are then fitted to the record in
  time by least squares — the amplitudes linear, solved for at every trial of the poles (variable projection),
  each sensor weighted by its own noise — and their standard uncertainties follow from the Jacobian of the full
  model (poles and amplitudes), inflated by the residuals' long-run variance when they are not white (modes
  left out, a drifting offset): the scatter of the estimates over noise realisations, not a guess.
A record under a force nobody measured (ambient) is a free decay of the same modes in its correlations (the
natural excitation technique): :mod:`identification.ambient_modes` reads them with :func:`decay_fit`.

Mode shapes: each mode's complex amplitude at every sensor, as a ratio to the sensor that sees the mode best
(the real part; its imaginary part is non-proportional damping or noise), with its standard uncertainty.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from scipy import optimize

from ebb_model.errors import DataError

from .record_poles import EXP_WINDOW, record_modes

if TYPE_CHECKING:
    from .modal_data import ModalData

__all__ = ["OutputModes", "DecayFit", "free_decay_modes", "decay_fit", "fit_poles", "shape_ratios", "SIGNIFICANCE",
           "HARMONIC_DAMPING", "DOUBLET", "DOUBLET_COMPANION"]

#: A mode is kept when its amplitude at one sensor at least is this many standard uncertainties (a fitted pole
#: on noise alone has an amplitude of about one).
SIGNIFICANCE = 5.0
#: Damping ratio below which the start's window-corrected estimate is taken to be this floor (the time fit
#: finds the rest): the window's own decay can be larger than a lightly damped mode's.
MIN_START_DAMPING = 1e-4
#: A pole's frequency stays within this factor of its start's; its damping ratio within [MIN_DAMPING, MAX_DAMPING].
POLE_RANGE = 1.5
MIN_DAMPING = 1e-6
MAX_DAMPING = 0.5
#: A fitted line whose damping ratio ends at or below this is no mode: it does not decay over the record (or its
#: correlations) — a tone in the force, a machine's harmonic, mains pickup.  No beam in air is damped this little
#: (a steel strip's modes: 1e-4 and up); the ARTS bench's three tones and their harmonics, read as an ambient
#: record, end at the fit's floor :data:`MIN_DAMPING`.
HARMONIC_DAMPING = 1e-5
#: Modes of one record closer than this ratio are a doublet: candidates for one mode of the beam, the model's mode
#: compared with the member nearest it (:class:`identification.modal_data.ModalData`'s ``groups``).  A beam's
#: bending modes lie far apart (a cantilever's first two: 6.3 times); an estimator resolves a bending mode beside
#: a torsional one or a support's — DROPBEAR's dwells: 192.5 beside 193.9 Hz, 174.3 beside 178.8 Hz (2.6 %).
DOUBLET = 1.05
#: A doublet's member damped at least this many times as heavily as a better-shown member is a companion (a rattling
#: support's), no candidate: DROPBEAR's 37.4–37.5 Hz at 2.1 % beside 37.6 Hz at 0.07–0.08 % (26–30 times).  A
#: torsional mode beside a bending one is damped alike (DROPBEAR's doublets near the second mode: within 1.5 times).
DOUBLET_COMPANION = 5.0
#: Lags of the residual's autocorrelation summed for the long-run variance (Bartlett weights).
LONG_RUN_LAGS = 64


@dataclass(frozen=True)
class OutputModes:
    """The modes a record without a force shows.

    Attributes
    ----------
    frequencies_hz, frequency_std : numpy.ndarray
        Undamped natural frequencies [Hz] (ascending) and their standard uncertainties, ``(m,)``.
    damping, damping_std : numpy.ndarray
        Damping ratios and their standard uncertainties, ``(m,)``.
    shapes, shape_std : numpy.ndarray
        ``(m, n_sensors)``: each mode's amplitude at every sensor over its amplitude at ``reference[k]`` (real
        part; 1 at the reference) and the ratio's standard uncertainty (0 at the reference).
    reference : numpy.ndarray
        ``(m,)`` the sensor each mode's shape is relative to (the one that sees it best).
    significance : numpy.ndarray
        ``(m,)`` each mode's amplitude at that sensor in standard uncertainties (at least :data:`SIGNIFICANCE`).
    noise_std : numpy.ndarray
        ``(n_sensors,)`` the residual's standard deviation per sensor.
    inflation : float
        The factor the Jacobian's covariance was multiplied by for the residual's correlation (1: white).
    kind : str
        ``"free decay"`` or ``"ambient"``.
    tones_hz : numpy.ndarray
        Lines the records hold that do not decay (:data:`HARMONIC_DAMPING`): a tone in the force, a machine's
        harmonic, mains pickup — fitted with the modes, not reported as modes.
    """

    frequencies_hz: np.ndarray
    frequency_std: np.ndarray
    damping: np.ndarray
    damping_std: np.ndarray
    shapes: np.ndarray
    shape_std: np.ndarray
    reference: np.ndarray
    significance: np.ndarray
    noise_std: np.ndarray
    inflation: float
    kind: str
    tones_hz: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def none(cls, n_sensors: int, noise_std: np.ndarray, kind: str = "free decay") -> "OutputModes":
        """No mode: a record that shows none."""
        z = np.zeros(0)
        return cls(z, z, z, z, np.zeros((0, n_sensors)), np.zeros((0, n_sensors)), np.zeros(0, int), z,
                   np.asarray(noise_std, dtype=float), 1.0, kind)

    def subset(self, keep: np.ndarray) -> "OutputModes":
        """The modes where the mask ``keep`` ``(m,)`` is true (the rest's frequencies left out of every array)."""
        k = np.asarray(keep, dtype=bool)
        return replace(self, frequencies_hz=self.frequencies_hz[k], frequency_std=self.frequency_std[k],
                       damping=self.damping[k], damping_std=self.damping_std[k], shapes=self.shapes[k],
                       shape_std=self.shape_std[k], reference=self.reference[k], significance=self.significance[k])

    def modal_data(self) -> "ModalData":
        """The frequencies as measured modes (:class:`identification.modal_data.ModalData`: the model's lowest in
        order — a mode the record does not show shifts the rest, so give records that show the lowest ones), modes
        within :data:`DOUBLET` of each other one mode's candidates — but for a member damped
        :data:`DOUBLET_COMPANION` times as heavily as a better-shown member: a companion, no candidate.

        Raises
        ------
        DataError
            The record shows no mode.
        """
        from .modal_data import ModalData

        if self.frequencies_hz.size == 0:
            tones = (f" (lines at {', '.join(f'{f:.5g}' for f in self.tones_hz)} Hz do not decay: tones in the force "
                     "or a machine's harmonics, not modes)" if self.tones_hz.size else "")
            raise DataError(f"the record shows no mode{tones}: no natural frequency to identify from")
        f, z, shown = self.frequencies_hz, self.damping, self.significance
        groups = np.concatenate([[0], np.cumsum(f[1:] / f[:-1] > DOUBLET)]).astype(int)
        same = groups[:, None] == groups[None, :]
        companion = same & (shown[None, :] > shown[:, None]) & (z[:, None] >= DOUBLET_COMPANION * z[None, :])
        keep = ~np.any(companion, axis=1)
        g = groups[keep]
        return ModalData(f[keep].copy(), self.frequency_std[keep].copy(), g if g[-1] + 1 < g.size else None)

    def to_dict(self) -> dict[str, object]:
        """JSON values."""
        return {"kind": self.kind, "frequencies_hz": self.frequencies_hz.tolist(),
                "frequency_std_hz": self.frequency_std.tolist(), "damping": self.damping.tolist(),
                "damping_std": self.damping_std.tolist(), "shapes": self.shapes.tolist(),
                "shape_std": self.shape_std.tolist(), "reference_sensor": self.reference.tolist(),
                "significance": self.significance.tolist(),
                "noise_std": self.noise_std.tolist(), "inflation": self.inflation, "tones_hz": self.tones_hz.tolist()}


def _as_record(outputs: np.ndarray, dt: float) -> np.ndarray:
    """The outputs as ``(n, n_sensors)`` finite floats, refused in one line otherwise."""
    y = np.asarray(outputs, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    if y.ndim != 2 or y.shape[0] < 64:
        raise DataError(f"a free decay needs at least 64 samples of each sensor, got shape {np.shape(outputs)}")
    if not np.all(np.isfinite(y)):
        raise DataError("the record holds NaN or infinite values")
    if not (math.isfinite(dt) and dt > 0):
        raise DataError(f"the sample interval must be a positive number, got {dt!r}")
    if np.any(np.ptp(y, axis=0) == 0):
        raise DataError("a sensor's record is constant: it shows no mode")
    return y


def _basis(p: np.ndarray, t: np.ndarray, derivatives: bool = False
           ) -> tuple[np.ndarray, np.ndarray | None]:
    """``(n, 2m + 1)``: per mode ``e^{−ζωt} cos ω_d t`` and ``e^{−ζωt} sin ω_d t`` (``p`` = ln f, ln ζ per mode),
    and a constant; with ``derivatives`` also ``(2m, n, 2)``: each parameter's derivative of its mode's two
    columns."""
    f, z = np.exp(p[0::2]), np.exp(p[1::2])
    w = 2 * np.pi * f
    root = np.sqrt(np.maximum(1.0 - z * z, 1e-12))
    wd = w * root
    env = np.exp(-np.outer(t, z * w))
    c, s = env * np.cos(np.outer(t, wd)), env * np.sin(np.outer(t, wd))
    cols = np.empty((t.size, 2 * f.size + 1))
    cols[:, 0:-1:2], cols[:, 1:-1:2], cols[:, -1] = c, s, 1.0
    if not derivatives:
        return cols, None
    d = np.empty((p.size, t.size, 2))
    # ∂/∂ln f: the decay rate ζω and ω_d both scale with f; ∂/∂ln ζ: the decay rate scales, ω_d by −ζ²/(1−ζ²)
    for k in range(f.size):
        for i, (rate, wdot) in enumerate(((z[k] * w[k], wd[k]), (z[k] * w[k], -wd[k] * z[k] ** 2 / root[k] ** 2))):
            d[2 * k + i, :, 0] = -t * (rate * c[:, k] + wdot * s[:, k])
            d[2 * k + i, :, 1] = -t * (rate * s[:, k] - wdot * c[:, k])
    return cols, d


def _projected(p: np.ndarray, t: np.ndarray, yw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The amplitudes ``(2m + 1, n_sensors)`` best for poles ``p`` on the weighted records ``yw`` (each sensor
    over its noise level; one basis for all, so each sensor's amplitudes are its own least squares) and the
    weighted residual ``(n, n_sensors)``."""
    phi = _basis(p, t)[0]
    amp = np.linalg.lstsq(phi, yw, rcond=None)[0]
    return amp, yw - phi @ amp


def _projected_jacobian(p: np.ndarray, t: np.ndarray, yw: np.ndarray) -> np.ndarray:
    """Kaufman's Jacobian of the projected residual (:func:`_projected`) in the poles: ``−P⊥ (∂Φ/∂p) A`` per
    parameter, raveled as the residual is."""
    phi, d = _basis(p, t, derivatives=True)
    assert d is not None
    q = np.linalg.qr(phi)[0]
    amp = np.linalg.lstsq(phi, yw, rcond=None)[0]
    jac = np.empty((yw.size, p.size))
    for i in range(p.size):
        k = i // 2
        di = d[i] @ amp[2 * k:2 * k + 2]                       # (n, n_sensors)
        jac[:, i] = -(di - q @ (q.T @ di)).ravel()
    return jac


def _long_run_factor(r: np.ndarray) -> float:
    """``1 + 2 Σ_k (1 − k/K) ρ_k`` of the residuals (mean over sensors), at least 1: how much a correlated
    residual inflates a smooth estimator's variance over a white one's."""
    n = r.shape[0]
    lags = min(LONG_RUN_LAGS, n // 4)
    rc = r - r.mean(axis=0)
    var = np.sum(rc * rc, axis=0)
    rho = np.array([np.sum(rc[k:] * rc[:-k], axis=0) / var for k in range(1, lags + 1)]).mean(axis=1)
    weights = 1.0 - np.arange(1, lags + 1) / (lags + 1)
    return max(1.0, 1.0 + 2.0 * float(weights @ rho))


def fit_poles(y: np.ndarray, dt: float, f0: np.ndarray, z0: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """The poles' least-squares fit from ``(f0, z0)``: ``(p, cov_p, amp, cov_amp per sensor, noise per sensor,
    inflation)``."""
    n, n_out = y.shape
    t = np.arange(n) * dt
    # each pole within a factor of its start in frequency, below Nyquist, with a damping ratio in
    # [MIN_DAMPING, MAX_DAMPING]: a pole the records do not hold wanders off otherwise (to an overflow)
    nyquist = 0.5 / dt
    lo = np.column_stack([np.log(f0 / POLE_RANGE), np.full(f0.size, math.log(MIN_DAMPING))]).ravel()
    hi = np.column_stack([np.log(np.minimum(f0 * POLE_RANGE, nyquist)), np.full(f0.size, math.log(MAX_DAMPING))]
                         ).ravel()
    p = np.clip(np.column_stack([np.log(f0), np.log(z0)]).ravel(), lo + 1e-9, hi - 1e-9)
    w = np.ones(n_out)
    for _ in range(2):           # unweighted, then each sensor weighted by its own residual level
        sol = optimize.least_squares(lambda q: _projected(q, t, y / w)[1].ravel(), p, bounds=(lo, hi),
                                     jac=lambda q: _projected_jacobian(q, t, y / w), x_scale="jac")
        p = sol.x
        w = np.sqrt(np.mean(_projected(p, t, y)[1] ** 2, axis=0))
    amp, r = _projected(p, t, y / w)          # whitened: amplitudes per unit noise
    dof = n * n_out - p.size - amp.size
    s2 = float(np.sum(r * r)) / dof
    infl = _long_run_factor(r)
    # the full model's Jacobian (poles and every sensor's amplitudes), whitened
    phi, d = _basis(p, t, derivatives=True)
    assert d is not None
    jp = np.empty((n * n_out, p.size))
    for i in range(p.size):
        k = i // 2
        jp[:, i] = (d[i] @ amp[2 * k:2 * k + 2]).ravel()
    m_amp = phi.shape[1]
    # normal equations block by block: [Jpᵀ Jp, Jpᵀ Ja; Jaᵀ Jp, Ja ᵀJa], Ja = I_sensors ⊗ phi (row-major ravel)
    jp3 = jp.reshape(n, n_out, p.size)
    a11 = jp.T @ jp
    a12 = np.concatenate([jp3[:, o, :].T @ phi for o in range(n_out)], axis=1)
    a22 = np.kron(np.eye(n_out), phi.T @ phi)
    normal = np.block([[a11, a12], [a12.T, a22]])
    cov = np.linalg.pinv(normal, rcond=1e-13) * s2 * infl
    cov_p = cov[:p.size, :p.size]
    cov_amp = np.stack([cov[p.size + o * m_amp:p.size + (o + 1) * m_amp, p.size + o * m_amp:p.size + (o + 1) * m_amp]
                        for o in range(n_out)])
    return p, cov_p, amp * w, cov_amp * (w[:, None, None] ** 2), w * math.sqrt(s2), infl


def shape_ratios(amp: np.ndarray, cov_amp: np.ndarray, m: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per mode: the shape ratios to the best-seen sensor (real part), their standard uncertainties, that sensor,
    and each mode's largest amplitude in standard uncertainties."""
    n_out = amp.shape[1]
    shapes, std = np.ones((m, n_out)), np.zeros((m, n_out))
    ref, signif = np.zeros(m, int), np.zeros(m)
    for k in range(m):
        a, b = amp[2 * k], amp[2 * k + 1]
        c = a - 1j * b
        var = np.array([cov_amp[o, 2 * k, 2 * k] + cov_amp[o, 2 * k + 1, 2 * k + 1] for o in range(n_out)])
        snr = np.abs(c) / np.sqrt(np.maximum(var, 1e-300))
        r = int(np.argmax(snr))
        ref[k], signif[k] = r, float(snr[r])
        ratio = c / c[r]
        shapes[k] = ratio.real
        # first order: var(c_j/c_r) ≈ (var_j + |ratio_j|² var_r) / |c_r|², half of it in the real part
        std[k] = np.sqrt(0.5 * (var + np.abs(ratio) ** 2 * var[r]) / abs(c[r]) ** 2)
        std[k, r] = 0.0
    return shapes, std, ref, signif


@dataclass(frozen=True)
class DecayFit:
    """The poles of a sum of damped oscillations fitted to records (:func:`decay_fit`): ``p`` (ln f, ln ζ per
    mode, ascending in f), their covariance ``cov_p``, the amplitudes ``amp`` (2m + 1, n_columns: a cosine and a
    sine per mode, then a constant) with their covariance per column ``cov_amp`` (n_columns, 2m + 1, 2m + 1), the
    residual's level per column ``noise``, the long-run ``inflation`` of the covariance, the shape ratios
    (:func:`shape_ratios`) and each mode's ``significance``."""

    p: np.ndarray
    cov_p: np.ndarray
    amp: np.ndarray
    cov_amp: np.ndarray
    noise: np.ndarray
    inflation: float
    shapes: np.ndarray
    shape_std: np.ndarray
    reference: np.ndarray
    significance: np.ndarray

    @property
    def frequencies_hz(self) -> np.ndarray:
        """The modes' undamped natural frequencies [Hz]."""
        return np.exp(self.p[0::2])

    @property
    def damping(self) -> np.ndarray:
        """The modes' damping ratios."""
        return np.exp(self.p[1::2])

    @property
    def tones(self) -> np.ndarray:
        """Which of the fitted lines do not decay (:data:`HARMONIC_DAMPING`): not modes."""
        return self.damping <= HARMONIC_DAMPING


def decay_fit(y: np.ndarray, dt: float) -> DecayFit | None:
    """The significant modes (:data:`SIGNIFICANCE`) of records that are sums of damped oscillations from their
    first sample (a free decay, or correlation functions: :mod:`identification.ambient_modes`), ``None`` when the
    records' start finds no stable pole or none is significant.  The start is the records' own stabilised
    estimator under a unit impulse, its exponential window's decay taken out; the least significant mode is
    dropped and the rest fitted again until every one is significant."""
    n, n_out = y.shape
    impulse = np.zeros((n, 1))
    impulse[0, 0] = 1.0
    start = record_modes([impulse], [y], dt)
    if start.frequencies_hz.size == 0:
        return None
    window_decay = 1.0 / (EXP_WINDOW * n * dt)              # the start's exponential window, in every pole
    w0 = 2 * np.pi * start.frequencies_hz
    z0 = np.maximum(start.damping - window_decay / w0, MIN_START_DAMPING)
    keep = np.ones(w0.size, bool)
    while True:
        p, cov_p, amp, cov_amp, noise, infl = fit_poles(y, dt, start.frequencies_hz[keep], z0[keep])
        m = p.size // 2
        shapes, shape_std, ref, signif = shape_ratios(amp, cov_amp, m)
        weak = signif < SIGNIFICANCE
        if not weak.any() or m == 1:
            break
        idx = np.flatnonzero(keep)
        keep[idx[int(np.argmin(signif))]] = False          # the least significant out, the rest fitted again
    if signif.min(initial=np.inf) < SIGNIFICANCE:
        return None
    order = np.argsort(p[0::2])
    pair = np.column_stack([2 * order, 2 * order + 1]).ravel()
    cols = np.concatenate([pair, [amp.shape[0] - 1]])
    return DecayFit(p[pair], cov_p[np.ix_(pair, pair)], amp[cols], cov_amp[:, cols][:, :, cols], noise, infl,
                    shapes[order], shape_std[order], ref[order], signif[order])


def free_decay_modes(outputs: np.ndarray, dt: float) -> OutputModes:
    """The modes of a free decay (module docstring): every sensor's record from the moment the structure was left
    to ring.

    Parameters
    ----------
    outputs : array_like
        ``(n, n_sensors)`` (or ``(n,)``): the records, the decay's start at the first sample.
    dt : float
        Sample interval [s].

    Returns
    -------
    OutputModes
        The significant modes (:data:`SIGNIFICANCE`), ascending; none when the record's start finds no stable
        pole.

    Raises
    ------
    DataError
        Fewer than 64 samples, a NaN or a constant sensor, a bad ``dt``.
    """
    y = _as_record(outputs, dt)
    fit = decay_fit(y, dt)
    if fit is None:
        return OutputModes.none(y.shape[1], np.std(y, axis=0))
    f, z, keep = fit.frequencies_hz, fit.damping, ~fit.tones
    sd = np.sqrt(np.maximum(np.diag(fit.cov_p), 0.0))
    return OutputModes(f[keep], (f * sd[0::2])[keep], z[keep], (z * sd[1::2])[keep], fit.shapes[keep],
                       fit.shape_std[keep], fit.reference[keep], fit.significance[keep], fit.noise, fit.inflation,
                       "free decay", f[fit.tones])
