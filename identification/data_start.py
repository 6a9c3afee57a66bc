"""A start read from the records: the basin of the global answer, whatever the config's nominal values.

Output-error fits of lightly damped records have a narrow valley along the stiffness-to-mass ratio (every
resonance moves with it, a fraction of a half-power bandwidth decides) and a long, flat one along the level (a
common scale of EI, ρA, c and N leaves every frequency where it is and scales the outputs): a GA started from
a config's nominal values and a local polish find the first but crawl along the second, and stop far from the
answer.  The records themselves fix both, before any search:

1. **Frequencies.**  The records' modes (:mod:`identification.record_poles`: averaged FRFs, a stabilised pole
   estimator and its stability chart — not the peaks of a noisy spectrum) are matched to the model's modes.
   For a uniform beam the modes depend on the parameters only through the frequency scale
   ``k = √((EI/ρA)/(EI₀/ρA₀))`` and ``U = N L²/EI``: the model's frequencies at the nominal point (one
   eigen-analysis per value of N tried) times ``k`` are its frequencies anywhere.  Every pairing of a record's
   mode with a model mode proposes a ``k``; each is scored by how many of the records' modes it places within
   :data:`MATCH_TOLERANCE` of a model mode (weighted by their support in the stability chart), and the best few
   distinct ones are kept.
2. **Refinement in time.**  Around each, the output error is scanned along the frequency scale (and N, when it
   is unknown) with the damping lowered stage by stage (:data:`STAGES`: each stage's window is the previous
   one's resolution; a heavily damped model's cost is smooth where a lightly damped one's is a comb), and the
   level projected out in closed form: with EI, ρA, c and N scaled by ``s`` together the outputs scale by
   ``1/s`` exactly, so the best level of every trial is one inner product.
3. **Level.**  The best trial's level gives ρA (and EI, c, N with it).  A level outside the bounds is kept as a
   note that the run prints only where its final fit bears it out (:class:`DataStart`); the start's sign is no
   claim (an undeclared delay turns it as readily as a reversed force).

The GA's first population carries the start (:func:`identification.optimise.optimise`), and the polish runs from
it as well as from the GA's knee (:func:`identification.run.identify`).  The model evaluations run through the
identification's runner (worker processes or Dask), counted in ``DataStart.n_evaluations``
(``data_start`` in ``pareto.json``), apart from the search's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ebb_model.acquisition.channel_delay import effective_delays
from ebb_model.errors import EbbError

from .polish import residual_scale
from .record_poles import record_modes
from .runners import Runner, SerialRunner

__all__ = ["DataStart", "MATCH_TOLERANCE", "STAGES", "alignment_miss", "data_start"]

#: A peak within this relative distance of a model mode is explained by it.
MATCH_TOLERANCE = 0.04
#: (relative half-window of the frequency scale, damping ratio at the lowest matched mode) per stage.
STAGES = ((0.06, 0.05), (0.015, 0.015), (0.004, 0.004), (0.001, 0.001))
#: Factors of the last stage's damping ratio tried at the end (the level's accuracy is the damping's).
DAMPING_FACTORS = 2.0 ** np.linspace(-1.5, 1.5, 13)
#: Trials per stage along the frequency scale.
TRIALS = 13
#: Candidate frequency scales refined in time.
CANDIDATES = 4
#: Samples per experiment the time-domain refinement uses (the record's start: it begins at rest).
MAX_SAMPLES = 1 << 15
#: Values of N at which the model's modes are computed when N is unknown (33: a step of 1/32 of the bounds' span;
#: with 9 a clamped beam in tension bounded at ±4 times a guess 40 % high fell between the values U = 0 and 11.8,
#: and no alignment placed its nine modes — the start went to N −13 for +50).
N_GRID = 33


@dataclass(frozen=True)
class DataStart:
    """What the records say, as a start for the search.

    Attributes
    ----------
    x
        The start (physical units, order of the unknowns), inside the bounds.
    modes_hz
        The records' modes [Hz] (:func:`identification.record_poles.record_modes`).
    level
        The records' level against the model at the frequency scale found (1: the model's own level; the
        outputs are ``level ×`` the model's at unit scale), NaN when the level is not free (EI or ρA known).
    level_note
        The records' level outside the bounds, in one sentence (``None`` when inside): a claim made at the start,
        which the run prints only where its final fit bears it out (:func:`identification.fit_hints.fit_hints`)
        and writes nowhere else.  Measured on the hint family (``tests/hint_family.py``: 64 broadband records,
        correct, with a withheld effect, an undeclared delay or filter): the start made it of 5 records whose
        units were right, the final fit bore it out on none.  The start makes no claim of a sign: a negative
        level here follows an undeclared delay as readily as a reversed force (measured: 3 records of the same
        family, each delayed), and the final fit's gains say a reversed sign where it holds.
    n_evaluations
        Model evaluations used.
    """

    x: np.ndarray
    modes_hz: np.ndarray
    level: float
    level_note: str | None = None
    n_evaluations: int = 0

    def to_dict(self, names: Sequence[str]) -> dict[str, Any]:
        """JSON-ready values."""
        return {"parameters": {n: float(v) for n, v in zip(names, self.x)},
                "modes_hz": [float(v) for v in self.modes_hz],
                "level": None if math.isnan(self.level) else float(self.level),
                "n_evaluations": int(self.n_evaluations)}


@dataclass(frozen=True, eq=False)
class _Directions:
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
        """A common scale of EI and ρA is among the unknowns (it leaves every frequency in place)."""
        return self.has("EI") and self.has("rhoA")

    def candidate(self, k: float, zeta: float, n_value: float | None, level: float = 1.0) -> np.ndarray:
        """The unknowns of frequency scale ``k``, damping ratio ``zeta`` at the reference mode, axial force
        ``n_value`` (at the nominal EI; scaled with EI) and ``level`` (ρA, EI, c, N times ``level``)."""
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
        return np.clip(x, self.lower, self.upper)

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


@dataclass(frozen=True, eq=False)
class ProjectedCost:
    """Output error of candidates with the level projected out (picklable; runs through any runner).

    ``evaluate(X)`` gives per candidate ``(cost, level)``: the sum over sensors of the squared error normalised
    by each sensor's spread, at the best common level ``a`` of the simulated outputs (``a = 1`` when the level
    is not free), and ``a``.  Refused candidates cost ``inf``.
    """

    evaluator: Any
    project: bool

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        out = np.empty((len(X), 2))
        exps = self.evaluator.experiments
        w = 1.0 / residual_scale(exps) ** 2        # the polish's normalisation of each sensor
        yy = float(sum(np.sum(e.outputs ** 2 * w) for e in exps))
        for j, x in enumerate(np.atleast_2d(X)):
            try:
                sim = self.evaluator.simulate(np.asarray(x, float))
            except (EbbError, ValueError, np.linalg.LinAlgError):
                out[j] = (np.inf, np.nan)
                continue
            if not sim.stable or not sim.outputs:
                out[j] = (np.inf, np.nan)
                continue
            sy = float(sum(np.sum(s * e.outputs * w) for s, e in zip(sim.outputs, exps)))
            ss = float(sum(np.sum(s * s * w) for s in sim.outputs))
            if not (np.isfinite(ss) and np.isfinite(sy)) or ss <= 0:
                out[j] = (np.inf, np.nan)
                continue
            a = sy / ss if self.project else 1.0
            out[j] = (yy - 2 * a * sy + a * a * ss, a)
        return out


def _head(evaluator: Any) -> Any:
    """``evaluator`` on the first :data:`MAX_SAMPLES` samples of every experiment."""
    from dataclasses import replace

    exps = tuple(replace(e, inputs=e.inputs[:MAX_SAMPLES], outputs=e.outputs[:MAX_SAMPLES])
                 for e in evaluator.experiments)
    return replace(evaluator, experiments=exps)


def _family(evaluator: Any, d: _Directions) -> list[tuple[float | None, np.ndarray]]:
    """The model's undamped frequencies [Hz] at the nominal EI and ρA, per value of N tried (``None``: N is not
    unknown), the values of N that buckle the beam left out: their "frequencies" are those of an unstable model
    (measured: a pinned–pinned beam bounded at 5.8 Euler loads in compression — its first eight values of N
    buckled it, every pairing with them placed the one mode its records showed, and the start went to the
    bound's end, EI 0.96 and N −32 for 3.79 and −11.8).  A candidate scales N with EI, so a value that buckles
    the beam at the nominal EI buckles it at every frequency scale."""
    from ebb_model.assemble import buckling_load
    from ebb_model.modal.modal import discrete_frequencies

    cfg = evaluator.config
    n_modes = min(40, cfg.beam.nodes)
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
        x = d.candidate(1.0, 0.0, nv)
        try:
            c, p = evaluator.space.apply(cfg, x)
            f, _ = discrete_frequencies(c, {**dict(p), "c": 0.0, "eta": 0.0}, n_modes)
        except (EbbError, ValueError, np.linalg.LinAlgError):
            continue
        out.append((nv, np.asarray(f, float)))
    return out


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


def _alignments(peaks: np.ndarray, weights: np.ndarray, family: list[tuple[float | None, np.ndarray]],
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


def data_start(evaluator: Any, runner: Runner | None = None) -> DataStart | None:
    """The start the records give (module docstring); ``None`` when neither the frequency scale nor the damping
    is among the unknowns (nothing to read).

    Parameters
    ----------
    evaluator
        The native evaluator of the identification (its config, unknowns and experiments).
    runner
        Where batches of trials are evaluated (default: this process).
    """
    run = runner or SerialRunner()
    sp, cfg = evaluator.space, evaluator.config
    names = tuple(sp.names)
    fixed = {k: float(cfg.parameters[k].value) for k in ("EI", "rhoA", "c", "eta", "N") if k in cfg.parameters}
    if not any(n in names for n in ("EI", "rhoA", "c", "eta")):
        return None
    d0 = _Directions(names, sp.lower, sp.upper, sp.nominal, fixed, 1.0)
    family = _family(evaluator, d0)
    if not family:
        return None
    exps = evaluator.experiments
    dt = float(cfg.time.dt)
    recorded = record_modes([e.inputs for e in exps], [e.outputs for e in exps], dt, effective_delays(cfg))
    peaks = recorded.frequencies_hz
    k_lo, k_hi = d0.k_range()
    nyquist = 0.5 / dt
    if peaks.size:
        starts = _alignments(peaks, recorded.support, family, k_lo, k_hi, nyquist)
    else:
        starts = []
    nominal_n = family[len(family) // 2][0]
    if not starts:
        starts = [(min(max(1.0, k_lo), k_hi), nominal_n)]
    # the damping's reference: the lowest mode the peaks show (else the model's first)
    cost_ev = ProjectedCost(_head(evaluator), d0.level_free)
    count = 0

    def trial_costs(trials: list[tuple[float, float, float | None]], d: _Directions) -> np.ndarray:
        nonlocal count
        X = np.array([d.candidate(k, z, nv) for k, z, nv in trials])
        count += len(X)
        return np.asarray(run(cost_ev, X), float)

    best: tuple[float, float, float, float | None, float, _Directions] | None = None
    for k0, nv0 in starts:
        f_model = dict(family)[nv0]
        f_model = f_model[f_model > 0]
        seen = f_model[np.min(np.abs(np.log(k0 * f_model[:, None] / peaks[None, :])), axis=1) < MATCH_TOLERANCE] \
            if peaks.size else f_model[:1]
        d = _Directions(names, sp.lower, sp.upper, sp.nominal, fixed,
                        2 * math.pi * float(seen[0] if seen.size else f_model[0]))
        k, zeta, nv = k0, STAGES[0][1], nv0
        cost, level = math.inf, math.nan
        for window, z_stage in STAGES:
            zs = sorted({zeta, z_stage}) if (d.has("c") or d.has("eta")) else [zeta]
            ks = k * (1.0 + window * np.linspace(-1.0, 1.0, TRIALS))
            ks = ks[(ks >= k_lo * (1 - 1e-12)) & (ks <= k_hi * (1 + 1e-12))]
            trials = [(float(kk), float(z), nv) for kk in ks for z in zs]
            if not trials:
                break
            res = trial_costs(trials, d)
            j = int(np.argmin(res[:, 0]))
            if res[j, 0] < cost or not math.isfinite(cost):
                k, zeta, _ = trials[j]
                cost, level = float(res[j, 0]), float(res[j, 1])
            if d.has("N") and nv is not None:
                i = names.index("N")
                span = (d.upper[i] - d.lower[i]) * window * 4.0
                nvs = np.clip(nv + span * np.linspace(-1.0, 1.0, 9), d.lower[i], d.upper[i])
                trials = [(k, zeta, float(v)) for v in nvs]
                res = trial_costs(trials, d)
                j = int(np.argmin(res[:, 0]))
                if res[j, 0] < cost:
                    nv = trials[j][2]
                    cost, level = float(res[j, 0]), float(res[j, 1])
        if d.has("c") or d.has("eta"):
            # the damping on a finer grid at the end: the level projected out depends on it (a peak's height is
            # ∝ 1/ζ), and the stages' values are a factor of 4 apart
            trials = [(k, float(z), nv) for z in zeta * DAMPING_FACTORS]
            res = trial_costs(trials, d)
            j = int(np.argmin(res[:, 0]))
            if res[j, 0] < cost:
                zeta, cost, level = trials[j][1], float(res[j, 0]), float(res[j, 1])
        if best is None or cost < best[0]:
            best = (cost, k, zeta, nv, level, d)
    assert best is not None
    cost, k, zeta, nv, level, d = best
    note: str | None = None
    if d.level_free and math.isfinite(level):
        scale = 1.0 / abs(level) if level != 0 else 1.0
        raw = d.candidate(k, zeta, nv)
        i, j = names.index("EI"), names.index("rhoA")
        # the scales EI and rhoA both allow (c and N follow; clipped on their own, they move no frequency)
        lo = max(d.lower[i] / raw[i], d.lower[j] / raw[j])
        hi = min(d.upper[i] / raw[i], d.upper[j] / raw[j])
        reach = min(max(scale, lo), hi) if lo <= hi else scale
        x = d.candidate(k, zeta, nv, reach)
        if reach != scale:
            note = (f"the records' level asks for EI {raw[i] * scale:.4g} and rhoA {raw[j] * scale:.4g}, outside "
                    f"their bounds ({d.lower[i]:.4g}–{d.upper[i]:.4g}, {d.lower[j]:.4g}–{d.upper[j]:.4g}): the "
                    f"records are {reach / scale:.3g} times what the bounds allow — check the records' units and "
                    "calibration, or widen the bounds")
    else:
        x = d.candidate(k, zeta, nv)
        level = math.nan
    return DataStart(x, peaks, level, note, count)
