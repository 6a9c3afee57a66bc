r"""Bistritz's unit-circle zero-location test for real polynomials.

For a real polynomial

.. math::

    D(z) = d_n z^n + d_{n-1} z^{n-1} + \dots + d_0 ,

the test counts the zeros of :math:`D` inside, on and outside the unit circle
without computing them.  It only uses additions, multiplications and about
``n`` divisions, so with :class:`fractions.Fraction` coefficients it runs in exact
rational arithmetic and gives exact verdicts, including the *singular* cases
(zeros on the unit circle, reciprocal zero pairs :math:`r, 1/r`).  (The
input handling and the polynomial operations it uses are in
:mod:`ebb_model.stability.polynomials`.)

The algorithm
-------------
Write :math:`P^\sharp(z) = z^{k} P(1/z)` for the reciprocal of a polynomial of
*nominal* degree ``k`` (the coefficient list reversed).  A polynomial is
*symmetric* if :math:`P^\sharp = P`.

0. **Reduction.**  Exact zero coefficients of the highest powers are dropped;
   exact zero coefficients of the lowest powers are zeros at :math:`z = 0`
   (counted *inside*) and are divided out; zeros at :math:`z = 1`
   (:math:`D(1) = 0`) are divided out by synthetic division by :math:`z - 1`
   and counted *on* the circle.  The remaining polynomial, again called
   :math:`D`, has degree ``n`` and :math:`D(1) \ne 0`.

1. **Initial pair** (both symmetric, of nominal degrees ``n`` and ``n - 1``):

   .. math::

       T_n(z) = D(z) + D^\sharp(z), \qquad
       T_{n-1}(z) = \frac{D(z) - D^\sharp(z)}{z - 1}.

2. **Three-term recursion**, ``k = n-1, ..., 1``.  *Normal step*
   (:math:`T_k(0) \ne 0`):

   .. math::

       T_{k-1}(z) = \frac{\delta_k (1 + z) T_k(z) - T_{k+1}(z)}{z},
       \qquad \delta_k = \frac{T_{k+1}(0)}{T_k(0)} .

   *Nonessential singularity* (:math:`T_k(0) = 0`, :math:`T_k \not\equiv 0`):
   let ``m`` be the number of vanishing low-order coefficients of
   :math:`T_k = \sum_{i=m}^{k-m} t_i z^i` (by symmetry as many high-order
   ones vanish), then [2]_

   .. math::

       T_{k-1}(z) = \frac{\delta_k (z^{-m} + z^{m+1}) T_k(z) - T_{k+1}(z)}{z},
       \qquad \delta_k = \frac{T_{k+1}(0)}{t_m} ,

   which is again a symmetric polynomial of nominal degree ``k - 1`` (for
   ``m = 0`` it is the normal step).  At :math:`z = 1` both steps read
   :math:`T_{k-1}(1) = 2\delta_k T_k(1) - T_{k+1}(1)`.

   *Essential singularity* (a newly computed :math:`T_{j} \equiv 0`).  Then
   :math:`T_{j+1}` is (a multiple of) the greatest common divisor of
   :math:`D` and :math:`D^\sharp`, i.e. the largest symmetric factor of
   :math:`D`; it holds all zeros on the unit circle and all reciprocal pairs.
   The first time this happens record :math:`s = j + 1 = \deg T_{j+1}` and
   the position of :math:`T_s` in the sequence.  The vanished polynomial and
   its successor are replaced by restarting the test on

   .. math::

       p(z) = -z^{s-1}\, T_s'(1/z) = z\,T_s'(z) - s\,T_s(z)
       \qquad (\text{nominal degree } s - 1),

   i.e. :math:`T_{s-1} := p + p^\sharp`, :math:`T_{s-2} := (p - p^\sharp)/(z - 1)`,
   and the recursion continues (further essential singularities, caused by
   multiple unit-circle zeros, are treated the same way; ``s`` keeps the
   value of the first one).  The construction rests on Cohn's theorem: a
   symmetric (self-inversive) :math:`T_s` has as many zeros inside the unit
   circle as :math:`T_s'` has outside, and :math:`p` has the zeros of
   :math:`T_s'` reflected in the circle.  The minus sign matters: with it
   :math:`p(1) = -\tfrac{s}{2} T_s(1)`, so there is always one sign change
   between :math:`T_s(1)` and :math:`T_{s-1}(1)`.

3. **Counting.**  With :math:`\nu_n` the number of sign changes of
   :math:`T_n(1), T_{n-1}(1), \dots, T_0(1)` (zero values skipped; an
   isolated :math:`T_k(1) = 0` implies :math:`T_{k-1}(1) = -T_{k+1}(1)`, so
   skipping it is unambiguous) and :math:`\nu_s` the number of sign changes
   of :math:`T_s(1), \dots, T_0(1)`:

   .. math::

       N_{\text{inside}} = n - \nu_n, \qquad
       N_{\text{on}} = 2\nu_s - s, \qquad
       N_{\text{outside}} = \nu_n - N_{\text{on}}

   (:math:`N_{\text{on}} = 0` without essential singularity).  In particular
   :math:`D` is Schur stable iff all :math:`T_k(1)` are nonzero and of one
   sign.  The zeros removed in step 0 are added to these counts.

Floating-point input
--------------------
With ``float`` coefficients every zero test is relative: a computed quantity
``x`` counts as zero when ``|x| <= tol * S`` where ``S`` is the magnitude of
the operands ``x`` was computed from:

* :math:`D(1) = \sum d_i` is tested against :math:`S = \sum |d_i|`;
* :math:`T_{n-1}` against :math:`S = \max_i |d_i|`;
* :math:`T_{k-1}` and, in the next step, :math:`T_{k-1}(0)` and the count
  ``m`` against :math:`S = \max(\|\delta_k B_k\|_\infty, \|T_{k+1}\|_\infty)`,
  :math:`B_k` the multiplied polynomial of the step;
* the restart pair against :math:`S = \|p\|_\infty`.

The default ``tol = 1000 * eps`` (about ``2.2e-13``) is a compromise.  In
our randomised tests (about ``10^5`` polynomials of degree <= 8 with all
roots at least ``1e-6`` away from the circle) the only spurious unit-circle
zeros were of polynomials with several zeros clustered within a few percent
of ``z = 1``, for which ``|D(1)|`` falls below ``tol * sum|d_i|`` (such a
polynomial *is* within the tolerance of one with a zero at ``z = 1``).
Conversely, unit-circle zeros of polynomials whose coefficients were
*rounded* (e.g. produced by :func:`numpy.poly`) are missed in a few percent
of the cases, because rounding moves them off the circle and the recursion
amplifies that.  Pass a larger ``tol`` (say ``1e-9``) when the coefficients
are known only to that relative accuracy, or :class:`~fractions.Fraction`
coefficients (``Fraction(x)`` is exact for a float ``x``) for the exact
verdict on the polynomial as given.  Like the Schur-Cohn and Jury
recursions the test is not backward stable: for high degrees (beyond ~100)
the float verdict can differ from the exact one.  Zero coefficients at the
ends are only stripped when they are exactly zero.

References
----------
.. [1] Y. Bistritz, "Zero location with respect to the unit circle of
   discrete-time linear system polynomials", Proc. IEEE 72(9), 1131-1142,
   1984.
.. [2] Y. Bistritz, "Zero location of polynomials with respect to the
   unit-circle unhampered by nonessential singularities", IEEE Trans.
   Circuits Syst. I 49(3), 305-314, 2002.
.. [3] A. Cohn, "Über die Anzahl der Wurzeln einer algebraischen Gleichung
   in einem Kreise", Math. Z. 14, 110-148, 1922.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, Iterator, Sequence, cast

import numpy as np

from .polynomials import (Number, check_tol, div_z_minus_1, norm, parse, sign_changes,
                          symmetrise, total)

__all__ = ["ZeroLocation", "bistritz", "bistritz_sequence"]



@dataclass(frozen=True)
class ZeroLocation:
    """Numbers of zeros of a polynomial relative to the unit circle.

    Zeros are counted with multiplicity; ``inside + on + outside`` is the
    degree of the polynomial (after stripping leading zero coefficients).

    Attributes
    ----------
    inside
        Zeros with ``|z| < 1`` (zeros at ``z = 0`` included).
    on
        Zeros with ``|z| = 1``.
    outside
        Zeros with ``|z| > 1``.
    """

    inside: int
    on: int
    outside: int

    @property
    def degree(self) -> int:
        """Degree of the polynomial, ``inside + on + outside``."""
        return self.inside + self.on + self.outside

    @property
    def schur_stable(self) -> bool:
        """``True`` iff all zeros lie strictly inside the unit circle."""
        return self.on == 0 and self.outside == 0

    @property
    def stable(self) -> bool:
        """``True`` iff no zero lies outside the unit circle.

        Zeros on the unit circle are allowed (marginal stability; whether a
        *repeated* unit-circle zero is acceptable is up to the caller).
        """
        return self.outside == 0


# --------------------------------------------------------------------------
# the test
# --------------------------------------------------------------------------

@dataclass
class _Run:
    """Result of the reduction and of the recursion (internal)."""

    exact: bool
    at_zero: int                 # zeros at z = 0 removed
    at_one: int                  # zeros at z = 1 removed
    degree: int                  # n, degree of the reduced polynomial
    sequence: list[list[Number]]  # T_n, ..., T_0 (lowest power first)
    s: int | None                # degree of T_s at the first essential singularity
    s_index: int | None          # its position in ``sequence``


def _run(coefficients: Any, tol: float | None, *, normalise: bool) -> _Run:
    d, exact = parse(coefficients)
    eps_rel: Number = Fraction(0) if exact else check_tol(tol)
    if exact and tol is not None:
        check_tol(tol)  # validated, then ignored: exact zero tests
    zero: Number = Fraction(0) if exact else 0.0

    def shift(p: list[Number], always: bool = False) -> int:
        # Exact power-of-two rescaling against overflow/underflow in float
        # arithmetic: it changes no rounding, no sign and no relative test.
        if exact or not (normalise or always):
            return 0
        big = norm(p)
        return 0 if big == 0 else -math.frexp(big)[1]

    def rescaled(p: list[Number], e: int) -> list[Number]:
        return p if e == 0 else [math.ldexp(x, e) for x in p]

    # -- step 0: reduction ---------------------------------------------------
    while d and d[-1] == 0:
        d.pop()
    if not d:
        raise ValueError("bistritz: the zero polynomial has no well-defined zeros")
    at_zero = 0
    while d[0] == 0:               # d[-1] != 0, so this stops
        d.pop(0)
        at_zero += 1
    e0 = shift(d, always=True)     # the sums below must not overflow
    d = rescaled(d, e0)
    at_one = 0
    # abs keeps each coefficient's type, float or Fraction (mypy would join the two to object)
    while len(d) > 1 and cast(Number, abs(total(d, exact))) <= eps_rel * sum(
            cast("Iterator[Number]", (abs(x) for x in d))):
        d = div_z_minus_1(d, zero)
        at_one += 1
    n = len(d) - 1
    if not normalise:
        d = rescaled(d, -e0)       # bistritz_sequence: the unscaled polynomial

    # -- step 1: initial pair ------------------------------------------------
    d_rev = d[::-1]
    t_n = symmetrise([a + b for a, b in zip(d, d_rev)], exact)
    sequence: list[list[Number]] = [rescaled(t_n, shift(t_n))]
    s: int | None = None
    s_index: int | None = None
    if n == 0:
        return _Run(exact, at_zero, at_one, 0, sequence, None, None)
    candidate = div_z_minus_1([a - b for a, b in zip(d, d_rev)], zero)
    scale = norm(d)

    # -- step 2: recursion -----------------------------------------------
    while True:
        candidate = symmetrise(candidate, exact)
        threshold = eps_rel * scale
        if norm(candidate) <= threshold:
            # essential singularity: restart from T_top = sequence[-1]
            top = sequence[-1]
            deg_top = len(top) - 1
            if s is None:
                s, s_index = deg_top, len(sequence) - 1
            # p = z T' - deg_top T, nominal degree deg_top - 1
            p = [(i - deg_top) * top[i] for i in range(deg_top)]
            p_rev = p[::-1]
            t_new = symmetrise([a + b for a, b in zip(p, p_rev)], exact)
            sequence.append(rescaled(t_new, shift(t_new)))
            if deg_top == 1:
                break                              # that was T_0
            candidate = div_z_minus_1([a - b for a, b in zip(p, p_rev)], zero)
            scale = norm(p)
            continue

        e = shift(candidate)
        t_k = rescaled(candidate, e)
        if e:
            threshold = math.ldexp(threshold, e)
        sequence.append(t_k)
        k = len(t_k) - 1
        if k == 0:
            break
        t_k1 = sequence[-2]
        # m = number of vanishing low-order (= high-order) coefficients of T_k;
        # m > 0 is a nonessential singularity.  T_k is not ~0, so m <= k/2.
        m = 0
        while cast(Number, abs(t_k[m])) <= threshold:  # abs keeps the type (see above)
            m += 1
        delta = t_k1[0] / t_k[m]
        # B = (z^-m + z^(m+1)) T_k, nominal degree k + 1
        b = [zero] * (k + 2)
        for i in range(m, k - m + 1):
            b[i - m] += t_k[i]
            b[i + m + 1] += t_k[i]
        num = [delta * x for x in b]
        # the z^0 and z^(k+1) terms of the numerator cancel; divide by z
        candidate = [num[j + 1] - t_k1[j + 1] for j in range(k)]
        scale = max(norm(num), norm(t_k1))

    return _Run(exact, at_zero, at_one, n, sequence, s, s_index)


def bistritz(coefficients: Sequence[Any] | np.ndarray, *, tol: float | None = None) -> ZeroLocation:
    r"""Count the zeros of a real polynomial inside, on and outside the unit circle.

    Bistritz's three-term symmetric-polynomial recursion [1]_ with the
    treatment of nonessential and essential singularities of [2]_; see the
    module docstring for the mathematics.  Works for any degree and for every
    configuration of zeros, including zeros on the unit circle (of any
    multiplicity), reciprocal pairs :math:`r, 1/r` and zeros at ``z = 0``.

    Parameters
    ----------
    coefficients
        Coefficients, **highest power first** (the :func:`numpy.roots`
        convention): ``[d_n, ..., d_1, d_0]``.  Leading zeros are stripped.
        If every coefficient is rational (``int``, :class:`fractions.Fraction`,
        NumPy integers) the computation is exact; otherwise it is done in
        ``float``.
    tol
        Relative tolerance of the floating-point zero tests (see the module
        docstring); default ``1000 * eps``.  Ignored in exact arithmetic.

    Returns
    -------
    ZeroLocation
        ``inside``, ``on``, ``outside`` counts (with multiplicity).  A nonzero
        constant has no zeros: ``ZeroLocation(0, 0, 0)``.

    Raises
    ------
    ValueError
        Empty input, a zero polynomial, non-real or non-finite coefficients,
        input that is not 1-D, or an invalid ``tol``.

    Examples
    --------
    >>> bistritz([1, -1, 0.5])           # z^2 - z + 1/2: zeros 0.5 +- 0.5j
    ZeroLocation(inside=2, on=0, outside=0)
    >>> bistritz([1, 2.5, 1])            # zeros -1/2 and -2
    ZeroLocation(inside=1, on=0, outside=1)
    >>> from fractions import Fraction
    >>> bistritz([1, -Fraction(5, 2), 1, 0])   # z (z - 2)(z - 1/2)
    ZeroLocation(inside=2, on=0, outside=1)
    >>> bistritz([1, 0, 1]).stable, bistritz([1, 0, 1]).schur_stable
    (True, False)
    """
    run = _run(coefficients, tol, normalise=True)
    values = [total(t, run.exact) for t in run.sequence]
    nu_n = sign_changes(values)
    inside = run.degree - nu_n
    if run.s is None:
        on = 0
    else:
        nu_s = sign_changes(values[run.s_index:])
        # exact arithmetic guarantees s/2 <= nu_s <= s; clamp float noise
        on = min(max(2 * nu_s - run.s, 0), nu_n)
    outside = run.degree - inside - on
    return ZeroLocation(
        inside=inside + run.at_zero,
        on=on + run.at_one,
        outside=outside,
    )


def bistritz_sequence(coefficients: Sequence[Any] | np.ndarray, *, tol: float | None = None) -> list[np.ndarray]:
    r"""The Bistritz polynomials :math:`T_n, T_{n-1}, \dots, T_0`.

    Parameters
    ----------
    coefficients, tol
        As for :func:`bistritz`.

    Returns
    -------
    list of numpy.ndarray
        ``n + 1`` arrays, ``T_n`` first, where ``n`` is the degree of the
        *reduced* polynomial :math:`D(z) / (z^{m_0} (z-1)^{m_1})` (zeros at
        ``z = 0`` and ``z = 1`` divided out, see the module docstring).  Entry
        ``n - k`` holds :math:`T_k`, **highest power first**, with exactly
        ``k + 1`` coefficients (its nominal degree; the leading coefficient
        is zero at a nonessential singularity).  Every :math:`T_k` is
        symmetric (palindromic).  After an essential singularity the vanished
        polynomials are replaced by the restart pair built from
        :math:`p = z T_s' - s T_s`.  The arrays have dtype ``float`` or, for
        exact input, ``object`` holding :class:`fractions.Fraction`.  The
        polynomials are those of the recursion, not normalised: extreme
        coefficients or very high degrees may overflow here, while
        :func:`bistritz` rescales every ``T_k`` by an exact power of two.

    Examples
    --------
    >>> [t.tolist() for t in bistritz_sequence([1.0, -0.5])]   # z - 1/2
    [[0.5, 0.5], [1.5]]
    """
    run = _run(coefficients, tol, normalise=False)
    dtype = object if run.exact else float
    return [np.array(t[::-1], dtype=dtype) for t in run.sequence]
