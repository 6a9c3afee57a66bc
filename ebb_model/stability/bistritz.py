"""Prototype (to be replaced by the documented version)."""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from fractions import Fraction

import numpy as np


@dataclass(frozen=True)
class ZeroLocation:
    inside: int
    on: int
    outside: int

    @property
    def schur_stable(self) -> bool:
        return self.on == 0 and self.outside == 0

    @property
    def stable(self) -> bool:
        return self.outside == 0


def _parse(coefficients):
    arr = list(np.asarray(coefficients, dtype=object).ravel()) if not isinstance(coefficients, (list, tuple)) else list(coefficients)
    exact = all(isinstance(c, numbers.Rational) for c in arr)
    if exact:
        vals = [Fraction(c) for c in arr]
    else:
        vals = [float(c) for c in arr]
    return vals[::-1], exact


def _run(coefficients, tol=None, *, trace=None):
    d, exact = _parse(coefficients)
    if tol is None:
        tol = 0 if exact else 1e3 * np.finfo(float).eps
    if exact:
        tol = 0
    zero = Fraction(0) if exact else 0.0
    # strip leading zeros (highest powers)
    while d and d[-1] == 0:
        d.pop()
    inside = 0
    on = 0
    while d and d[0] == 0:
        d.pop(0)
        inside += 1
    # divide out z - 1
    while len(d) > 1:
        s = sum(d)
        scale = sum(abs(x) for x in d)
        if abs(s) > tol * scale:
            break
        q = [zero] * (len(d) - 1)
        acc = zero
        for j in range(len(d) - 1):
            acc = acc - d[j]
            q[j] = acc
        d = q
        on += 1
    n = len(d) - 1
    if n <= 0:
        return ZeroLocation(inside, on, 0), [], None
    dstar = d[::-1]
    Tn = [a + b for a, b in zip(d, dstar)]
    diff = [a - b for a, b in zip(d, dstar)]
    cand = _div_zm1(diff, zero)
    cand_scale = max(abs(x) for x in d)
    seq = [Tn]
    s = None
    s_pos = None
    while True:
        if max(abs(x) for x in cand) <= tol * cand_scale:
            top = seq[-1]
            sd = len(top) - 1
            if s is None:
                s, s_pos = sd, len(seq) - 1
            p = [(i - sd) * top[i] for i in range(sd)]  # z T' - sd T, degree sd-1
            pst = p[::-1]
            seq.append(_sym([a + b for a, b in zip(p, pst)], exact))
            if sd - 1 == 0:
                break
            cand = _div_zm1([a - b for a, b in zip(p, pst)], zero)
            cand_scale = max(abs(x) for x in p)
            continue
        cand = _sym(cand, exact)
        seq.append(cand)
        k = len(cand) - 1
        if k == 0:
            break
        Tk1, Tk = seq[-2], seq[-1]
        thr = tol * cand_scale
        if abs(Tk[0]) > thr:
            m = 0
        else:
            m = next(i for i in range(len(Tk)) if abs(Tk[i]) > thr)
            if trace is not None:
                trace.append(("nonessential", k, m))
        delta = Tk1[0] / Tk[m]
        B = [zero] * (k + 2)
        for i in range(m, k - m + 1):
            B[i - m] += Tk[i]
            B[i + m + 1] += Tk[i]
        num = [delta * b for b in B]
        new = [num[j + 1] - Tk1[j + 1] for j in range(k)]
        cand_scale = max(max(abs(x) for x in num), max(abs(x) for x in Tk1))
        cand = new
    vals = [sum(T) for T in seq]
    nu_n = _changes(vals)
    if s is not None:
        nu_s = _changes(vals[s_pos:])
        c = 2 * nu_s - s
    else:
        c = 0
    ins = n - nu_n
    return ZeroLocation(inside + ins, on + c, n - ins - c), seq, s


def _sym(P, exact):
    if exact:
        return P
    R = P[::-1]
    return [(a + b) / 2 for a, b in zip(P, R)]


def _div_zm1(P, zero):
    q = [zero] * (len(P) - 1)
    acc = zero
    for j in range(len(P) - 1):
        acc = acc - P[j]
        q[j] = acc
    return q


def _changes(vals):
    prev = 0
    c = 0
    for v in vals:
        if v == 0:
            continue
        sg = 1 if v > 0 else -1
        if prev and sg != prev:
            c += 1
        prev = sg
    return c


def bistritz(coefficients, *, tol=None):
    return _run(coefficients, tol)[0]
