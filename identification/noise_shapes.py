"""The shapes a sensor's noise spectrum may take outside the excited band (:mod:`identification.noise_model` fits
them): a polynomial in ``log f`` (white, a power law such as 1/f, a curved one), a white floor plus one
second-order resonance (a transducer's mounted resonance), each ending in the acquisition's anti-alias edge when
the record has one — fitted to the record's channels at once (:func:`common_edge`): one acquisition filters every
channel alike, and fitted per channel the edge would trade off against each one's slope.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["EDGE_CORNERS", "EDGE_ORDERS", "EDGE_RANGE", "MIN_QUIET", "TOP", "common_edge", "fit_resonance",
           "log_edge", "log_polynomial", "log_resonance", "robust_polynomial", "shapes"]

#: Fraction of Nyquist above which anti-alias filters may pull the measured spectrum below the noise: excluded.
TOP = 0.8
#: Fewest quiet bins (every other one is used) for a spectrum's shape.
MIN_QUIET = 8
#: Orders of the anti-alias edge a quiet spectrum may end in (``20 n`` dB per decade beyond the corner; a gentler
#: edge would bend the whole quiet range and trade off against the slope carried across the band).
EDGE_ORDERS = (4, 6, 8)
#: Corners tried for an edge: log-spaced over this range, in units of the Nyquist frequency (an acquisition's
#: anti-alias corner lies near the top of its band — 0.39 of the sampling rate with the usual 2.56 ratio, 0.45 for
#: a sigma-delta converter's —; a corner lower down would trade off against the shape's slope, which is carried
#: across the excited band, so none is tried there).
EDGE_RANGE = (0.5, 2.0)
EDGE_CORNERS = 32


def log_polynomial(x: np.ndarray, logS: np.ndarray, degree: int, weights: np.ndarray) -> np.ndarray:
    """Weighted least-squares coefficients of ``log S`` as a polynomial of degree ``degree`` in ``x = log f``."""
    V = np.vander(x, degree + 1)
    return np.linalg.lstsq(V * weights[:, None], logS * weights, rcond=None)[0]


def log_resonance(p: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``log(s_w + s_r |H(f)|²)``, ``H`` a second-order low-pass resonance at ``f_0`` with damping ratio ``ζ``;
    ``p = (log s_w, log s_r, log f_0, log ζ)``: a white floor plus a transducer's (or an amplifier's)
    resonance — flat at ``s_w + s_r`` well below ``f_0``, a peak ``≈ s_r / 4ζ²`` at it, ``s_w`` far above."""
    r = f / math.exp(p[2])
    h2 = 1.0 / ((1.0 - r * r) ** 2 + (2.0 * math.exp(p[3]) * r) ** 2)
    return np.logaddexp(p[0], p[1] + np.log(h2))


def fit_resonance(f: np.ndarray, logS: np.ndarray, var_log: float) -> tuple[np.ndarray, np.ndarray] | None:
    """Least-squares fit of :func:`log_resonance` to the log spectrum (outlying bins dropped as for the
    polynomial shapes): ``(p, used)``, or None when the bins show no peak to start from."""
    from scipy import optimize

    k = int(np.argmax(logS))
    if k == 0 or k == len(f) - 1:
        return None                          # no interior peak: no resonance in view
    z0 = 0.2
    p0 = np.array([float(np.median(logS)), float(logS[k]) + math.log(4 * z0 * z0), math.log(f[k]), math.log(z0)])
    lo = np.array([-np.inf, -np.inf, math.log(f[0]), math.log(0.005)])
    hi = np.array([np.inf, np.inf, math.log(f[-1]), math.log(2.0)])
    w = np.ones(len(f))
    p = p0
    for _ in range(3):
        res = optimize.least_squares(lambda q: (logS - log_resonance(q, f)) * w, p, bounds=(lo, hi))
        p = res.x
        dev = logS - log_resonance(p, f)
        w = (dev <= 4.0 * math.sqrt(var_log) + np.median(dev)).astype(float)
    return p, w > 0


def log_edge(f: np.ndarray, corner: float, order: int) -> np.ndarray:
    """``− log(1 + (f/f_c)^{2n})``: the log power gain of an order-``n`` Butterworth low-pass (an anti-alias
    filter's edge)."""
    return -np.log1p((np.asarray(f, dtype=float) / corner) ** (2 * order))


def robust_polynomial(x: np.ndarray, logS: np.ndarray, d: int, var_log: float) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients of the degree-``d`` polynomial in ``x`` fitted to ``logS`` with the bins that carry more than
    noise (≥ 4σ above the fit) dropped, and the bins used."""
    w = np.ones(x.size)
    for _ in range(3):
        c = log_polynomial(x, logS, d, w)
        dev = logS - np.polyval(c, x)
        w = (dev <= 4.0 * math.sqrt(var_log) + np.median(dev)).astype(float)
    return c, w > 0


def common_edge(f: np.ndarray, S: np.ndarray, nu: float, quiet: np.ndarray) -> tuple[float, int] | None:
    """The anti-alias edge ``(corner, order)`` the quiet bins of a record's sensors end in, or ``None``.

    One acquisition filters every channel alike, so the edge is fitted to all sensors at once: for each corner
    (:data:`EDGE_RANGE`) and order (:data:`EDGE_ORDERS`) the sum over the sensors of the best log-polynomial
    fit (degree 0 or 1) of ``log S − edge``; the edge is taken when it lowers that sum by more than BIC's price
    of its two parameters.  Fitted per sensor the edge would trade off against each one's slope (a white floor
    ending early mimics 1/f ending late); together the steep channels fix the corner for the flat ones."""
    from scipy.special import polygamma

    nyquist = float(f[-1])
    keep = quiet & (f > 0) & (f <= TOP * nyquist) & np.all(S > 0, axis=1)
    idx = np.flatnonzero(keep)[::2]
    if idx.size < MIN_QUIET + 4:
        return None
    fq, logS = f[idx], np.log(S[idx])
    var_log = float(polygamma(1, nu / 2.0))
    x = np.log(fq)

    def cost(edge: np.ndarray, resonance: bool = False) -> float:
        total = 0.0
        for s in range(logS.shape[1]):
            best = np.inf
            for d in (0, 1):
                c, used = robust_polynomial(x, logS[:, s] - edge, d, var_log)
                rss = float(np.sum((logS[:, s] - edge - np.polyval(c, x))[used] ** 2)) / var_log
                best = min(best, rss + 16.0 * int((~used).sum()) + (d + 1) * math.log(idx.size))
            fit = fit_resonance(fq, logS[:, s], var_log) if resonance else None
            if fit is not None:
                p, used = fit
                rss = float(np.sum((logS[:, s] - log_resonance(p, fq))[used] ** 2)) / var_log
                best = min(best, rss + 16.0 * int((~used).sum()) + 4 * math.log(idx.size))
            total += best
        return total

    # without an edge every shape may serve (a resonance rolls off too); with one, the polynomials: an edge is
    # taken only where it explains what nothing else does
    plain = cost(np.zeros(idx.size), resonance=True)
    found = min(((cost(log_edge(fq, corner, n)), float(corner), n)
                 for n in EDGE_ORDERS
                 for corner in np.geomspace(EDGE_RANGE[0] * nyquist, EDGE_RANGE[1] * nyquist, EDGE_CORNERS)),
                key=lambda t: t[0])
    if found[0] + 2.0 * math.log(idx.size * logS.shape[1]) < plain:
        return found[1], found[2]
    return None


def shapes(f: np.ndarray, logS: np.ndarray, var_log: float, max_degree: int,
            edge: tuple[float, int] | None = None):
    """The candidate shapes of the quiet bins' log spectrum: ``(label, log-shape function of f, n_params, used)``
    — polynomials in ``log f`` of degree ``0 … max_degree`` (ending in the record's anti-alias ``edge`` when it
    has one, :func:`common_edge`) and a white floor plus one resonance."""
    x = np.log(f)
    e = np.zeros(f.size) if edge is None else log_edge(f, *edge)
    tail = "" if edge is None else f", ending in an order-{edge[1]} edge at {edge[0]:.4g} Hz"
    for d in range(0, max_degree + 1):
        if f.size < d + 4:
            break
        c, used = robust_polynomial(x, logS - e, d, var_log)
        if edge is None:
            yield ("white" if d == 0 else f"log-polynomial {d}",
                   (lambda g, c=c: np.polyval(c, np.log(g))), d + 1, used)
        else:
            yield (f"log-polynomial {d}{tail}",
                   (lambda g, c=c, fc=edge[0], n=edge[1]: np.polyval(c, np.log(g)) + log_edge(g, fc, n)),
                   d + 1, used)
    if f.size >= 8:
        fit = fit_resonance(f, logS - e, var_log)
        if fit is not None:
            p, used = fit
            if edge is None:
                yield "resonance", (lambda g, p=p: log_resonance(p, g)), 4, used
            else:
                yield (f"resonance{tail}",
                       (lambda g, p=p, fc=edge[0], n=edge[1]: log_resonance(p, g) + log_edge(g, fc, n)), 4, used)
