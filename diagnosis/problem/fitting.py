"""Least-squares fits of the baseline and of augmented models on the fit windows.

A :class:`GapProblem` bundles what every fit needs: the baseline config, its
unknowns (:class:`identification.parameters.ParameterSpace`), the records with
their windows and the per-sensor noise standard deviation.  A model is the
baseline unknowns ``beta`` plus, optionally, one effect's search variables
``s``.  The fits are the identification's fitting engine
(:mod:`identification.least_squares`: unknowns scaled by their bounds, refused
candidates penalised, bounded least squares with a forward-difference Jacobian
and the χ² resolution stop, differential evolution for the global search) on
noise-normalised residuals.

Errors are reported as *gap ratios*: the mean squared noise-normalised
residual of a window, 1 at the noise floor.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ebb_model.config import BeamConfig
from ebb_model.errors import EbbError

from identification.least_squares import Box, distinct_members, evolve, fit_least_squares, penalised
from identification.noise_model import NoiseModel
from identification.modal_data import ModalData
from identification.prior import Prior
from identification.start_modes import scale_moves_modes
from identification.parameters import ParameterSpace

from .augmented import simulate_effects
from ..effects import AugmentedModel, Effect
from .records import Record
from ..settings import Thresholds

__all__ = ["GapProblem", "Fit"]


@dataclass(frozen=True)
class Fit:
    """A fitted model: baseline unknowns, effect variables, residual statistics.

    Attributes
    ----------
    beta
        Baseline unknowns (physical units, order of the space).
    s
        Effect search variables (empty for the baseline).
    rss
        Sum of squared noise-normalised residuals over the fit windows.
    n
        Number of fitted residuals.
    jac
        Jacobian of the normalised residuals w.r.t. the scaled variables at the solution.
    residuals
        Normalised residuals at the solution.
    n_evaluations
        Model evaluations used (including finite-difference Jacobians).
    """

    beta: np.ndarray
    s: np.ndarray
    rss: float
    n: int
    jac: np.ndarray
    residuals: np.ndarray
    n_evaluations: int

    def bic(self, k: int) -> float:
        """Bayesian information criterion ``n ln(RSS/n) + k ln n`` (Gaussian, variance unknown)."""
        return float(self.n * np.log(self.rss / self.n) + k * np.log(self.n))

    def aic(self, k: int) -> float:
        """Akaike information criterion ``n ln(RSS/n) + 2k``."""
        return float(self.n * np.log(self.rss / self.n) + 2 * k)


@dataclass(frozen=True, eq=False)
class GapProblem:
    """Baseline model, unknowns, records and noise level of one diagnosis.

    Parameters
    ----------
    config
        Baseline set-up; parameters that are not unknowns keep its nominal values.
    space
        Baseline unknowns with bounds.
    records
        Measured records with fit and held-out windows.
    noise_std
        Measurement-noise standard deviation per sensor (white-equivalent: the noise's own standard deviation,
        pooled over the records): the yardstick of the localisation and the reports.
    noise
        The noise model per record and sensor (:class:`~identification.noise_model.NoiseModel`): residuals
        are whitened by it, so a model at the truth leaves unit-variance residuals whatever the noise's colour
        and level in each record.  Default: white, ``noise_std`` in every record.
    """

    config: BeamConfig
    space: ParameterSpace
    records: tuple[Record, ...]
    noise_std: np.ndarray
    noise: NoiseModel | None = None
    #: the user's Gaussian priors on the baseline unknowns (:class:`identification.prior.Prior`): fits then
    #: minimise the negative log posterior (the prior's residuals appended to the whitened ones)
    prior: Prior | None = None
    #: measured natural frequencies (:class:`identification.modal_data.ModalData`): their residuals are appended
    #: to the records' — evidence of another kind, fitted together
    modes: ModalData | None = None
    #: further starts of the baseline unknowns (other basins of the global search), tried by refits
    other_starts: tuple[np.ndarray, ...] = ()
    #: the baseline fit from the records' own start (:func:`diagnosis.baseline.fit.baseline_fit`), beside the
    #: baseline from the start given: the force's sign is weighed on the better of the two; after
    #: :func:`diagnosis.baseline.fit.floor_from_the_records`, that fit when it is better than the baseline without
    #: reaching the floor, or worse but placing the records' own modes better (the measured modes' scan and the
    #: modal patterns start there too), else ``None``
    rival: Fit | None = None
    #: the thresholds every stage decides with (:class:`diagnosis.settings.Thresholds`)
    settings: Thresholds = field(default_factory=Thresholds)
    #: the rig parts of the records' set-up that the measured modes' set-up did not have
    #: (:meth:`diagnosis.setups.Setups.modes_lack`): effects modelling them are off in the modes' model
    modes_lack: frozenset[str] = frozenset()

    def __post_init__(self) -> None:
        if self.noise is None:
            object.__setattr__(self, "noise", NoiseModel.white(self.noise_std, len(self.records)))

    @cached_property
    def level_seen(self) -> bool:
        """Whether a common scale of EI, ρA, c and N (those among the unknowns) moves the modes at the config's
        nominal point (:func:`identification.start_modes.scale_moves_modes`, the records' start's criterion): it
        does where the config declares parts the scale leaves alone (a point mass, a spring, a fixed axial force)
        — the modes then see ρA, not only EI/ρA."""
        return scale_moves_modes(self, self.space.nominal)

    @property
    def has_prior(self) -> bool:
        """Whether a prior on the beam's unknowns is given (one term or more)."""
        return self.prior is not None and self.prior.count > 0

    # ----------------------------------------------------------- simulation
    def model(self, beta: np.ndarray, effect: Effect | None = None, s: np.ndarray | None = None
              ) -> AugmentedModel:
        """The augmented model of baseline unknowns ``beta`` and effect values ``s``."""
        cfg, params = self.space.apply(self.config, np.asarray(beta, dtype=float))
        if effect is None:
            return AugmentedModel(cfg, params)
        return effect.apply(cfg, params, np.asarray(s, dtype=float))

    def modes_model(self, beta: np.ndarray, effect: Effect | None = None, s: np.ndarray | None = None
                    ) -> AugmentedModel:
        """The model the measured modes are compared with: :meth:`model`, with the effect's parts that model a
        rig part the modes' set-up did not have (:attr:`modes_lack`) off."""
        if effect is None or not self.modes_lack:
            return self.model(beta, effect, s)
        members = effect.members or (effect,)
        z = np.asarray(s, dtype=float)
        kept, values, k = [], [], 0
        for e in members:
            if e.rig_part not in self.modes_lack:
                kept.append(e)
                values.append(z[k:k + e.dim])
            k += e.dim
        if len(kept) == len(members):
            return self.model(beta, effect, s)
        return self.model(beta, kept[0], values[0]) if kept else self.model(beta)

    def simulate(self, beta: np.ndarray, effect: Effect | None = None, s: np.ndarray | None = None, *,
                 until: str = "fit") -> list[np.ndarray | None]:
        """Simulated outputs per record, up to the end of the fit window (``"fit"``) or the record (``"all"``).

        Records without a fit window give ``None`` for ``until="fit"``.
        Raises :class:`ebb_model.errors.EbbError` subclasses for invalid models.
        """
        m = self.model(beta, effect, s)
        out: list[np.ndarray | None] = []
        for r in self.records:
            stop = r.fit_end if until == "fit" else r.n
            if stop == 0:
                out.append(None)
                continue
            out.append(simulate_effects(m.config, m.params, r.inputs[:stop], m.signals))
        return out

    @property
    def n_fit(self) -> int:
        """Number of fitted residuals (samples × sensors over all fit windows, one per measured mode and one per
        prior)."""
        n_prior = 0 if self.prior is None else self.prior.count
        n_modes = 0 if self.modes is None else self.modes.count
        return int(sum(r.fit_end for r in self.records) * len(self.config.sensors)) + n_modes + n_prior

    def residuals(self, beta: np.ndarray, effect: Effect | None = None, s: np.ndarray | None = None
                  ) -> np.ndarray:
        """Whitened residuals over the fit windows, stacked, then the measured modes' ``(f_model − f)/σ`` and the
        priors' ``(β − μ)/σ_p``."""
        try:
            with np.errstate(over="ignore", invalid="ignore"):   # an unstable candidate: penalised below
                sims = self.simulate(beta, effect, s, until="fit")
        except (EbbError, ValueError, np.linalg.LinAlgError):
            return penalised(None, self.n_fit)
        noise = self.noise_model
        with np.errstate(over="ignore", invalid="ignore"):   # a diverging candidate is penalised below
            parts = [noise.whiten(i, y - r.outputs[:r.fit_end]).ravel()
                     for i, (y, r) in enumerate(zip(sims, self.records)) if y is not None]
        if self.modes is not None:
            m = self.modes_model(beta, effect, s)
            parts.append(self.modes.residuals(m.config, m.params))
        if self.prior is not None and self.prior.count:
            parts.append(self.prior.residuals(beta))
        return penalised(np.concatenate(parts), self.n_fit)

    def heldout(self, beta: np.ndarray, effect: Effect | None = None, s: np.ndarray | None = None
                ) -> tuple[np.ndarray, list[np.ndarray]]:
        """Gap ratio per sensor on the held-out windows, and the held-out residuals per record.

        Returns
        -------
        ratio
            Mean square of the whitened residuals per sensor over every held-out sample (1 = noise floor).
        residuals
            Whitened held-out residuals ``(n_hold, n_sensors)`` per record with a held-out window (whitened
            from the record's start, so the filter has settled where the window begins).
        """
        sims = self.simulate(beta, effect, s, until="all")
        noise = self.noise_model
        res = [noise.whiten(i, y - r.outputs)[r.hold_start:]
               for i, (y, r) in enumerate(zip(sims, self.records)) if r.has_holdout]
        if not res:
            raise ValueError("no held-out samples")
        stacked = np.concatenate(res)
        return np.mean(stacked ** 2, axis=0), res

    @property
    def noise_model(self) -> NoiseModel:
        """The noise model (:attr:`noise`, never ``None`` after construction)."""
        assert self.noise is not None      # set in __post_init__
        return self.noise

    def with_noise(self, noise: NoiseModel) -> GapProblem:
        """The same problem under the noise model ``noise`` (``noise_std``: its white-equivalent level per
        sensor, the median over the records)."""
        return replace(self, noise=noise, noise_std=np.median(noise.std, axis=0))

    # ------------------------------------------------------------------ fits
    def box(self, effect: Effect | None = None) -> Box:
        """Bounds of the baseline unknowns (and of ``effect``'s variables)."""
        lo, hi = np.asarray(self.space.lower, dtype=float), np.asarray(self.space.upper, dtype=float)
        if effect is None:
            return Box(lo, hi)
        return Box(np.concatenate([lo, effect.lower]), np.concatenate([hi, effect.upper]))

    def _stacked(self, z: np.ndarray, effect: Effect | None) -> np.ndarray:
        p = self.space.dim
        return self.residuals(z[:p], effect, z[p:] if effect is not None else None)

    def fit(self, beta0: np.ndarray, effect: Effect | None = None, s0: np.ndarray | None = None, *,
            max_evaluations: int = 300) -> Fit:
        """Bounded least-squares fit of the baseline unknowns (and the effect's variables) on the fit windows."""
        z0 = np.asarray(beta0, dtype=float)
        if effect is not None:
            z0 = np.concatenate([z0, np.asarray(s0 if s0 is not None else effect.off, dtype=float)])
        fit = fit_least_squares(lambda Z: np.array([self._stacked(z, effect) for z in Z]), z0, self.box(effect),
                                max_evaluations=max_evaluations)
        p = self.space.dim
        return Fit(fit.x[:p], fit.x[p:], fit.rss, int(fit.residuals.size), fit.jac, fit.residuals,
                   fit.n_evaluations)

    def fit_along_the_level(self, beta0: np.ndarray, effect: Effect | None = None, s0: np.ndarray | None = None, *,
                            max_evaluations: int = 300) -> Fit:
        """The fit in the beam's own coordinates (:mod:`identification.coordinates`: the level — EI, ρA, c and N
        scaled together — one of them), finished by :meth:`fit`: a lightly damped record's level valley is
        followed where a fit in the config's coordinates stops in it (the strip under a broadband force, refitted on
        finer numerics: 1.49 noise variances and ρA 1.3 % high in the config's coordinates, the floor in these).

        With ``effect`` (from its variables ``s0``), its variables proportional to the level
        (:attr:`Effect.scaled <diagnosis.effects.Effect.scaled>`: a mass, a stiffness) are fitted as their ratio
        to ρA, so that the level is the same one coordinate with the effect on (the strip's crack, refitted on the
        band-limited force: 6.2 noise variances with EI and ρA 7 % high in the config's coordinates, 0.80 and
        both within 0.2 % in these).
        """
        from identification.coordinates import BeamCoordinates

        sp = self.space
        p = sp.dim
        coords = BeamCoordinates.of(sp.names, np.asarray(sp.lower, float), np.asarray(sp.upper, float))
        b0 = np.clip(np.asarray(beta0, dtype=float), sp.lower, sp.upper)
        t0, box = coords.to_internal(b0), coords.box()
        if effect is None:
            first = fit_least_squares(lambda T: np.array([self.residuals(b) for b in coords.to_physical(T)]), t0,
                                      box, max_evaluations=max_evaluations)
            return self.fit(coords.to_physical(first.x), max_evaluations=max_evaluations)
        lo, hi = np.asarray(effect.lower, dtype=float), np.asarray(effect.upper, dtype=float)
        rho = sp.names.index("rhoA") if coords.active else None
        scaled = list(effect.scaled) if rho is not None else []

        def variables(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            b = coords.to_physical(t[:p])
            s = np.array(t[p:], dtype=float)
            if scaled:
                s[scaled] *= b[rho] / b0[rho]
            return b, np.clip(s, lo, hi)

        def residuals(t: np.ndarray) -> np.ndarray:
            b, s = variables(t)
            return self.residuals(b, effect, s)

        z0 = np.concatenate([t0, np.clip(np.asarray(s0 if s0 is not None else effect.off, dtype=float), lo, hi)])
        first = fit_least_squares(lambda T: np.array([residuals(t) for t in T]), z0,
                                  Box(np.concatenate([box.lower, lo]), np.concatenate([box.upper, hi])),
                                  max_evaluations=max_evaluations)
        b, s = variables(first.x)
        return self.fit(b, effect, s, max_evaluations=max_evaluations)

    def baseline_basins(self, beta0: np.ndarray, *, n_basins: int = 3, seed: int = 0, maxiter: int = 20,
                        popsize: int = 8) -> list[np.ndarray]:
        """Starts of the baseline unknowns in distinct basins, best first (differential evolution on the fit RSS).

        Lightly damped records have many local minima (resonances misaligned by
        one mode, or a parameter compensating an unmodelled effect at its
        bound); a short differential evolution seeded with ``beta0`` finds the
        basin that :meth:`fit` then polishes.  The best members of its final
        population that lie apart from each other (> 0.15 of the bounds in some
        unknown) are returned as further starts, up to ``n_basins`` in all.
        """
        box = self.box()

        def cost(beta: np.ndarray) -> float:
            r = self.residuals(beta)
            return float(r @ r)

        evo = evolve(cost, beta0, box, seed=seed, maxiter=maxiter, popsize=popsize)
        first = evo.x if evo.cost <= cost(box.from_unit(box.to_unit(beta0))) else beta0
        return distinct_members(evo, box, first, n_basins)

    def truncated(self, fraction: float) -> "GapProblem":
        """The same problem fitted on the first ``fraction`` of every fit window (held-out windows unchanged).

        A lightly damped record misaligns a resonance by whole cycles once its
        frequency is a few per cent off, and the output error then stops
        pointing towards the right frequency; on a short window the same
        frequency error costs a fraction of a cycle, so the cost is smoother.
        """
        if not 0.0 < fraction <= 1.0:
            raise ValueError(f"fraction must lie in (0, 1], got {fraction!r}")
        return replace(self, records=tuple(replace(r, fit_end=max(1, int(r.fit_end * fraction))) if r.has_fit
                                           else r for r in self.records))

    def global_search(self, beta0: np.ndarray, effect: Effect, s0: np.ndarray, *, seed: int = 0,
                      maxiter: int = 20, popsize: int = 8) -> tuple[np.ndarray, np.ndarray, int]:
        """Differential evolution over the baseline unknowns and ``effect``'s variables together.

        Seeded with ``(beta0, s0)``; returns the best ``(beta, s)`` and the
        evaluations used.  Meant for a :meth:`truncated` problem, where it is
        cheap and the cost has few basins.
        """
        def cost(z: np.ndarray) -> float:
            r = self._stacked(z, effect)
            return float(r @ r)

        z0 = np.concatenate([np.asarray(beta0, float), np.asarray(s0, float)])
        evo = evolve(cost, z0, self.box(effect), seed=seed, maxiter=maxiter, popsize=popsize)
        p = self.space.dim
        return evo.x[:p], evo.x[p:], evo.n_evaluations

    def scaled_jacobian(self, beta: np.ndarray, effect: Effect, s: np.ndarray, *, step: float = 1e-3,
                        r0: np.ndarray | None = None) -> np.ndarray:
        """Forward-difference Jacobian of the residuals w.r.t. the effect's variables scaled by their bounds.

        Steps move away from the nearer bound, so one-sided effects are
        differentiated at their "off" value from the feasible side.
        """
        s = np.asarray(s, dtype=float)
        lo, hi = np.asarray(effect.lower), np.asarray(effect.upper)
        span = hi - lo
        if r0 is None:
            r0 = self.residuals(beta, effect, s)
        J = np.empty((r0.size, effect.dim))
        for j in range(effect.dim):
            ds = step * span[j]
            sign = 1.0 if s[j] + ds <= hi[j] else -1.0
            s1 = s.copy()
            s1[j] += sign * ds
            J[:, j] = (self.residuals(beta, effect, s1) - r0) / (sign * step)
        return J
