"""The records' modes placed by the model's: step 1 of the records' start (:mod:`identification.data_start`).

For a uniform beam the modes depend on the parameters only through the frequency scale
``k = √((EI/ρA)/(EI₀/ρA₀))`` and ``U = N L²/EI``: the model's frequencies at the nominal point (one eigen-analysis
per value of N tried, :func:`family`) times ``k`` are its frequencies anywhere.  Every pairing of a record's mode
with a model mode proposes a ``k``; each is scored by how many of the records' modes it places within
:data:`MATCH_TOLERANCE` of a model mode, weighted by their support in the stability chart (:func:`alignment_miss`),
and the best few distinct ones are kept (:func:`alignments`).

Where the model has parts a common scale of EI, ρA, c and N leaves alone — a declared point mass, a spring, a
fixed axial force — the level moves the modes too (:func:`scale_moves_modes`), and their pattern gives it: the
matched modes are fitted in the frequency scale, the level and N (:func:`pattern_level`).  Measured on a strip
with an accelerometer of 6 % of its mass at the tip, a newcomer's ρA 40 % high: from the amplitude alone the
start was 2.4 times the truth (a level note claimed the records' units wrong) and the run ended at 4,660 noise
variances; from the pattern, 0.6 % low, and the run at the noise floor.  Where an unmodelled part zigzags the
modes by more than the level moves them, the pattern leaves the level undetermined and the records' spectrum gives
it (:func:`spectrum_level`: the median ratio of the FRF magnitudes, which a misplaced mode barely moves).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ebb_model.errors import EbbError

from .record_poles import frequency_response_estimate

__all__ = ["CANDIDATES", "LEVEL_MOVES", "MATCH_TOLERANCE", "N_GRID", "PATTERN_GAIN", "PATTERN_SIGMA", "Directions",
           "SPECTRUM_TOLERANCE", "alignment_miss", "alignments", "family", "pattern_level", "scale_moves_modes",
           "spectrum_level", "undamped_hz"]

#: A peak within this relative distance of a model mode is explained by it.
MATCH_TOLERANCE = 0.04
#: Candidate frequency scales refined in time.
CANDIDATES = 4
#: Values of N at which the model's modes are computed when N is unknown (33: a step of 1/32 of the bounds' span;
#: with 9 a clamped beam in tension bounded at ±4 times a guess 40 % high fell between the values U = 0 and 11.8,
#: and no alignment placed its nine modes — the start went to N −13 for +50).
N_GRID = 33
#: The share of the misfit of the records' modes at the nominal level that a level must leave to be taken from
#: them.
PATTERN_GAIN = 0.5
#: The largest standard error of the log level, from the fit's Jacobian and residual, with which the level is taken
#: from the modes' pattern (measured: 0.011–0.030 where the pattern placed six to nine modes of a declared tip mass
#: or spring support; 0.5–1.2 for a frequency scale that placed three modes wrongly).
PATTERN_SIGMA = 0.1
#: A relative shift of a mode by a common scale of the parameters that counts as moving it (well inside the last
#: stage's window).
LEVEL_MOVES = 2e-4
#: The records' spectrum fixes the level once the median log ratio of the records' to the model's FRF magnitude is
#: within this of 0 (a few tenths of a percent: the refinement in time and the search take it from there).
SPECTRUM_TOLERANCE = 0.003
#: Secant steps of the spectrum's level.
SPECTRUM_STEPS = 8


@dataclass(frozen=True, eq=False)
class Directions:
    """How a trial ``(k, ζ, N)`` at unit level becomes a candidate of the unknowns."""

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    nominal: np.ndarray
    fixed: dict[str, float]
    omega_ref: float

    def has(self, name: str) -> bool:
        return name in self.names

    def value(self, name: str) -> float:
        return float(self.nominal[self.names.index(name)]) if self.has(name) else self.fixed.get(name, 0.0)

    @property
    def level_free(self) -> bool:
        """A common scale of EI and ρA is among the unknowns (it leaves every frequency in place on a uniform beam
        without attached parts; :func:`scale_moves_modes` says where it does not)."""
        return self.has("EI") and self.has("rhoA")

    def candidate(self, k: float, zeta: float, n_value: float | None, level: float = 1.0,
                  clip: bool = True) -> np.ndarray:
        """The unknowns of frequency scale ``k``, damping ratio ``zeta`` at the reference mode, axial force
        ``n_value`` (at the nominal EI; scaled with EI) and ``level`` (ρA, EI, c, N times ``level``), inside the
        bounds unless ``clip`` is false."""
        x = self.nominal.copy()
        EI0, rhoA0 = self.value("EI"), self.value("rhoA")
        s = level if self.level_free else 1.0
        if self.has("EI"):
            EI, rhoA = EI0 * k * k * s, rhoA0 * s
        else:
            EI, rhoA = EI0, rhoA0 / (k * k)
        vals = {"EI": EI, "rhoA": rhoA}
        if n_value is not None:
            vals["N"] = n_value * EI / EI0
        omega = self.omega_ref * k
        if self.has("c"):
            vals["c"] = 2.0 * zeta * rhoA * omega
        elif self.has("eta"):
            vals["eta"] = 2.0 * zeta / omega
        for name, v in vals.items():
            if self.has(name):
                x[self.names.index(name)] = v
        return np.clip(x, self.lower, self.upper) if clip else x

    def rebased(self, level: float) -> "Directions":
        """The same directions about the nominal point with EI, ρA, c and N times ``level`` (a candidate's ``k``
        keeps its meaning: the ratio EI/ρA is the nominal's; its ``n_value`` is ``level`` times)."""
        nominal = self.nominal.copy()
        for name in ("EI", "rhoA", "c", "N"):
            if self.has(name):
                nominal[self.names.index(name)] *= level
        return replace(self, nominal=nominal)

    def k_range(self) -> tuple[float, float]:
        """The frequency scales the bounds allow."""
        if self.has("EI") and self.has("rhoA"):
            i, j = self.names.index("EI"), self.names.index("rhoA")
            r0 = self.value("EI") / self.value("rhoA")
            return (math.sqrt(self.lower[i] / self.upper[j] / r0), math.sqrt(self.upper[i] / self.lower[j] / r0))
        if self.has("EI"):
            i = self.names.index("EI")
            return math.sqrt(self.lower[i] / self.value("EI")), math.sqrt(self.upper[i] / self.value("EI"))
        if self.has("rhoA"):
            j = self.names.index("rhoA")
            return math.sqrt(self.value("rhoA") / self.upper[j]), math.sqrt(self.value("rhoA") / self.lower[j])
        return 1.0, 1.0


def undamped_hz(evaluator: Any, x: np.ndarray) -> np.ndarray:
    """The undamped natural frequencies [Hz] of candidate ``x`` (at most 40 modes).

    Raises
    ------
    EbbError, ValueError, numpy.linalg.LinAlgError
        The candidate's model cannot be built or solved.
    """
    from ebb_model.modal.modal import discrete_frequencies

    cfg = evaluator.config
    c, p = evaluator.space.apply(cfg, np.asarray(x, dtype=float))
    return np.asarray(discrete_frequencies(c, {**dict(p), "c": 0.0, "eta": 0.0}, min(40, cfg.beam.nodes))[0], float)


def family(evaluator: Any, d: Directions) -> list[tuple[float | None, np.ndarray]]:
    """The model's undamped frequencies [Hz] at the nominal EI and ρA, per value of N tried (``None``: N is not
    unknown), the values of N that buckle the beam left out: their "frequencies" are those of an unstable model
    (measured: a pinned–pinned beam bounded at 5.8 Euler loads in compression — its first eight values of N
    buckled it, every pairing with them placed the one mode its records showed, and the start went to the
    bound's end, EI 0.96 and N −32 for 3.79 and −11.8).  A candidate scales N with EI, so a value that buckles
    the beam at the nominal EI buckles it at every frequency scale."""
    from ebb_model.assemble import buckling_load

    cfg = evaluator.config
    if d.has("N"):
        i = d.names.index("N")
        values: list[float | None] = [float(v) for v in np.linspace(d.lower[i], d.upper[i], N_GRID)]
        if d.lower[i] < 0:
            try:
                c, p = evaluator.space.apply(cfg, d.candidate(1.0, 0.0, 0.0))
                n_cr = buckling_load(c, p)
            except (EbbError, ValueError, np.linalg.LinAlgError):
                n_cr = None
            if n_cr is not None:
                values = [v for v in values if v is not None and v > n_cr]
    else:
        values = [None]
    out = []
    for nv in values:
        try:
            out.append((nv, undamped_hz(evaluator, d.candidate(1.0, 0.0, nv))))
        except (EbbError, ValueError, np.linalg.LinAlgError):
            continue
    return out


def scale_moves_modes(evaluator: Any, x: np.ndarray, scale: float = 2.0) -> bool:
    """Whether a common scale ``scale`` of EI, ρA, c and N (those among the unknowns) moves the modes of candidate
    ``x`` by more than :data:`LEVEL_MOVES` — it does where the model has parts the scale leaves alone (a declared
    point mass, a spring, a fixed axial force); unknown when the model cannot be evaluated (``False``).
    ``evaluator`` is anything with the ``config`` and the ``space`` of the unknowns (an identification's
    evaluator, a diagnosis' problem)."""
    x = np.asarray(x, dtype=float)
    scaled = x * np.array([scale if n in ("EI", "rhoA", "c", "N") else 1.0 for n in evaluator.space.names])
    try:
        f = [undamped_hz(evaluator, v) for v in (x, scaled)]
    except (EbbError, ValueError, np.linalg.LinAlgError):
        return False
    ok = (f[0] > 0) & (f[1] > 0)
    return bool(np.any(np.abs(np.log(f[1][ok] / f[0][ok])) > LEVEL_MOVES))


def pattern_level(evaluator: Any, d: Directions, k: float, n_value: float | None, recorded: Any,
                   k_range: tuple[float, float]) -> tuple[float, float, float | None] | None:
    """The frequency scale, level and axial force whose modes best place the records' modes where the level moves
    them (module docstring, step 1); ``None`` where it does not, where too few modes are matched, or where the
    level does not place them clearly better than the nominal one (:data:`PATTERN_GAIN`) or is not determined by
    them (:data:`PATTERN_SIGMA`).

    The records' modes matched to the model's at ``(k, n_value)`` (nearest, within :data:`MATCH_TOLERANCE`) are
    fitted in log frequency, each weighted by its support over its damping ratio (a mode's frequency is known to a
    share of its half-power bandwidth)."""
    from scipy.optimize import least_squares

    peaks = recorded.frequencies_hz
    if peaks.size < 3 or not scale_moves_modes(evaluator, d.candidate(k, 0.0, n_value, clip=False)):
        return None
    has_n = d.has("N") and n_value is not None
    i_n = d.names.index("N") if has_n else -1
    n_span = float(d.upper[i_n] - d.lower[i_n]) if has_n else 1.0

    def freqs(theta: np.ndarray) -> np.ndarray:
        nv = n_value + theta[2] * n_span if has_n and n_value is not None else n_value
        return undamped_hz(evaluator, d.candidate(math.exp(theta[0]), 0.0, nv, math.exp(theta[1]), clip=False))

    theta0 = np.zeros(3 if has_n else 2)
    theta0[0] = math.log(k)
    try:
        f0 = freqs(theta0)
    except (EbbError, ValueError, np.linalg.LinAlgError):
        return None
    dist = np.abs(np.log(peaks[:, None] / np.where(f0 > 0, f0, np.nan)[None, :]))
    j = np.nanargmin(dist, axis=1)
    near = np.nanmin(dist, axis=1) < MATCH_TOLERANCE
    pairs: dict[int, int] = {}             # one record mode per model mode: the best supported
    for i in map(int, np.flatnonzero(near)):
        m = int(j[i])
        if m not in pairs or recorded.support[i] > recorded.support[pairs[m]]:
            pairs[m] = i
    if len(pairs) < theta0.size + 1:
        return None
    model_j = np.array(sorted(pairs))
    rec_i = np.array([pairs[m] for m in model_j])
    w = np.sqrt(recorded.support[rec_i]) / np.maximum(recorded.damping[rec_i], 1e-3)
    target = np.log(peaks[rec_i])

    def residual(theta: np.ndarray) -> np.ndarray:
        try:
            f = freqs(theta)[model_j]
        except (EbbError, ValueError, np.linalg.LinAlgError):
            return np.full(model_j.size, 1e3)
        return w * (np.log(np.maximum(f, 1e-300)) - target)

    jr = d.names.index("rhoA")          # the level is ρA's scale; the frequency scale's range keeps EI/ρA inside
    lower = [math.log(k_range[0]), math.log(d.lower[jr] / d.value("rhoA"))] + ([-1.0] if has_n else [])
    upper = [math.log(k_range[1]), math.log(d.upper[jr] / d.value("rhoA"))] + ([1.0] if has_n else [])
    fixed_level = least_squares(lambda t: residual(np.insert(t, 1, 0.0)), np.delete(theta0, 1),
                                bounds=(np.delete(lower, 1), np.delete(upper, 1)), x_scale=0.01)
    free = least_squares(residual, np.insert(fixed_level.x, 1, 0.0), bounds=(lower, upper), x_scale=0.01)
    dof = model_j.size - free.x.size
    try:
        cov = np.linalg.inv(free.jac.T @ free.jac) * (2.0 * free.cost / dof if dof > 0 else np.inf)
        sigma = math.sqrt(cov[1, 1]) if cov[1, 1] >= 0 else math.inf
    except np.linalg.LinAlgError:
        sigma = math.inf
    if not (free.cost < PATTERN_GAIN * fixed_level.cost and sigma < PATTERN_SIGMA):
        return None
    nv = n_value + free.x[2] * n_span if has_n and n_value is not None else n_value
    return math.exp(free.x[0]), math.exp(free.x[1]), nv


def spectrum_level(evaluator: Any, d: Directions, k: float, n_value: float | None, zeta: float,
                   record_frf: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[float | None, int]:
    """The level at which the model's FRF magnitude meets the records' — the median over the excited band of the
    log ratio — where the modes' pattern cannot say it (:func:`pattern_level`: an unmodelled mass zigzags the modes
    by more than the level moves them), ``None`` where the model cannot be evaluated or the magnitudes meet
    outside the bounds of ρA (the amplitude's level then says it, with its note on the records' units); and the
    model evaluations used.

    A projection of the outputs in time (the refinement's) needs the modes aligned to a share of a half-power
    bandwidth: with an unmodelled 10 g mass on a strip carrying a declared 45 g accelerometer, the modes miss by up
    to 1 % and the projected level collapsed to half the truth (ρA 2.45 times it at the start, the run at 3,960
    noise variances).  The median of the magnitudes' ratio is set by the band between the resonances, which a
    misplaced mode barely moves and the damping does not (measured on that record: 0.964 at the truth's damping,
    0.964–0.970 at 0.3–10 times it); with the declared part the outputs scale by less than ``1/level``, hence the
    secant on the log level.

    Parameters
    ----------
    evaluator
        The evaluator whose experiments the records' FRF ``record_frf`` was estimated on
        (:func:`identification.record_poles.frequency_response_estimate`).
    d, k, n_value, zeta
        The candidate (:meth:`Directions.candidate`) whose level is sought.
    """
    f, H, excited = record_frf
    inputs = [e.inputs for e in evaluator.experiments]
    dt = float(evaluator.config.time.dt)
    jr = d.names.index("rhoA")
    lo, hi = math.log(d.lower[jr] / d.value("rhoA")), math.log(d.upper[jr] / d.value("rhoA"))
    used = 0

    def gap(log_s: float) -> float:
        nonlocal used
        used += 1
        sim = evaluator.simulate(d.candidate(k, zeta, n_value, math.exp(log_s), clip=False))
        _, G, _ = frequency_response_estimate(inputs, list(sim.outputs), dt)
        h, g = np.abs(H[excited]), np.abs(G[excited])
        ok = (h > 0) & (g > 0) & np.isfinite(g)
        return float(np.median(np.log(h[ok] / g[ok]))) if np.any(ok) else math.nan

    try:
        s0, g0 = 0.0, gap(0.0)
        if not math.isfinite(g0):
            return None, used
        s1 = min(max(-g0, lo), hi)        # a uniform beam's outputs scale by 1/level exactly
        for _ in range(SPECTRUM_STEPS):
            g1 = gap(s1)
            if not math.isfinite(g1):
                return None, used
            if abs(g1) < SPECTRUM_TOLERANCE or s1 == s0:
                break
            slope = (g1 - g0) / (s1 - s0)
            step = -g1 / slope if slope > 0 else -g1   # the ratio rises with the level; else the uniform beam's step
            s0, g0, s1 = s1, g1, min(max(s1 + step, lo), hi)
    except (EbbError, ValueError, np.linalg.LinAlgError):
        return None, used
    if abs(g1) >= SPECTRUM_TOLERANCE and s1 in (lo, hi):
        return None, used        # on a bound and still off: the amplitude's level and its note say the rest
    return math.exp(s1), used


def alignment_miss(peaks: np.ndarray, weights: np.ndarray, model_hz: np.ndarray) -> float:
    """How badly a model's modes ``model_hz`` [Hz] place the records' modes ``peaks`` [Hz] of stability-chart
    support ``weights``: each record mode's squared distance to the nearest model mode in units of
    :data:`MATCH_TOLERANCE` (at most 1: a mode missed), weighted by its support, plus half a mean weight for each
    model mode inside the records' span with no record mode near it (a node of a sensor or actuator may hide one).
    0: every record mode on a model mode and no model mode unseen."""
    fk = np.asarray(model_hz, dtype=float)
    fk = fk[fk > 0]
    if fk.size == 0 or peaks.size == 0:
        return float(np.sum(weights))
    d = np.min(np.abs(np.log(peaks[:, None] / fk[None, :])), axis=1) / MATCH_TOLERANCE
    miss = float(np.sum(weights * np.minimum(d * d, 1.0)))
    span = fk[(fk > peaks.min() * (1 - MATCH_TOLERANCE)) & (fk < peaks.max() * (1 + MATCH_TOLERANCE))]
    unseen = np.min(np.abs(np.log(span[:, None] / peaks[None, :])), axis=1) > MATCH_TOLERANCE \
        if span.size else np.zeros(0, bool)
    return miss + 0.5 * float(np.mean(weights)) * int(np.count_nonzero(unseen))


def alignments(peaks: np.ndarray, weights: np.ndarray, family: list[tuple[float | None, np.ndarray]],
                k_lo: float, k_hi: float, nyquist: float) -> list[tuple[float, float | None]]:
    """The best distinct ``(k, N)`` pairs by the peaks they explain (module docstring, step 1)."""
    scored: list[tuple[float, float, float | None]] = []
    for nv, f in family:
        f = f[f > 0]
        ks = {1.0} if k_lo == k_hi else set()
        for fp in peaks:
            for fm in f:
                k = fp / fm
                if k_lo <= k <= k_hi:
                    ks.add(float(k))
        for k in ks:
            fk = k * f[k * f < nyquist]
            if fk.size:
                scored.append((alignment_miss(peaks, weights, fk), k, nv))
    scored.sort(key=lambda t: t[0])
    picks: list[tuple[float, float | None]] = []
    for _, k, nv in scored:
        if all(abs(math.log(k / q)) > 0.02 or nv != m for q, m in picks):
            picks.append((k, nv))
        if len(picks) >= CANDIDATES:
            break
    return picks
