r"""The measured modes: natural frequency and damping ratio of every excited mode, fitted to the records in time.

A lightly damped record pins a mode's frequency far more precisely than an
FRF estimate can resolve (a 2 s record at 0.1 % damping: the Welch bins are
wider than the half-power band), and a whole-model fit cannot deliver it
either when the model lacks the effect that moved the mode.  Here each
excited mode is a single-degree-of-freedom oscillator of its own frequency
:math:`\omega_i` and damping ratio :math:`\zeta_i`,

.. math::  \ddot x_{ik} + 2\zeta_i\omega_i\dot x_{ik} + \omega_i^2 x_{ik} = u_k(t),

driven by every input :math:`u_k` (linear between samples, or band-limited when the model takes the force so —
:mod:`ebb_model.acquisition.bandlimited`, the same reconstruction — integrated exactly).
Every output is a linear combination of the :math:`x_{ik}`, :math:`\dot x_{ik}`
(a residue and its phase: mode shapes, sensor and actuator lags), of the
inputs and their first two derivatives (the quasi-static share of the modes
above the band, and an accelerometer's mass line) and of the first mode above
the band held at the model's frequency.  The coefficients enter linearly and
are eliminated by least squares for every trial of the frequencies and
damping ratios (variable projection); the frequencies are found by a scan of
each mode in turn around the model's value (steps of a fraction of the
half-power bandwidth and of the record's resolution ``1/T``) and polished
together by Levenberg–Marquardt.  Standard errors come from the polish's
Jacobian, scaled by the residual variance.

Nothing of the beam model enters except the start: the estimate is what the
data say, and :mod:`diagnosis.search.modal_pattern` compares it with each effect's
prediction.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike
from scipy import linalg, optimize, signal, stats

from ebb_model.acquisition.channel_delay import delay_outputs

__all__ = ["MeasuredModes", "estimate_modes", "seen"]

#: Half-width of the frequency scan around the model's value (relative).
SEARCH = 0.12
#: The smallest damping ratio an estimate reports (far below any structure's: a bolted steel beam's is ~1e-3).
DAMPING_FLOOR = 1e-6

#: Damping ratio beyond which the oscillators' joint fit rejects a trial step outright (:func:`estimate_modes`):
#: far above any mode a record shows (overdamped oscillators up to it stay admissible, as they always were), far
#: below where the columns overflow.
ZETA_REJECTED = 1e3

#: A variable whose residual column reaches less than this share of the largest one is not determined.
UNDETERMINED = 1e-10
#: Largest number of trial frequencies per mode in the scan.
MAX_TRIALS = 600
#: Independent trial frequencies per ``1/T`` of a scan window for :attr:`MeasuredModes.chance`: measured on pure
#: noise (4,800 oscillators over ±12 % windows, 1,000 samples): with one per ``1/T`` the chance's tail was 5.7–6.3×
#: too small (a continuous scan finds more than the record's bins, and the damping is free too).
LOOKS_PER_BIN = 6.0
#: Family-wise false-alarm rate of :func:`seen`: the chance that a set holds one oscillator the records do not need.
FALSE_MODE_RATE = 0.01


@dataclass(frozen=True)
class MeasuredModes:
    """Frequencies and damping ratios of the excited modes, fitted to the records.

    Attributes
    ----------
    freq_hz, damping
        Natural frequency [Hz] and damping ratio per mode, shape ``(m,)``.
    freq_std, damping_std
        Their standard errors.
    gap_ratio
        Residual variance of the modal fit over the noise variance (1: the modes explain the records).
    chance
        Per mode, the chance that records holding no mode in its scan window would need an oscillator as much:
        the rise of the residual sum of squares when it is left out (the others needed held), over the fit's
        residual variance — χ² with two degrees of freedom per input for one trial frequency — taken over the
        window's independent frequencies (its width times the record's length) and the set's oscillators
        (Bonferroni; :func:`_chances`).  :func:`seen` reads it.
    """

    freq_hz: np.ndarray
    damping: np.ndarray
    freq_std: np.ndarray
    damping_std: np.ndarray
    gap_ratio: float
    chance: np.ndarray

    def select(self, keep: np.ndarray) -> "MeasuredModes":
        """The modes where ``keep`` (a boolean mask) is true; the modal fit's gap ratio stays the whole fit's."""
        keep = np.asarray(keep, dtype=bool)
        return MeasuredModes(self.freq_hz[keep], self.damping[keep], self.freq_std[keep], self.damping_std[keep],
                             self.gap_ratio, self.chance[keep])

    def in_order(self) -> "MeasuredModes":
        """The modes by increasing frequency.  The polish moves every mode freely, and an oscillator started far
        from its mode can pass a neighbour (measured: a compliant clamp's cantilever, the baseline's modes 0.8×
        the records', the fourth oscillator polished from 36 to 73.9 Hz past the fifth's 43.8): the modal match
        pairs measured and model modes in increasing order (:func:`diagnosis.search.mode_match.matched`), and an
        unordered set put every pattern's χ² at ~1e6."""
        order = np.argsort(self.freq_hz, kind="stable")
        return MeasuredModes(self.freq_hz[order], self.damping[order], self.freq_std[order],
                             self.damping_std[order], self.gap_ratio, self.chance[order])

    def to_dict(self) -> dict[str, list[float] | float]:
        """JSON-ready values."""
        return {"freq_hz": [float(v) for v in self.freq_hz], "damping": [float(v) for v in self.damping],
                "freq_std": [float(v) for v in self.freq_std], "damping_std": [float(v) for v in self.damping_std],
                "gap_ratio": float(self.gap_ratio), "chance": [float(v) for v in self.chance]}


def _oscillator(omega: float, zeta: float, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Numerators (displacement, velocity) and the denominator of the oscillator's exact discrete transfer
    function for an input linear between samples."""
    A = np.array([[0.0, 1.0], [-omega * omega, -2.0 * zeta * omega]])
    M = np.zeros((4, 4))
    M[:2, :2] = A * dt
    M[1, 2] = dt
    M[2, 3] = 1.0
    E = linalg.expm(M)
    Phi, g_hold, g_ramp = E[:2, :2], E[:2, 2], E[:2, 3]
    # z_{n+1} = Φ z_n + g_hold u_n + g_ramp (u_{n+1} − u_n): input vector g0 + g1 z
    g0, g1 = g_hold - g_ramp, g_ramp
    Psi = np.trace(Phi) * np.eye(2) - Phi                 # adj(zI − Φ) = zI − Ψ for 2×2
    den = np.array([1.0, -np.trace(Phi), np.linalg.det(Phi)])
    nums = np.array([[g1[j], g0[j] - Psi[j] @ g1, -Psi[j] @ g0] for j in range(2)])
    return nums[0], nums[1], den


def _mode_columns(inputs: Sequence[np.ndarray], omega: float, zeta: float, dt: float,
                  bandlimited: bool = False) -> np.ndarray:
    """Displacement and velocity responses of one oscillator to every input of every record, stacked (an input
    linear between samples); ``bandlimited``: the real and imaginary parts of its modal coordinate under the
    band-limited input between samples (:mod:`ebb_model.acquisition.bandlimited`; the same span, the residues are
    free)."""
    if bandlimited:
        return _bandlimited_columns(inputs, omega, zeta, dt)
    bx, bv, a = _oscillator(omega, zeta, dt)
    blocks = []
    for u in inputs:
        cols = []
        for k in range(u.shape[1]):
            cols += [signal.lfilter(bx, a, u[:, k]), signal.lfilter(bv, a, u[:, k])]
        blocks.append(np.column_stack(cols))
    return np.concatenate(blocks)


def _bandlimited_columns(inputs: Sequence[np.ndarray], omega: float, zeta: float, dt: float) -> np.ndarray:
    """The oscillator's pole ``s`` under the band-limited input: ``q⁺ = e^{sT} q + Σ_m W_m u_{k+m}``
    (:func:`ebb_model.acquisition.bandlimited.pole_weights`, the record held at its first and last sample beyond its
    ends); columns ``Re q`` and ``Im q`` per input."""
    from ebb_model.acquisition.bandlimited import HALF_WIDTH, pole_weights

    s = complex(-zeta * omega, omega * np.sqrt(max(1.0 - zeta * zeta, 0.0)))
    E, W = pole_weights(np.array([s]), dt)
    taps = W[::-1, 0]
    blocks = []
    for u in inputs:
        cols = []
        for k in range(u.shape[1]):
            padded = np.concatenate([np.full(HALF_WIDTH - 1, u[0, k]), u[:, k], np.full(HALF_WIDTH, u[-1, k])])
            v = np.convolve(padded, taps, mode="valid")             # v_n = Σ_m W_m u_{n+m}
            with np.errstate(over="ignore", invalid="ignore"):
                q = signal.lfilter([0.0, 1.0], [1.0, -E[0]], v)      # q_{n+1} = e^{sT} q_n + v_n
            cols += [q.real, q.imag]
        blocks.append(np.column_stack(cols))
    return np.concatenate(blocks)


def _input_columns(inputs: Sequence[np.ndarray], dt: float) -> np.ndarray:
    """Every input and its first two derivatives (quasi-static modes above the band, mass line)."""
    blocks = []
    for u in inputs:
        du = np.gradient(u, dt, axis=0)
        blocks.append(np.column_stack([u, du, np.gradient(du, dt, axis=0)]))
    return np.concatenate(blocks)


@dataclass(frozen=True)
class _Projection:
    """The records after the least-squares part of fixed columns is removed: an orthonormal basis ``U`` of the
    columns' range, the outputs' residual ``y`` against it, and the columns' largest singular value ``top``."""

    U: np.ndarray
    y: np.ndarray
    top: float


class _Problem:
    """Variable-projection residual of the modal model (module docstring).

    The residual is the outputs' component orthogonal to every column.  The columns held during a scan (the
    static ones and the other modes') are projected out once (:meth:`projection`), and each trial removes only
    its own mode's columns from what remains: the same residual as one least-squares solve with every column
    (``numpy.linalg.lstsq``'s rank cutoff, ``eps·max(n, p)`` of the largest singular value), a quarter of the
    work on a 44,000-sample record with eleven columns.
    """

    def __init__(self, inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray], sigma: np.ndarray, dt: float,
                 fixed: Sequence[tuple[float, float]], n_modes: int, bandlimited: bool = False):
        self.inputs, self.dt, self.bandlimited = list(inputs), dt, bandlimited
        self.y = np.concatenate(outputs) / sigma
        self.static = np.column_stack([_input_columns(self.inputs, dt)]
                                      + [_mode_columns(self.inputs, w, z, dt, bandlimited) for w, z in fixed])
        self.scale = 1.0 / np.maximum(np.linalg.norm(self.static, axis=0), 1e-300)
        self.scaled = self.static * self.scale
        n_cols = self.scaled.shape[1] + 2 * n_modes * self.inputs[0].shape[1]    # every column of the model
        self.rcond = np.finfo(float).eps * max(self.y.shape[0], n_cols)        # lstsq's default cutoff
        self.static_part = self.projection([])

    def columns(self, omega: float, zeta: float) -> np.ndarray:
        """One mode's response columns, each scaled to unit norm (once: a scan re-uses the other modes')."""
        b = _mode_columns(self.inputs, omega, zeta, self.dt, self.bandlimited)
        with np.errstate(over="ignore", invalid="ignore"):
            return b / np.maximum(np.sqrt(np.einsum("ij,ij->j", b, b)), 1e-300)

    def projection(self, blocks: Sequence[np.ndarray]) -> _Projection:
        """The static columns and the modes' ``blocks`` projected out of the records."""
        U, s, _ = np.linalg.svd(np.column_stack([self.scaled, *blocks]), full_matrices=False)
        U = U[:, s > self.rcond * s[0]]
        return _Projection(U, self.y - U @ (U.T @ self.y), float(s[0]))

    def residual(self, blocks: Sequence[np.ndarray], held: _Projection | None = None) -> np.ndarray:
        """The records' residual after the least-squares residues of the static columns, of the columns ``held``
        projects out (default: the static ones) and of the modes' ``blocks`` (from :meth:`columns`)."""
        held = self.static_part if held is None else held
        B = np.column_stack(blocks)
        if not np.all(np.isfinite(B)):
            # a trial mode the step took outside the stable range (its filter diverged): worse than no mode
            return 10.0 * self.y.ravel()
        # twice (Gram-Schmidt's rule): V orthogonal to the held range to round-off even when the columns nearly
        # lie in it (the residual itself is sensitive to that only to second order: held.y is orthogonal to it)
        for _ in range(2):
            B = B - held.U @ (held.U.T @ B)
        V, s, _ = np.linalg.svd(B, full_matrices=False)
        V = V[:, s > self.rcond * held.top]     # (the held columns' top singular value: ≥ 1, they have unit norm)
        return (held.y - V @ (V.T @ held.y)).ravel()


def estimate_modes(inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray], noise_std: np.ndarray, dt: float,
                   freq_hz: ArrayLike, damping: ArrayLike, *, above_hz: Iterable[float] = (),
                   search: float = SEARCH, bandlimited: bool = False, delays: Sequence[float] = ()) -> MeasuredModes:
    """Fit the frequency and damping of every mode in ``freq_hz`` to the records (module docstring).

    Parameters
    ----------
    inputs, outputs
        Per record: inputs ``(n, n_in)`` and outputs ``(n, n_out)`` from rest (the fit windows).
    noise_std
        Noise standard deviation per output.
    dt
        Sample time [s].
    freq_hz, damping
        The model's frequencies and damping ratios of the excited modes: where the scan starts.
    above_hz
        Frequencies of the first modes above the band (held; their responses are regressors).
    search
        Relative half-width of the scan around each model frequency.
    bandlimited
        The inputs band-limited between samples (the model's ``[time] input = "bandlimited"``), not linear.
    delays
        Each output channel's delay after the force's in samples
        (:func:`ebb_model.acquisition.channel_delay.effective_delays`), taken out of the records first (the oscillators
        are the beam's, shared by every output).

    Returns
    -------
    MeasuredModes
    """
    if any(delays):
        outputs = [delay_outputs(y, [-d for d in delays]) for y in outputs]
    sigma = np.asarray(noise_std, dtype=float)
    f = np.asarray(freq_hz, dtype=float).copy()
    z = np.clip(np.asarray(damping, dtype=float), 1e-4, 0.5).copy()
    m = f.size
    prob = _Problem(inputs, outputs, sigma, dt, [(2 * np.pi * fa, float(z[-1])) for fa in above_hz], m,
                    bandlimited)
    blocks = [prob.columns(2 * np.pi * f[i], z[i]) for i in range(m)]
    duration = sum(u.shape[0] for u in inputs) * dt / len(inputs)
    # scan each mode in turn with the others held (the cost of one mode is smooth only within its bandwidth)
    looks = np.ones(m)          # independent frequencies per scan window: how many places noise could offer
    for i in range(m):
        step = max(min(z[i] * f[i], 1.0 / duration) / 3.0, 1e-6 * f[i])
        lo, hi = f[i] * (1 - search), f[i] * (1 + search)
        if i > 0:
            lo = max(lo, 0.5 * (f[i - 1] + f[i]))
        if i + 1 < m:
            hi = min(hi, 0.5 * (f[i] + f[i + 1]))
        trials = np.linspace(lo, hi, int(min(MAX_TRIALS, max(3, (hi - lo) / step))))
        looks[i] = max(1.0, LOOKS_PER_BIN * (hi - lo) * duration)
        held = prob.projection(blocks[:i] + blocks[i + 1:])
        costs = []
        for ft in trials:
            r = prob.residual([prob.columns(2 * np.pi * ft, z[i])], held)
            costs.append(r @ r)
        f[i] = trials[int(np.argmin(costs))]
        blocks[i] = prob.columns(2 * np.pi * f[i], z[i])

    def oscillators(theta: np.ndarray) -> np.ndarray:
        fs, zs = theta[:m], np.exp(theta[m:])
        return prob.residual([prob.columns(2 * np.pi * fs[j], zs[j]) for j in range(m)])

    theta0 = np.concatenate([f, np.log(z)])
    size = oscillators(theta0).size

    def resid(theta: np.ndarray) -> np.ndarray:
        # a trial step of the unbounded Levenberg–Marquardt fit once sent ζ to 1e155, where the columns overflow:
        # beyond ZETA_REJECTED the residual is one the step cannot lower, so the step is rejected and damped
        if np.any(theta[m:] > np.log(ZETA_REJECTED)):
            return np.full(size, 1e100)
        return oscillators(theta)

    sol = optimize.least_squares(resid, theta0, method="lm", x_scale=np.concatenate([np.maximum(z * f, 1e-3),
                                                                                     np.ones(m)]))
    n = sol.fun.size
    var = float(sol.fun @ sol.fun) / max(n - theta0.size, 1)
    fs, zs = sol.x[:m], np.maximum(np.exp(sol.x[m:]), DAMPING_FLOOR)
    std = _standard_errors(resid, fs, zs, var)
    chance = _chances(prob, [prob.columns(2 * np.pi * fs[j], zs[j]) for j in range(m)], looks, var)
    return MeasuredModes(fs, zs, std[:m], std[m:], var, chance)


def _chances(prob: _Problem, blocks: list[np.ndarray], looks: np.ndarray, var: float) -> np.ndarray:
    """:attr:`MeasuredModes.chance` of every oscillator ``blocks[j]`` (its scan window's ``looks`` independent
    frequencies, the fit's residual variance ``var``), by backward elimination: the least needed oscillator whose
    chance reaches :data:`FALSE_MODE_RATE` is left out and the others' rises measured again without it — two
    oscillators on one mode each leave out little while the other stays, and the one kept must show the mode's
    whole rise."""
    m = len(blocks)
    dof = 2 * prob.inputs[0].shape[1]
    chance = np.ones(m)
    active = list(range(m))
    while active:
        r = prob.residual([blocks[j] for j in active])
        rss = float(r @ r)
        for j in active:
            left = prob.residual([blocks[k] for k in active if k != j]) if len(active) > 1 else prob.static_part.y
            rise = (float(left.ravel() @ left.ravel()) - rss) / max(var, np.finfo(float).tiny)
            chance[j] = min(1.0, m * looks[j] * float(stats.chi2.sf(rise, dof)))
        worst = max(active, key=lambda j: chance[j])
        if chance[worst] < FALSE_MODE_RATE:
            break
        active.remove(worst)
    return chance


def seen(modes: MeasuredModes) -> np.ndarray:
    """Which of ``modes`` the records need (a boolean mask): those whose :attr:`MeasuredModes.chance` is below
    :data:`FALSE_MODE_RATE`.

    An oscillator started where the records hold no mode still lands somewhere and takes up a little of the
    noise — with a frequency standard error that knows nothing of that.  Measured on a cantilever with a
    compliant clamp, one displacement sensor, twelve oscillators started from a baseline 0.8× the records'
    modes: three oscillators at no mode (78.4, 181 and 251 Hz, between true modes at 73.9, 157.9 and 273.7 Hz,
    their standard errors 0.1–0.2 % of the frequency) were matched to model modes all the same and put every
    modal pattern's χ² at ~1e5.  The rise a fitted oscillator finds in noise alone is far above one trial's χ²
    (its frequency and damping are the noise's best): on pure noise, twelve oscillators over ±12 % windows, the
    median rise 9.2 where one trial's is 1.4 — hence the window's independent frequencies in the chance."""
    return np.asarray(modes.chance < FALSE_MODE_RATE, dtype=bool)


def _standard_errors(resid: Callable[[np.ndarray], np.ndarray], fs: np.ndarray, zs: np.ndarray,
                     var: float) -> np.ndarray:
    """Standard errors (infinite: not determined) of the frequencies and damping ratios ``(fs, zs)``, from
    central differences in those variables themselves, scaled by the residual variance ``var``.

    Not from the fit's own Jacobian: its damping variable is the logarithm, and a damping the records do not
    determine runs towards zero, where the logarithm's column vanishes and the pseudo-inverse gives it a
    standard error of 0 — the most certain value of all (measured: a compressed beam's fourth mode, weakly
    seen by both sensors, ζ → 6e-20 with "std" 0, which put every candidate's modal match at ~1e8).  Here the
    damping is floored at :data:`DAMPING_FLOOR` and differenced with an absolute step, so such a damping gets
    the large standard error its flat residual implies."""
    m = fs.size
    x0 = np.concatenate([fs, zs])
    h = np.concatenate([1e-6 * fs, np.maximum(1e-4 * zs, 1e-7)])

    def r(x: np.ndarray) -> np.ndarray:
        return resid(np.concatenate([x[:m], np.log(x[m:])]))

    J = np.column_stack([(r(x0 + h[j] * e) - r(x0 - h[j] * e)) / (2.0 * h[j]) for j, e in enumerate(np.eye(2 * m))])
    # a variable the residual does not depend on at all (its column zero on the scale of a frequency's relative
    # change or a damping's change of 0.01) is not determined: infinite, not the pseudo-inverse's zero
    reach = np.linalg.norm(J, axis=0) * np.concatenate([fs, np.full(m, 0.01)])
    known = reach > UNDETERMINED * np.max(reach, initial=0.0)
    std = np.full(2 * m, np.inf)
    try:
        std[known] = np.sqrt(np.maximum(np.diag(np.linalg.pinv(J[:, known].T @ J[:, known])) * var, 0.0))
    except np.linalg.LinAlgError:
        pass
    return std
