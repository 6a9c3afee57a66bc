r"""Band-limited excitation signals for synthetic experiments.

Two kinds, both exactly band-limited to ``[f_lo, f_hi]`` on the DFT grid of
the record (``n`` samples at ``dt``: frequencies :math:`j/(n\,\Delta t)`) and
exactly zero-mean:

* ``"multisine"`` -- equal-amplitude cosines at every DFT frequency in the
  band with independent uniformly random phases (a random-phase multisine;
  Pintelon & Schoukens, *System Identification: A Frequency Domain
  Approach*, ch. 2).  Periodic over the record; independent phases make
  several inputs nearly uncorrelated.
* ``"chirp"`` -- a linear sweep from ``f_lo`` to ``f_hi`` over the record
  (random start phase per input), projected onto the band by zeroing its DFT
  outside ``[f_lo, f_hi]``.

A raised-cosine fade-in over the first ``fade`` fraction of the record (default
5 %) makes the force start at exactly zero with zero slope, so that a
simulation starting from rest is not kicked by a force step (which would
excite every mode, including unresolved ones); a multiple of the window is
then subtracted so that the mean stays exactly zero.  ``fade = 0`` keeps the
exactly band-limited (periodic) signal.  Each channel is finally scaled to
RMS ``amplitude``.
"""
from __future__ import annotations


import numpy as np

from ..checks import finite_scalar
from ..errors import ParameterError

__all__ = ["EXCITATION_KINDS", "band_limited_input"]

#: Accepted ``kind`` values of :func:`band_limited_input`.
EXCITATION_KINDS: tuple[str, ...] = ("multisine", "chirp")


def _positive_int(name: str, v: object, minimum: int) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < minimum:
        raise ParameterError(f"{name} must be an integer >= {minimum}, got {v!r}")
    return int(v)


def band_limited_input(
    n: int,
    dt: float,
    f_lo: float,
    f_hi: float,
    *,
    n_inputs: int = 1,
    amplitude: float = 1.0,
    seed: int = 0,
    kind: str = "multisine",
    fade: float = 0.05,
) -> np.ndarray:
    """Band-limited, zero-mean random excitation.

    Parameters
    ----------
    n
        Number of samples (>= 4).
    dt
        Sample interval [s] (> 0).
    f_lo, f_hi
        Band edges [Hz], ``0 <= f_lo < f_hi <= 1/(2 dt)``; at least one DFT
        frequency ``j/(n dt)``, ``j >= 1``, must lie in the band.
    n_inputs
        Number of channels (columns), each with its own random phases.
    amplitude
        RMS of each channel (> 0), in the unit of the force [N].
    seed
        Seed of :func:`numpy.random.default_rng`; equal seeds give equal
        signals.
    kind
        ``"multisine"`` or ``"chirp"`` (see the module docstring).
    fade
        Fraction of the record, in ``[0, 0.5]``, faded in with a raised
        cosine (0: no fade).

    Returns
    -------
    numpy.ndarray
        Shape ``(n, n_inputs)``, sample ``k`` at ``t_k = k dt``.

    Raises
    ------
    ParameterError
        Invalid sizes, band outside ``[0, Nyquist]`` or without any DFT
        frequency, unknown kind.
    """
    n = _positive_int("n", n, 4)
    n_inputs = _positive_int("n_inputs", n_inputs, 1)
    dt = finite_scalar("dt", dt, numbers_only=True)
    if dt <= 0.0:
        raise ParameterError(f"dt must be > 0, got {dt:g}")
    f_lo = finite_scalar("f_lo", f_lo, numbers_only=True)
    f_hi = finite_scalar("f_hi", f_hi, numbers_only=True)
    nyq = 0.5 / dt
    if not 0.0 <= f_lo < f_hi <= nyq * (1.0 + 1e-12):
        raise ParameterError(
            f"band [f_lo, f_hi] = [{f_lo:g}, {f_hi:g}] Hz must satisfy 0 <= f_lo < f_hi <= Nyquist = {nyq:g} Hz"
        )
    amplitude = finite_scalar("amplitude", amplitude, numbers_only=True)
    if amplitude <= 0.0:
        raise ParameterError(f"amplitude must be > 0, got {amplitude:g}")
    if kind not in EXCITATION_KINDS:
        raise ParameterError(f"kind must be one of {', '.join(EXCITATION_KINDS)}, got {kind!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise ParameterError(f"seed must be an integer, got {seed!r}")
    fade = finite_scalar("fade", fade, numbers_only=True)
    if not 0.0 <= fade <= 0.5:
        raise ParameterError(f"fade must lie in [0, 0.5], got {fade:g}")
    n_fade = round(fade * n)
    window = np.ones(n)
    if n_fade >= 2:
        window[:n_fade] = 0.5 - 0.5 * np.cos(np.pi * np.arange(n_fade) / n_fade)

    freqs = np.fft.rfftfreq(n, dt)
    band = (freqs >= f_lo) & (freqs <= f_hi) & (freqs > 0.0)
    if n % 2 == 0:
        band[-1] = False  # the Nyquist bin cannot carry an arbitrary phase
    if not np.any(band):
        raise ParameterError(
            f"no DFT frequency j/(n dt) (resolution {1.0 / (n * dt):g} Hz) lies in "
            f"[{f_lo:g}, {f_hi:g}] Hz; lengthen the record or widen the band"
        )
    rng = np.random.default_rng(int(seed))
    out = np.empty((n, n_inputs))
    t = np.arange(n) * dt
    T = n * dt
    for j in range(n_inputs):
        if kind == "multisine":
            spec = np.zeros(freqs.size, dtype=complex)
            spec[band] = np.exp(2j * np.pi * rng.random(int(band.sum())))
        else:
            phase0 = 2.0 * np.pi * rng.random()
            sweep = np.cos(phase0 + 2.0 * np.pi * (f_lo * t + 0.5 * (f_hi - f_lo) / T * t * t))
            spec = np.fft.rfft(sweep)
            spec[~band] = 0.0
        x = np.fft.irfft(spec, n)
        if n_fade >= 2:
            x = window * x
            x -= (x.mean() / window.mean()) * window  # exactly zero mean, still x[0] = 0
        rms = float(np.sqrt(np.mean(x * x)))
        if not rms > 0.0:  # pragma: no cover - a non-empty band always has energy
            raise ParameterError("the band-limited signal vanished; widen the band")
        out[:, j] = x * (amplitude / rms)
    return out
