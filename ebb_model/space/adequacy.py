"""Numerical adequacy: how much of a model-vs-measurement gap is the model's own discretisation error.

At given parameters the model is simulated on its own grid and on a refined one: :func:`refined_grid`, or,
when :mod:`ebb_model.space.grid_advice` finds the config's grid too coarse for the band the record excites, the grid
it recommends (one refinement step of a grid far from its asymptotic range changes only part of its error).
Against the measurements, per sensor and in noise variances: the gap of the model, the gap of the refined model,
and the change refinement makes.
Their ratio, the *numerical share*, says how much of the gap is numerical: near 0 the gap is the physics'
(or noise), near 1 the grid's — then no physical effect should be blamed for it, and the grid should be
refined (``[beam] nodes``).

What the grid does to the *answer* is :class:`ParameterShift`: the step a fit on the refined grid would take from
the identified point, in the unknowns' Cramér–Rao deviations (:func:`parameter_shift`).  The outputs' change alone
misses it: a change the noise hides per sample can move the parameters by many deviations on a long record (a
pinned–clamped beam under broadband force, one accelerometer, 10,000 samples: 323 → 1,295 nodes changes the outputs
by 0.25 noise variances per sample and moves EI by 6.7 deviations, 0.16 %; 647 → 2,591 nodes, 0.0014 and 1.65).
The advice names the grid measured, not one extrapolated from it: where the records resolve the unknowns to 1e-4
the answer's convergence on large grids is not the spacing squared (the demo's beam under white noise for 10 s, N's
deviation 8e-5 of N: 323 → 647 nodes 1.1 deviations, 647 → 1,295 1.9, 1,295 → 2,591 13 — the eigen-solver's
round-off grows with the grid, :mod:`ebb_model.space.richardson_pair`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import math

import numpy as np
from numpy.typing import ArrayLike
from scipy.signal import periodogram, welch

from ..config import BeamConfig
from ..errors import DataError
from ..simulate import fast_model, simulate

if TYPE_CHECKING:
    from .grid_advice import GridAdvice

__all__ = ["DECISIVE_EVIDENCE", "GRID_SHIFT", "NOISE_FLOOR_EXCESS", "NumericalAdequacy", "ParameterShift",
           "TRANSIENT_SHARE", "adequacy_line", "at_the_floor", "excited_band", "grid_line", "is_transient", "modes_top",
           "numerical_adequacy", "refined_grid"]

#: Relative excess of a residual variance over the noise floor below which there is no gap (to explain, or to
#: share between grid and physics): a gap ratio up to ``1 + NOISE_FLOOR_EXCESS`` is the noise.
NOISE_FLOOR_EXCESS = 0.25
#: A grid is too coarse for the records when refining it moves some unknown by more than this many of its
#: Cramér–Rao deviations (the grid's bias then exceeds what the noise leaves: the mean square error at least
#: doubles) and the records prefer the refined grid by :data:`DECISIVE_EVIDENCE`.
GRID_SHIFT = 1.0
#: Decisive odds of 100 to 1 between two models of the same unknowns, in χ² (2 ln 100): what the records must prefer
#: a refinement by (here and in :mod:`identification.numerics`).
DECISIVE_EVIDENCE = 2.0 * math.log(100.0)


def refined_grid(config: BeamConfig) -> BeamConfig:
    """``config`` on a finer grid: θ-scheme twice the intervals (``2n + 1`` nodes) and twice the sub-steps;
    exact scheme four times (``4n + 3`` nodes), so that its Richardson pair of grids is a finer pair too
    (``2n + 1`` alone would pair with the config's own grid again, see
    :func:`ebb_model.space.richardson_pair.companion_config`)."""
    n = config.beam.nodes
    if config.time.scheme == "theta":
        return replace(config, beam=replace(config.beam, nodes=2 * n + 1),
                       time=replace(config.time, substeps=2 * config.time.substeps))
    return replace(config, beam=replace(config.beam, nodes=4 * n + 3))


@dataclass(frozen=True)
class ParameterShift:
    """What refining the grid from ``nodes`` to ``refined_nodes`` does to the identified unknowns ``names``: the
    Gauss–Newton step of a fit on the refined grid, in Cramér–Rao deviations (``deviations``), relative to the
    values (``relative``; ``nan`` for a value of zero) and in the unknowns' units (``step``); ``gain``, how much
    lower the refit's χ² is than the fit's (negative: the records fit the model's own grid better)."""

    names: tuple[str, ...]
    deviations: np.ndarray
    relative: np.ndarray
    nodes: int
    refined_nodes: int
    step: np.ndarray
    gain: float

    @property
    def worst(self) -> int:
        """Index of the unknown moved by the most deviations."""
        return int(np.argmax(np.abs(self.deviations)))

    @property
    def largest(self) -> float:
        """The largest shift in deviations (absolute)."""
        return float(np.max(np.abs(self.deviations), initial=0.0))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {"nodes": self.nodes, "refined_nodes": self.refined_nodes,
                "cramer_rao_deviations": dict(zip(self.names, map(float, self.deviations))),
                "step": dict(zip(self.names, map(float, self.step))), "chi2_gain": self.gain,
                "relative": {k: (None if not math.isfinite(v) else float(v)) for k, v in zip(self.names,
                                                                                              self.relative)}}

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> ParameterShift:
        """The inverse of :meth:`to_dict`."""
        names = tuple(doc["cramer_rao_deviations"])
        rel = doc["relative"]
        return cls(names, np.array([float(doc["cramer_rao_deviations"][k]) for k in names]),
                   np.array([math.nan if rel[k] is None else float(rel[k]) for k in names]), int(doc["nodes"]),
                   int(doc["refined_nodes"]), np.array([float(doc["step"][k]) for k in names]),
                   float(doc["chi2_gain"]))


@dataclass(frozen=True)
class NumericalAdequacy:
    """Per sensor, in noise variances: ``gap`` (model), ``gap_refined``, ``change`` (refined − model);
    ``numerical_share = change / gap``; ``shift``, what the refined grid does to the unknowns
    (:func:`identification.grid_shift.parameter_shift`; ``None`` when not measured)."""

    sensors: tuple[str, ...]
    gap: np.ndarray
    gap_refined: np.ndarray
    change: np.ndarray
    refined_nodes: int
    shift: ParameterShift | None = None

    @property
    def numerical_share(self) -> np.ndarray:
        """Fraction of each sensor's gap that refining the grid changes."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.gap > 0, self.change / self.gap, 0.0)

    @property
    def share_of_the_gap(self) -> float:
        """The largest sensor's :attr:`numerical_share`, or 0 when every sensor is at the noise floor
        (:func:`at_the_floor`): then there is no gap to share — the one reading of :func:`adequacy_line` and of the
        diagnosis' grid rule (a cantilever's correct record fitted to 1.1 noise variances on a coarse grid was said
        to be at the floor, "none to share", beside "27 % of the baseline gap is the model's grid")."""
        if at_the_floor(self.gap):
            return 0.0
        return float(np.max(self.numerical_share, initial=0.0))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        per = {s: {"gap_ratio": float(g), "gap_ratio_refined": float(r), "change": float(c),
                   "numerical_share": float(f)}
               for s, g, r, c, f in zip(self.sensors, self.gap, self.gap_refined, self.change,
                                        self.numerical_share)}
        return {"refined_nodes": self.refined_nodes, "sensors": per,
                "max_numerical_share": float(np.max(self.numerical_share)) if self.sensors else 0.0,
                "parameter_shift": None if self.shift is None else self.shift.to_dict()}

    def summary(self) -> str:
        """One line for reports (:func:`adequacy_line`)."""
        return adequacy_line(self.to_dict())


def adequacy_line(summary: Mapping[str, Any]) -> str:
    """One report line from :meth:`NumericalAdequacy.to_dict`'s summary.

    A fit at the noise floor (every sensor's gap ratio at most ``1 + NOISE_FLOOR_EXCESS``) has no gap to share:
    the line then says so and gives the change refinement makes, in noise variances, instead of a percentage.
    """
    share = summary["max_numerical_share"]
    per = summary.get("sensors", {}).values()
    if per and at_the_floor([s["gap_ratio"] for s in per]):
        change = max(s["change"] for s in per)
        return (f"numerical share of the gap: none to share, the fit is at the noise floor ({_refining(summary)} "
                f"changes the outputs by {change:.2g} noise variances)")
    change = max((s["change"] for s in per), default=0.0)
    refine = share > 0.1 and change > NOISE_FLOOR_EXCESS      # the grid line's criterion (grid_line) as well
    return (f"numerical share of the gap: {100 * share:.2g} % at most ({_refining(summary)}"
            + ("; refine [beam] nodes before blaming physics)" if refine else ")"))


def _refining(summary: Mapping[str, Any]) -> str:
    return f"refining the grid to {summary['refined_nodes']} nodes"


def at_the_floor(gap_ratios: ArrayLike) -> bool:
    """Whether every gap ratio (residual over noise variance, one per sensor) is within :data:`NOISE_FLOOR_EXCESS`
    of the noise floor."""
    return bool(np.all(np.asarray(gap_ratios, dtype=float) <= 1.0 + NOISE_FLOOR_EXCESS))


def grid_line(advice: GridAdvice, adequacy: NumericalAdequacy) -> str:
    """One grid advice from the records: too coarse when refining the grid moves some unknown by more than
    :data:`GRID_SHIFT` Cramér–Rao deviations (``adequacy.shift``, when measured) and the records prefer the refined
    grid by :data:`DECISIVE_EVIDENCE`, or changes some sensor's outputs by more than the noise hides
    (:data:`NOISE_FLOOR_EXCESS` noise variances); undecided when the answer moves but the records do not prefer
    the refined grid (another error of the model's is as large: measured on the first-record family's cantilever
    under a chirp, at the floor, rhoA 2 deviations on the refined grid, χ² 0.7 lower, and the refined answer 1.7
    deviations from the truth where the model's own was 0.4); adequate otherwise — whatever the
    modes' frequency errors say (``advice``, quoted beside it): the outputs count every mode the sensors see, its
    shape at the sensors and actuators, and the modes above the band (a strip's tip accelerometer under a broadband
    force: modes 1-6 within 5 % of a half-power bandwidth on 80 nodes, the outputs 3.5 noise variances off), and
    the shift counts what the records resolve (module docstring: 0.25 noise variances, 6.7 deviations).  Where the
    outputs change by more than the noise hides but the model's grid fits the records to the noise
    (:func:`at_the_floor`) and the refined grid's refit raises χ² decisively, the records fit the model's grid
    better, and the line says that instead of "too coarse for these records": a record made by the model itself on
    the config's 80 nodes (the strip, a tip accelerometer, 1 % noise) moves ρA by 30 deviations and raises χ² by
    2.3e3 on 323 nodes — "too coarse" is true of a beam's records there, not of these.  Away from the floor the
    Gauss–Newton step's χ² says nothing of the kind (the seed's θ-scheme on a coarse grid, its gap 252 % the
    grid's, the step's χ² higher by more than decisive: "too coarse", as the grid verdict says)."""
    from .grid_advice import BANDWIDTH_FRACTION

    change = float(np.max(adequacy.change, initial=0.0))
    k = advice.frequencies_hz.size
    worst = float(np.max(advice.error_bandwidths, initial=0.0))
    modes = (f"modes 1-{k} to {advice.frequencies_hz[-1]:.4g} Hz within {BANDWIDTH_FRACTION:.0%} of a half-power "
             f"bandwidth" if advice.adequate else f"the modes to {advice.frequencies_hz[-1]:.4g} Hz up to {worst:.2g} "
             "half-power bandwidths off")
    moved = f"{_refining(adequacy.to_dict())} changes the outputs by {change:.2g} noise variances"
    shift = adequacy.shift
    if shift is not None:
        i = shift.worst
        rel = shift.relative[i]
        moved += (f" and moves {shift.names[i]} by {abs(shift.deviations[i]):.2g} Cramér–Rao deviations"
                  + (f" ({100 * abs(rel):.2g} %)" if math.isfinite(rel) else ""))
    moves = shift is not None and shift.largest > GRID_SHIFT
    coarse_shift = moves and shift is not None and shift.gain > DECISIVE_EVIDENCE
    if change <= NOISE_FLOOR_EXCESS and moves and not coarse_shift:
        assert shift is not None
        refit = (f"lowers χ² by {shift.gain:.2g}, short of decisive {DECISIVE_EVIDENCE:.2g}" if shift.gain >= 0.0
                 else f"raises χ² by {-shift.gain:.2g}")
        return (f"grid: undecided for these records ({moved}, more than the noise leaves, but the records do not "
                f"prefer the refined grid: its refit {refit}; {modes})")
    if change <= NOISE_FLOOR_EXCESS and not coarse_shift:
        return f"grid: adequate for these records ({moved}; {modes})"
    if shift is not None and shift.gain < -DECISIVE_EVIDENCE and at_the_floor(adequacy.gap):
        return (f"grid: these records fit it better than a finer one ({moved}, but its refit raises χ² by "
                f"{-shift.gain:.2g}, decisively: records a model made on this grid, or another error of the model's "
                f"that this grid's makes up for; a beam's records would ask for [beam] nodes >= "
                f"{adequacy.refined_nodes}; {modes})")
    why = "more than the noise leaves" if coarse_shift else "more than the noise hides"
    return (f"grid: too coarse for these records ({moved}, {why}; {modes}); use [beam] nodes >= "
            f"{adequacy.refined_nodes}")


#: An input whose energy lies for this share within a tenth of the record is a transient (a hammer blow).
TRANSIENT_SHARE = 0.9


def is_transient(u: np.ndarray) -> bool:
    """Whether most of the input's energy (:data:`TRANSIENT_SHARE`) lies in a tenth of the record (a blow, not a
    persistent excitation); ``u`` ``(n,)`` or ``(n, m)``."""
    u = np.asarray(u, dtype=float).reshape(u.shape[0], -1)
    e = np.sum(u * u, axis=1)
    total = float(e.sum())
    if total <= 0.0:
        return False
    w = max(1, e.size // 10)
    run = np.convolve(e, np.ones(w), mode="valid")
    return float(run.max()) >= TRANSIENT_SHARE * total


def modes_top(band_hz: float, dt: float) -> float:
    """The top of the modes a record with the excited band's top ``band_hz`` shows [Hz]: a fifth above the band
    (a mode just above it still answers), below Nyquist (an impact excites up to it)."""
    return min(1.2 * band_hz, 0.98 * 0.5 / dt)


def excited_band(inputs: Sequence[np.ndarray], dt: float, *, rel: float = 1e-3) -> tuple[float, float]:
    """Frequency range [Hz] where the input power is above ``rel`` of its peak: Welch's PSD for a persistent
    input, the whole record's periodogram for a transient one (:func:`is_transient` — a blow near the record's
    start falls where Welch's Hann windows are near zero: measured, a 10 ms blow at 2 kHz read as excited to
    0.49 Hz only, and the grid advice then counted one mode).

    Raises
    ------
    DataError
        The inputs carry no power.
    """
    lo, hi = math.inf, 0.0
    for u in inputs:
        if is_transient(u):
            f, P = periodogram(u, fs=1.0 / dt, window="boxcar", axis=0)
        else:
            f, P = welch(u, fs=1.0 / dt, nperseg=min(4096, u.shape[0]), axis=0)
        P = P.sum(axis=1) if P.ndim > 1 else P
        on = f[P >= rel * P.max()] if P.max() > 0 else f[:0]
        if on.size:
            lo, hi = min(lo, float(on.min())), max(hi, float(on.max()))
    if hi <= 0:
        raise DataError("inputs: the measured forces carry no power")
    return (0.0 if not math.isfinite(lo) else lo), hi


def adequacy_grid(config: BeamConfig, params: Mapping[str, float], band_hz: float,
                  advice: GridAdvice | None = None) -> BeamConfig:
    """The grid to compare with: :func:`refined_grid`, or finer where the grid advice (``advice``, computed
    when not given) asks for more."""
    from .grid_advice import grid_advice

    fine = refined_grid(config)
    if advice is None:
        advice = grid_advice(config, params, band_hz=band_hz)
    if advice.adequate or advice.nodes_needed is None:
        return fine
    time = replace(fine.time, substeps=max(fine.time.substeps, advice.substeps_needed))
    return replace(fine, beam=replace(fine.beam, nodes=max(fine.beam.nodes, advice.nodes_needed)), time=time)


def numerical_adequacy(config: BeamConfig, params: Mapping[str, float],
                       records: Sequence[tuple[np.ndarray, np.ndarray]],
                       noise_std: ArrayLike, *, band_hz: float | None = None,
                       advice: GridAdvice | None = None) -> NumericalAdequacy:
    """Gap of the model at ``params`` with and without refinement, over ``records`` of ``(inputs, outputs)``.

    Parameters
    ----------
    config, params
        The model and its (fitted) parameter values.
    records
        Inputs (n, n_actuators) and measured outputs (n, n_sensors) in the config's sensor order.
    noise_std
        Noise standard deviation per sensor.
    band_hz
        Top of the excited band [Hz] (default: from the inputs, :func:`excited_band`), for the grid advice.
    advice
        The grid advice at ``params`` for that band, when the caller has it
        (:func:`~ebb_model.space.grid_advice.grid_advice`; computed otherwise — its reference grids are the costly
        part).
    """
    if band_hz is None:
        band_hz = excited_band([u for u, _ in records], config.time.dt)[1]
    fine_cfg = adequacy_grid(config, params, band_hz, advice)
    model, fine = fast_model(config, params), fast_model(fine_cfg, params)
    sigma2 = np.asarray(noise_std, dtype=float) ** 2
    sq = np.zeros((3, len(config.sensors)))
    n = 0
    for u, y in records:
        y_m = simulate(model, u).outputs
        y_f = simulate(fine, u).outputs
        sq += [np.sum((y - y_m) ** 2, axis=0), np.sum((y - y_f) ** 2, axis=0), np.sum((y_f - y_m) ** 2, axis=0)]
        n += y.shape[0]
    gap, gap_f, change = (sq / max(n, 1)) / sigma2
    return NumericalAdequacy(config.output_names, gap, gap_f, change, fine_cfg.beam.nodes)
