r"""The exact scheme's per-pole algebra: each continuous pole integrated over a sample, and the real 2×2 blocks.

A pole ``s`` of the diagonalised modal system (:mod:`ebb_model.exact.exact_modal`) advances over a sample ``T`` as
``z⁺ = e^{sT} z + Σ_j W_j u[k + j]``, the weights ``W_j`` the integrals of ``e^{s(T−τ)}`` against the Lagrange
basis of the input reconstruction (:data:`INPUT_TAPS`); conjugate pairs of discrete poles then become real 2×2
blocks (:func:`modal_blocks`).  Both run once per parameter set on a few hundred poles: compiled loops (numba),
as the NumPy forms of the same formulas spent ~0.1 ms per evaluation in small array operations (a third of an
R1 evaluation within one family of modes).
"""
from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import numba
import numpy as np

from ..acquisition import bandlimited

__all__ = ["INPUT_TAPS", "POLYNOMIAL_HOLDS", "ADVANCE", "polynomial_integrals", "pole_integrals", "input_weights",
           "Blocks", "modal_blocks"]

#: Most terms of the series of :func:`polynomial_integrals` (``|z| < 1``): the last is below ``1/24! ≈ 2e-24``.
_SERIES_TERMS = 24
#: The series' coefficients ``p!/(k + p + 1)!`` per degree ``p`` (rows) and term ``k`` (columns).
_SERIES = np.array([[math.factorial(p) / math.factorial(k + p + 1) for k in range(_SERIES_TERMS)]
                    for p in range(4)])
_SERIES.setflags(write=False)
#: What the terms left out may add, relative to the series' first term ``1/(p + 1)``: a sixteenth of an ulp.
_SERIES_TOLERANCE = 2.0 ** -56


def _series_radii() -> np.ndarray:
    """``r[p, K]``: the largest ``|z| ≤ 1`` for which the first ``K`` terms of degree ``p``'s series suffice —
    the rest, ``Σ_{k ≥ K} |z|^k p!/(k + p + 1)! ≤ |z|^K p!/(K + p + 1)! / (1 − |z|/(K + p + 2))`` (each term at
    most ``|z|/(k + p + 2)`` of the one before), at most :data:`_SERIES_TOLERANCE` of ``1/(p + 1)``; 0 where no
    ``|z|`` does; 1 for all :data:`_SERIES_TERMS`."""
    r = np.zeros((4, _SERIES_TERMS + 1))
    for p in range(4):
        lead = 1.0 / (p + 1)
        for K in range(1, _SERIES_TERMS):
            def rest(x: float) -> float:
                return x ** K * _SERIES[p, K - 1] / (K + p + 1) / (1.0 - x / (K + p + 2))
            lo, hi = 0.0, 1.0
            for _ in range(60):                        # bisection: rest() grows with x
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if rest(mid) <= _SERIES_TOLERANCE * lead else (lo, mid)
            r[p, K] = lo
        r[p, _SERIES_TERMS] = 1.0
    r.setflags(write=False)
    return r


#: :func:`_series_radii`, once.
_SERIES_RADII = _series_radii()

#: Sample offsets the input reconstruction between ``t_k`` and ``t_{k+1}`` reads, per ``[time] input``:
#: held (``zoh``), the straight line (``foh``), the cubic through four samples ``k−2 … k+1`` (``cubic``), and the
#: band-limited reconstruction (``bandlimited``, :mod:`ebb_model.acquisition.bandlimited`), whose offsets are relative
#: to the record read :data:`~ebb_model.acquisition.bandlimited.ADVANCE` samples ahead.
INPUT_TAPS = {"zoh": (0,), "foh": (0, 1), "cubic": (-2, -1, 0, 1), "bandlimited": bandlimited.TAPS}
#: The holds that are polynomials through their taps (:data:`LAGRANGE`); the rest are computed per pole.
POLYNOMIAL_HOLDS = ("zoh", "foh", "cubic")
#: How many samples ahead of the record each hold reads the input (the lookahead ``u[k+1]`` aside).
ADVANCE = {hold: bandlimited.ADVANCE if hold == "bandlimited" else 0 for hold in INPUT_TAPS}


@numba.njit(cache=True, nogil=True)
def _integrals(s, T, degree, series, radii, E, I):  # pragma: no cover - compiled
    for n in range(s.size):
        z = s[n] * T
        E[n] = cmath.exp(z)
        size = abs(z)
        if size < 1.0:              # the highest degree by its series, the lower ones by the recurrence downwards
            terms = 1
            while radii[degree, terms] < size:         # as many terms as |z| needs (_series_radii)
                terms += 1
            acc = complex(series[degree, terms - 1])
            for k in range(terms - 2, -1, -1):
                acc = acc * z + series[degree, k]
            I[degree, n] = T * acc
            for p in range(degree, 0, -1):
                acc = (z * acc + 1.0) / p
                I[p - 1, n] = T * acc
        else:                       # I_0 = (e^z − 1)/z with e^z − 1 to full accuracy, then upwards
            x, y = z.real, z.imag
            h = math.sin(0.5 * y)
            acc = complex(math.expm1(x) * math.cos(y) - 2.0 * h * h, math.exp(x) * math.sin(y)) / z
            I[0, n] = T * acc
            for p in range(1, degree + 1):
                acc = (p * acc - 1.0) / z
                I[p, n] = T * acc


def polynomial_integrals(s: np.ndarray, T: float, degree: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """``e^{sT}`` and ``I_p = ∫₀ᵀ e^{s(T−τ)} (τ/T)^p dτ`` for ``p = 0 … degree``, each pole, to round-off.

    With ``z = sT``: ``I_0 = T (e^z − 1)/z`` and ``I_p = (p I_{p−1} − T)/z`` (integration by parts), stable for
    ``|z| ≥ 1`` (the recurrence amplifies round-off by at most ``p!/|z|^p``); below, the highest degree by its
    series ``T Σ_k z^k p!/(k + p + 1)!`` (Horner's rule, as many terms as ``|z|`` needs for what is left out to
    stay below a sixteenth of an ulp of the first, :func:`_series_radii`; at most :data:`_SERIES_TERMS`) and
    the lower ones by the recurrence run downwards, ``I_{p−1} = (z I_p + T)/p``, which damps round-off by ``|z|/p``.
    ``degree`` at most 3 (the cubic's).  An unstable pole's ``e^{sT}`` may overflow to ``inf`` (the stability
    check catches it).  Returns ``E`` (n,) and ``I`` (degree + 1, n).
    """
    if not 0 <= degree < _SERIES.shape[0]:
        raise ValueError(f"degree must lie in 0 … {_SERIES.shape[0] - 1}, got {degree}")
    z = np.ascontiguousarray(s, dtype=complex).reshape(-1)
    E = np.empty(z.size, dtype=complex)
    I = np.empty((degree + 1, z.size), dtype=complex)
    _integrals(z, float(T), degree, _SERIES, _SERIES_RADII, E, I)
    return E, I


def pole_integrals(s: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``e^{sT}``, ``φ₀ = ∫₀ᵀ e^{s(T−τ)} dτ`` and ``φ₁ = ∫₀ᵀ e^{s(T−τ)} τ/T dτ`` for each pole, to round-off
    (:func:`polynomial_integrals` of degree 1)."""
    E, I = polynomial_integrals(s, T, 1)
    return E, I[0], I[1]


def _lagrange_coefficients(taps: tuple[int, ...]) -> np.ndarray:
    """``c[j, p]``: the Lagrange basis polynomial of node ``taps[j]`` is ``ℓ_j(σ) = Σ_p c[j, p] σ^p``."""
    t = np.asarray(taps, dtype=float)
    coef = np.zeros((t.size, t.size))
    for j in range(t.size):                               # ℓ_j(σ) = Π_{i≠j} (σ − t_i)/(t_j − t_i)
        others = np.delete(t, j)
        coef[j] = np.atleast_1d(np.poly(others))[::-1] / np.prod(t[j] - others)
    return coef


#: :func:`_lagrange_coefficients` of each input reconstruction's taps (constants: built once, read per model).
LAGRANGE = {hold: _lagrange_coefficients(INPUT_TAPS[hold]) for hold in POLYNOMIAL_HOLDS}
#: Where each tap of :data:`INPUT_TAPS` goes in :func:`modal_blocks`: the column block of sample ``k − j`` (``j``),
#: or ``−1`` for the lookahead.
_COLUMNS = {hold: np.array([-1 if t == 1 else -t for t in taps]) for hold, taps in INPUT_TAPS.items()}


def input_weights(s: np.ndarray, T: float, hold: str) -> tuple[np.ndarray, np.ndarray]:
    """``e^{sT}`` and the weights ``W`` (taps, n) of ``x⁺ = e^{sT} x + Σ_j W_j u[k + j]`` per pole.

    The input between samples is the polynomial through the samples at the offsets :data:`INPUT_TAPS`
    (Lagrange basis ``ℓ_j(σ)``, ``σ = (t − t_k)/T``), so ``W_j = Σ_p c_{jp} I_p`` with ``ℓ_j = Σ_p c_{jp} σ^p``.
    The cubic reads one sample ahead, as the straight line does, and two behind: its error is ``O(T⁴)``
    against ``O(T²)`` — at fs/13 the straight line's amplitude error is 2 %, the cubic's 0.2 %.  The band-limited
    reconstruction's weights are not a polynomial's (:func:`ebb_model.acquisition.bandlimited.pole_weights`).
    """
    if hold not in POLYNOMIAL_HOLDS:
        return bandlimited.pole_weights(s, T)
    E, I = polynomial_integrals(s, T, len(INPUT_TAPS[hold]) - 1)
    return E, LAGRANGE[hold] @ I


@numba.njit(cache=True, nogil=True)
def _blocks(lam, W, inputs, CV, A, B, column, T, G, H, Cb, Dh):  # pragma: no cover - compiled
    m = inputs.shape[1]
    for b in range(A.size):
        a, c = A[b], B[b]
        if c < 0:                                   # a conjugate pair, by its pole with Im λ > 0
            T[b, 0, 0] = T[b, 1, 1] = lam[a].real
            T[b, 0, 1], T[b, 1, 0] = -lam[a].imag, lam[a].imag
            for o in range(CV.shape[0]):
                Cb[o, b, 0], Cb[o, b, 1] = 2.0 * CV[o, a].real, -2.0 * CV[o, a].imag
        else:                                       # two real poles
            T[b, 0, 0], T[b, 1, 1] = lam[a].real, lam[c].real
            T[b, 0, 1] = T[b, 1, 0] = 0.0
            for o in range(CV.shape[0]):
                Cb[o, b, 0], Cb[o, b, 1] = CV[o, a].real, CV[o, c].real
        for q in range(W.shape[0]):                 # tap q: into column block column[q], or the lookahead (-1)
            for l in range(m):
                ba = W[q, a] * inputs[a, l]
                g0 = ba.real
                g1 = ba.imag if c < 0 else (W[q, c] * inputs[c, l]).real
                if column[q] < 0:
                    H[b, 0, l], H[b, 1, l] = g0, g1
                else:
                    G[b, 0, column[q] * m + l], G[b, 1, column[q] * m + l] = g0, g1
    if H.shape[0]:                                  # the lookahead made causal: ξ = z − Γ₁ u
        for b in range(A.size):
            for l in range(m):
                G[b, 0, l] += T[b, 0, 0] * H[b, 0, l] + T[b, 0, 1] * H[b, 1, l]
                G[b, 1, l] += T[b, 1, 0] * H[b, 0, l] + T[b, 1, 1] * H[b, 1, l]
        for o in range(CV.shape[0]):
            for l in range(m):
                acc = 0.0
                for b in range(A.size):
                    acc += Cb[o, b, 0] * H[b, 0, l] + Cb[o, b, 1] * H[b, 1, l]
                Dh[o, l] = acc


@numba.njit(cache=True, nogil=True)
def _pole_blocks(s, T, degree, series, radii, lagrange, inputs, CV, column,
                 E, I, W, A, B, freqs, Tb, G, H, Cb, Dh):  # pragma: no cover - compiled
    # the poles' integrals and input weights (input_weights), then the blocks chosen by the discrete poles, into
    # the arrays given (allocated by the caller: a fresh FMU process compiles this once, and every array type
    # made here would lengthen that); 0, or 1 for an odd number of real poles, 2 for poles not in pairs
    n = s.size
    _integrals(s, T, degree, series, radii, E, I)
    for q in range(lagrange.shape[0]):
        for d in range(degree + 1):
            for j in range(n):
                W[q, j] += lagrange[q, d] * I[d, j]
    return _select_blocks(s, E, W, inputs, CV, column, A, B, freqs, Tb, G, H, Cb, Dh)


@numba.njit(cache=True, nogil=True)
def _select_blocks(s, E, W, inputs, CV, column, A, B, freqs, Tb, G, H, Cb, Dh):  # pragma: no cover - compiled
    # the blocks chosen by the discrete poles E (module docstring of modal_blocks), from the weights W
    n, nb = s.size, A.size
    upper, real = 0, 0
    for j in range(n):
        if E[j].imag > 0:
            upper += 1
        elif E[j].imag == 0:
            real += 1
    if real % 2:
        return 1
    if upper + real // 2 != nb:
        return 2
    b, first = 0, -1
    for j in range(n):                              # the pairs, by their pole with Im λ > 0, in order
        if E[j].imag > 0:
            A[b], B[b], freqs[b] = j, -1, abs(s[j])
            b += 1
    for j in range(n):                              # then the real poles two by two, in order
        if E[j].imag == 0:
            if first < 0:
                first = j
            else:
                A[b], B[b], freqs[b] = first, j, max(abs(s[first]), abs(s[j]))
                b, first = b + 1, -1
    _blocks(E, W, inputs, CV, A, B, column, Tb, G, H, Cb, Dh)
    return 0


@dataclass(frozen=True)
class Blocks:
    """The real block form of :func:`modal_blocks`: ``T`` (nb, 2, 2); ``G`` (nb, 2, m·(delays + 1)), column
    ``j m + l`` input ``l`` at sample ``k − j``, the lookahead folded in; ``hold`` (nb, 2, m) the lookahead ``Γ₁``
    (``None`` without one); ``C`` (p, nb, 2); ``D_hold`` (p, m) the feedthrough the fold adds (``C Γ₁``);
    ``frequencies`` (nb,) each block's continuous natural frequency ``|s|`` [rad/s]; ``filters`` how many of the
    last blocks are the filters'."""

    T: np.ndarray
    G: np.ndarray
    hold: np.ndarray | None
    C: np.ndarray
    D_hold: np.ndarray
    frequencies: np.ndarray
    filters: int


def modal_blocks(s: np.ndarray, T: float, hold: str, inputs: np.ndarray, CV: np.ndarray,
                 filters_from: int | None = None) -> Blocks:
    """Real 2×2 blocks of the diagonal continuous system ``ż = diag(s) z + inputs u``, ``y = CV z`` — ``s`` (n,),
    ``inputs`` (n, m), ``CV`` (p, n) — integrated exactly over the sample ``T`` under the input reconstruction
    ``hold`` (:func:`input_weights`: ``z⁺ = λ z + Σ_q W_q inputs u[k + taps_q]``, ``λ = e^{sT}``), its lookahead
    ``u[k+1]`` made causal (:class:`Blocks`).  One compiled pass (the NumPy form of the same steps spent more time
    in small array operations than in the arithmetic).

    A conjugate pair ``(z, z̄)`` becomes ``(r, m) = (Re z, Im z)``: ``x = 2 Re(v z) = 2 Re v · r − 2 Im v · m``
    and ``[r; m]⁺ = [[Re λ, −Im λ], [Im λ, Re λ]] [r; m] + [Re b; Im b] u``; the pairs' blocks come first, by
    their pole with ``Im λ > 0``, then real poles in pairs, in their order, as diagonal blocks.  The blocks are
    chosen by the discrete poles: a mode above the Nyquist frequency can have ``Im λ < 0`` with ``Im s > 0``.
    Poles from index ``filters_from`` on are the anti-alias filters': their blocks go last.  The band-limited
    reconstruction's weights come from :func:`ebb_model.acquisition.bandlimited.pole_weights` (its taps relative to the
    record read :data:`ADVANCE` samples ahead), the rest as above.

    Raises
    ------
    numpy.linalg.LinAlgError
        An odd number of real poles, or poles not in conjugate pairs.
    """
    taps = INPUT_TAPS[hold]
    s = np.ascontiguousarray(s, dtype=complex).reshape(-1)
    inputs = np.ascontiguousarray(inputs, dtype=complex)
    n, m, p, nb, degree = s.size, inputs.shape[1], CV.shape[0], s.size // 2, len(taps) - 1
    lookahead = 1 in taps
    A, B = np.empty(nb, dtype=np.int64), np.empty(nb, dtype=np.int64)
    freqs = np.empty(nb)
    Tb, Cb = np.empty((nb, 2, 2)), np.empty((p, nb, 2))
    G = np.zeros((nb, 2, m * (len(taps) - 1 if lookahead else len(taps))))
    H = np.empty((nb if lookahead else 0, 2, m))
    Dh = np.zeros((p, m))
    CV = np.ascontiguousarray(CV, dtype=complex)
    if hold in POLYNOMIAL_HOLDS:
        status = _pole_blocks(s, float(T), degree, _SERIES, _SERIES_RADII, LAGRANGE[hold], inputs, CV,
                              _COLUMNS[hold], np.empty(n, dtype=complex), np.empty((degree + 1, n), dtype=complex),
                              np.zeros((len(taps), n), dtype=complex), A, B, freqs, Tb, G, H, Cb, Dh)
    else:
        E, W = bandlimited.pole_weights(s, float(T))
        status = _select_blocks(s, E, W, inputs, CV, _COLUMNS[hold], A, B, freqs, Tb, G, H, Cb, Dh)
    if status == 1:
        raise np.linalg.LinAlgError("odd number of real poles")
    if status == 2:
        raise np.linalg.LinAlgError("the poles are not in conjugate pairs")
    filters = 0
    if filters_from is not None:                    # the filters' blocks last, each part in its order
        is_filter = A >= filters_from
        filters = int(np.count_nonzero(is_filter))
        if filters:
            order = np.argsort(is_filter, kind="stable")
            Tb, G, H, Cb, freqs = Tb[order], G[order], H[order] if H.shape[0] else H, Cb[:, order], freqs[order]
    return Blocks(Tb, G, H if 1 in taps else None, Cb, Dh, freqs, int(filters))
