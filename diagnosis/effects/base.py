"""What an effect of the catalogue is: search variables, and the model it makes of a baseline.

An :class:`Effect` maps search values ``s`` and a baseline ``(config, params)`` to an :class:`AugmentedModel`:
a config and parameters (structural effects change these: end springs, a point mass, beam terms) plus the
:class:`Signal` parts no config can express (lags on the way in or out, laws of the axial force).  The
simulation (:func:`diagnosis.problem.augmented.simulate_effects`) and the corrected model's StateSpace
(:func:`diagnosis.corrected.export.corrected_statespace`) ask each signal part what it does, so a new signal-level
effect is its own module in this package: a :class:`Signal` subclass and the family that builds it.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping

import numpy as np

from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError
from ebb_model.statespace import DiscreteStateSpace

__all__ = ["Scales", "AxialLoad", "Signal", "AugmentedModel", "Effect", "Family", "Landing", "signal_effect",
           "pair_effect", "on_top_of", "mirror_image", "variables_for", "PAIR_SEPARATOR"]

#: Joins the labels of two effects acting at once (``foundation+actuator_lag``).
PAIR_SEPARATOR = "+"


@dataclass(frozen=True)
class Scales:
    """Scales of the baseline beam and record that set the effects' search bounds.

    Attributes
    ----------
    EI, rhoA, N, length
        Identified baseline values and beam length.
    omega_low, omega_high
        Lowest and highest modal angular frequency [rad/s] inside the excited band.
    duration
        Length of the fitted record [s].
    stretch_max
        Largest ``∫ w_x² dx`` of the baseline response over the record (for the
        geometric-stiffening bound); 0 when unknown.
    output_rms
        Root-mean-square reading of each sensor over the fitted records, in the config's sensor order (what an
        output-level effect — an offset, a drift of a reading — sizes its bounds from); empty when unknown.
    read_delay
        The sensors' delay after the force [samples] and its concentration, read from the phase of the fitted
        records against the baseline's prediction (:func:`diagnosis.effects.delay.read_delay`); ``None`` when
        unread.
    """

    EI: float
    rhoA: float
    N: float
    length: float
    omega_low: float
    omega_high: float
    duration: float
    stretch_max: float = 0.0
    output_rms: tuple[float, ...] = ()
    read_delay: tuple[float, float] | None = None


@dataclass(frozen=True)
class AxialLoad:
    r"""Terms of the extra axial force :math:`\delta N(t) = \text{rate}\cdot t + \frac{EA}{2L}\int_0^L w_x^2\,dx`.

    The laws the axial simulation (:func:`diagnosis.problem.augmented.simulate_axial`) integrates; the terms of several
    signal parts add.
    """

    rate: float = 0.0
    EA: float = 0.0

    def __add__(self, other: AxialLoad) -> AxialLoad:
        return AxialLoad(self.rate + other.rate, self.EA + other.EA)

    @property
    def zero(self) -> bool:
        """No extra axial force: the beam stays linear and time-invariant."""
        return self.rate == 0.0 and self.EA == 0.0


@dataclass(frozen=True)
class Signal:
    """A signal-level part of an effect: what no change of the beam's config can express.

    Subclasses override what they act on; the defaults leave everything unchanged.  Values are checked when
    the part is made (raise :class:`~ebb_model.errors.ParameterError` naming the effect).
    """

    #: Words for reports ("the actuator's first-order lag").
    description = "a signal-level effect"

    def inputs(self, u: np.ndarray, dt: float) -> np.ndarray:
        """The force the beam feels from the measured inputs ``u`` (n_samples, n_inputs)."""
        return u

    def outputs(self, y: np.ndarray, dt: float, names: tuple[str, ...]) -> np.ndarray:
        """What the sensors ``names`` record of the beam's outputs ``y`` (n_samples, n_sensors); a new array."""
        return y

    def axial(self) -> AxialLoad:
        """This part's terms of the extra axial force (none by default)."""
        return AxialLoad()

    def in_series(self, sys: DiscreteStateSpace) -> DiscreteStateSpace | None:
        """The discrete system with this part in series, equal to the simulation of :meth:`inputs` and
        :meth:`outputs`; ``None`` when the part is not linear time-invariant (then there is no such system)."""
        return sys if self.axial().zero else None

    @property
    def time_invariant(self) -> bool:
        """Whether the model stays linear and time-invariant with this part."""
        return self.axial().zero


@dataclass(frozen=True)
class AugmentedModel:
    """A baseline model with effects applied, ready for :func:`diagnosis.problem.augmented.simulate_effects`.

    Attributes
    ----------
    config, params
        The beam (structural effects included) and its parameter values.
    signals
        The signal-level parts, in the order they act (inputs first to last, then outputs likewise).
    """

    config: BeamConfig
    params: Mapping[str, float]
    signals: tuple[Signal, ...] = ()

    @property
    def axial(self) -> AxialLoad:
        """The signal parts' axial-force terms together."""
        return sum((s.axial() for s in self.signals), AxialLoad())

    @property
    def time_invariant(self) -> bool:
        """Whether every signal part keeps the model linear and time-invariant."""
        return all(s.time_invariant for s in self.signals)


@dataclass(frozen=True)
class Landing:
    """Where the refit of a special case at a fixed place starts: a general effect's refit that landed near the
    place (a point mass's refit within 5 % of the beam's length of a sensor starts that sensor's transducer mass).

    Attributes
    ----------
    source
        Label of the general effect.
    position
        Which of the source's search variables is its position [m].
    copy
        ``(this effect's variable, the source's variable)`` pairs taken from the landing; the other variables
        start at their "off" value.
    reach
        How near the place the landing must be, as a share of the beam's length.
    """

    source: str
    position: int
    copy: tuple[tuple[int, int], ...]
    reach: float


@dataclass(frozen=True, eq=False)
class Effect:
    """A candidate unmodelled effect.

    Attributes
    ----------
    name
        Catalogue family (one of :data:`diagnosis.effects.EFFECT_NAMES`).
    target
        Sensor name for ``sensor_lag``; ``None`` otherwise.
    variables
        Names of the search variables.
    lower, upper, off
        Bounds and "off" value of each search variable (``off`` lies on a bound
        for one-sided effects, inside for two-sided ones such as drift).
    description
        One line for reports.
    units
        Unit of each physical parameter (:meth:`physical`'s keys), in the catalogue's notation (``N.m/rad``,
        ``kg``, ``N/m2``) — what the corrected model's files and the reports print beside the values.
    plausible
        The physically plausible range ``(lo, hi)`` of some physical parameters (catalogue units), narrower
        than the search bounds: a refit outside it explains the data with a value no rig has (a point mass
        heavier than a quarter of the beam), and is not named as the cause (:mod:`diagnosis.problem.plausibility`).
    """

    name: str
    target: str | None
    variables: tuple[str, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    off: tuple[float, ...]
    description: str
    units: Mapping[str, str]
    _apply: Callable[[BeamConfig, dict[str, float], np.ndarray], AugmentedModel] = field(repr=False)
    _physical: Callable[[np.ndarray], dict[str, float]] = field(repr=False)
    plausible: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    #: a start for the refit that moves along a direction the data cannot see to where the priors are best (the
    #: measurement chain's gains: :func:`diagnosis.effects.chain.rescaled_start`); ``None``: no such direction
    rescale: Callable[[tuple[str, ...], np.ndarray, np.ndarray, Any], tuple[np.ndarray, np.ndarray] | None] | None \
        = field(default=None, repr=False)
    #: the label of the effect this one is a special case of (a transducer's mass: a point mass at its sensor);
    #: tied with it, this one is named when it explains the held-out records on its own
    #: (:func:`diagnosis.judgement.rules.nested`)
    nested_in: str | None = None
    #: whether the effect is degenerate with a common scale of the beam's unknowns (a gain of the measurement chain:
    #: scaling EI, ρA, c and N scales every output alike), so that its score at a baseline that took up the scale
    #: says little of its worth: it is refitted apart from the shortlist, tried as a pair's second effect only
    #: where a prior breaks the degeneracy, and named beside a model at the noise floor as what the data cannot
    #: tell from the beam's scale (:mod:`diagnosis.search.rank`, :mod:`diagnosis.search.pairs`,
    #: :func:`diagnosis.judgement.rules.notes`)
    scale_degenerate: bool = False
    #: for a special case at a place the set-up fixes: that place [m] in a config (a sensor's or an actuator's
    #: position) and the general effects' landings its refit starts from (:mod:`diagnosis.search.nested`)
    place: Callable[[BeamConfig], float] | None = field(default=None, repr=False)
    landings: tuple[Landing, ...] = ()
    #: the simpler effects it must beat, each by the BIC margin, to stay a candidate (an armature: its mass alone
    #: and its suspension alone — a point mass at the drive point is a point mass, not an armature with a
    #: vanishing suspension); given this effect, returns them
    parts: Callable[[Effect], tuple[Effect, ...]] | None = field(default=None, repr=False)
    #: the rig part it models (:data:`diagnosis.setups.RIG_PARTS`: a shaker's armature, a transducer's mass): a
    #: candidate only where the records' set-up has the part, off in evidence from a set-up without it
    #: (:mod:`diagnosis.setups`); ``None``: the beam's own physics, shared by every set-up
    rig_part: str | None = None
    #: for a pair, its two effects (:func:`pair_effect`)
    members: tuple[Effect, ...] = field(default=(), repr=False)
    #: the search variables proportional to a physical size the beam's force-like constants measure (a mass in
    #: units of the nominal ρA L, a stiffness in units of EI/L³): multiplying them with EI, ρA, c and N by λ
    #: leaves the modes alone and divides the response by λ (:mod:`diagnosis.search.modal_pattern` sets that scale from
    #: the amplitudes)
    scaled: tuple[int, ...] = ()
    #: the refit's trial starts in place of the coarse grid around "off"
    #: (:func:`diagnosis.candidates.score.trial_values`) — for a variable whose χ² is not unimodal between the grid's
    #: points (a delay: periodic along each dominant mode's period, :mod:`.delay`); empty: that grid
    trials: tuple[np.ndarray, ...] = field(default=(), repr=False)
    #: boxes ``(lower, upper)`` of the effect's variables read from the records themselves, within the reading's
    #: error (a delay from the phase of the records against the baseline's prediction: :func:`.delay.read_delay`):
    #: where the refit from the best trial leaves a gap, the effect is refitted held in each box, then freed
    #: (:mod:`diagnosis.search.refits`) — a trial is judged with the baseline's unknowns held, which the effect
    #: left out had bent; empty: none
    read: tuple[tuple[tuple[float, ...], tuple[float, ...]], ...] = ()

    @property
    def label(self) -> str:
        """Unique label, e.g. ``sensor_lag[y2]``."""
        return f"{self.name}[{self.target}]" if self.target else self.name

    @property
    def dim(self) -> int:
        """Number of search variables."""
        return len(self.variables)

    def apply(self, config: BeamConfig, params: Mapping[str, float], s: np.ndarray) -> AugmentedModel:
        """The baseline ``(config, params)`` with this effect at search values ``s``."""
        s = np.asarray(s, dtype=float)
        if s.shape != (self.dim,):
            raise ValueError(f"{self.label}: expected {self.dim} values, got shape {s.shape}")
        return self._apply(config, dict(params), s)

    def physical(self, s: np.ndarray) -> dict[str, float]:
        """Physical parameters (catalogue units) of search values ``s``."""
        return self._physical(np.asarray(s, dtype=float))


@dataclass(frozen=True)
class Family:
    """A catalogue entry: the effect families a module names, and its builder of candidates.

    ``candidates(config, scales, identified)`` returns the module's effects that apply to this set-up (none
    whose parameter is already among the baseline unknowns ``identified``).
    """

    names: tuple[str, ...]
    candidates: Callable[[BeamConfig, Scales, tuple[str, ...]], tuple[Effect, ...]]


def sensor_index(family: str, sensor: str, names: tuple[str, ...]) -> int:
    """Column of ``sensor`` among the output ``names`` of a per-sensor signal part of ``family``.

    Raises
    ------
    ConfigError
        ``sensor`` is not one of ``names``.
    """
    if sensor not in names:
        raise ConfigError(f"{family}: unknown sensor {sensor!r}; sensors are {', '.join(names)}")
    return list(names).index(sensor)


def signal_effect(name: str, target: str | None, variable: str, bounds: tuple[float, float], off: float,
                  description: str, part: Callable[[float], Signal], parameter: str, unit: str) -> Effect:
    """A one-variable signal-level effect: the search value ``s`` is the physical ``parameter`` itself (in
    ``unit``), and ``part(s)`` the signal part (none at the off value, so the "off" model is the baseline
    exactly)."""

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        value = float(s[0])
        return AugmentedModel(cfg, params, () if value == off else (part(value),))

    return Effect(name, target, (variable,), (bounds[0],), (bounds[1],), (off,), description, {parameter: unit},
                  apply, lambda s: {parameter: float(s[0])})


def pair_effect(first: Effect, second: Effect) -> Effect:
    """Two effects at once: ``second`` applied to the model ``first`` made; search variables side by side.

    The physical parameters (and their units) are keyed ``"<label>.<parameter>"`` (both effects may have a
    ``tau``).
    """
    if first.name == second.name:
        raise ValueError(f"a pair needs two different effects, got {first.label} twice")
    k = first.dim

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        m1 = first.apply(cfg, params, s[:k])
        m2 = second.apply(m1.config, m1.params, s[k:])
        return AugmentedModel(m2.config, m2.params, m1.signals + m2.signals)

    def physical(s: np.ndarray) -> dict[str, float]:
        return ({f"{first.label}.{n}": v for n, v in first.physical(s[:k]).items()}
                | {f"{second.label}.{n}": v for n, v in second.physical(s[k:]).items()})

    return Effect(f"{first.label}{PAIR_SEPARATOR}{second.label}", None,
                  tuple(f"{first.label}.{v}" for v in first.variables)
                  + tuple(f"{second.label}.{v}" for v in second.variables),
                  first.lower + second.lower, first.upper + second.upper, first.off + second.off,
                  f"{first.description}, and {second.description}",
                  {f"{e.label}.{n}": u for e in (first, second) for n, u in e.units.items()}, apply, physical,
                  {f"{e.label}.{n}": r for e in (first, second) for n, r in e.plausible.items()},
                  members=(first, second))


def on_top_of(first: Effect, s_first: np.ndarray, second: Effect) -> Effect:
    """``second`` acting on the model with ``first`` held at ``s_first`` (the score test of a second effect at
    the refit of the first); variables, bounds and label are ``second``'s."""
    pair = pair_effect(first, second)
    s_first = np.asarray(s_first, dtype=float)

    def apply(cfg: BeamConfig, params: dict[str, float], s: np.ndarray) -> AugmentedModel:
        return pair.apply(cfg, params, np.concatenate([s_first, s]))

    return replace(second, _apply=apply)


def mirror_image(effect: Effect, config: BeamConfig, s: np.ndarray) -> np.ndarray | None:
    """``s`` with the effect's place taken to its mirror image about mid-span (every variable ``x``, a pair's
    ``<label>.x`` too, to ``L − x``) when the beam ``config`` is the same seen from either end — its two ends and
    its own point masses, springs and weak segments; the sensors and actuators are what tell the halves apart —,
    else ``None`` (an effect without a place, or a beam whose ends differ).

    On such a beam every mode is symmetric or antisymmetric, so a place and its mirror image shift the natural
    frequencies alike: a refit can settle at the wrong one (the compressed pinned–pinned beam with a mass at 0.45 L
    withheld: the mass placed at 0.55 L, 158 noise variances left)."""
    places = [i for i, v in enumerate(effect.variables) if v == "x" or v.endswith(".x")]
    L = config.beam.length
    if not places or not _symmetric(config):
        return None
    out = np.array(s, dtype=float)
    out[places] = L - out[places]
    return out


def variables_for(effect: Effect, physical: Mapping[str, float], start: np.ndarray) -> np.ndarray | None:
    """The variables of ``effect`` whose physical values (:meth:`Effect.physical`) are ``physical`` — a refit of
    the same effect in another catalogue, sized from another baseline (a mass searched as a share of the
    baseline's ρA L) —, solved from ``start`` inside the effect's bounds; ``None`` when no point of them gives
    those values to 1e-9 (relative)."""
    from scipy.optimize import least_squares

    keys = list(physical)
    target = np.array([physical[k] for k in keys], dtype=float)
    scale = np.maximum(np.abs(target), 1e-300)

    def miss(s: np.ndarray) -> np.ndarray:
        got = effect.physical(s)
        return np.array([got.get(k, np.nan) for k in keys], dtype=float) / scale - target / scale

    lo, hi = np.asarray(effect.lower, dtype=float), np.asarray(effect.upper, dtype=float)
    if not np.all(np.isfinite(miss(np.clip(start, lo, hi)))):
        return None
    s = least_squares(miss, np.clip(np.asarray(start, dtype=float), lo, hi), bounds=(lo, hi), xtol=1e-15,
                      ftol=1e-15, gtol=1e-15).x
    return s if float(np.max(np.abs(miss(s)))) <= 1e-9 else None


def _symmetric(config: BeamConfig) -> bool:
    """Whether the beam ``config`` is its own mirror image about mid-span (ends and attachments; to 1e-9 L)."""
    L, tol = config.beam.length, 1e-9 * config.beam.length
    if config.beam.left != config.beam.right:
        return False

    def invariant(points: list[tuple[float, ...]]) -> bool:
        here = sorted(points)
        there = sorted((L - p[0], *p[1:]) for p in points)
        return all(abs(a[0] - b[0]) <= tol and a[1:] == b[1:] for a, b in zip(here, there))

    return (invariant([(m.x, m.mass) for m in config.masses]) and invariant([(k.x, k.k) for k in config.springs])
            and invariant([(w.x, w.length, w.factor) for w in config.weak_segments]))
