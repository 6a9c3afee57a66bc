"""The identification's result as one typed value: what :func:`identification.run.identify` returns, what
``pareto.json`` holds (:meth:`IdentificationResult.to_dict`) and what export and diagnosis read back
(:meth:`IdentificationResult.read`).

The schema of ``pareto.json`` is written and read here only:

``config``, ``config_name``
    The identification config (``[identification]`` included) and the name of its file.
``identified``
    *The* identified model (:attr:`IdentificationResult.identified`).
``parameter_names``, ``objective_names``, ``knee``, ``generations``
    The unknowns, the objectives, the knee's index into ``points``, the GA's generations.
``n_evaluations``, ``n_evaluations_ga``, ``n_evaluations_polish``
    Model evaluations of the search (GA plus polish), and of each part.
``history``
    The GA's convergence per generation: ``evaluations`` so far and ``best``, each objective's best value in
    the generation's non-dominated set (:attr:`~identification.optimise.ParetoSet.history`).
``points``, ``polished``
    Every Pareto point and every polished point: parameters, objectives, Cramér–Rao standard deviations,
    growth factor and stability (polished points also their start, evaluations and the local solver's verdict).
``numerical_adequacy``
    The grid's share of the gap at the identified model (:class:`~ebb_model.space.adequacy.NumericalAdequacy`).
``noise_model``
    Each experiment's noise per sensor: level and colour (:mod:`identification.noise_model`).
``grid_advice``
    Which grid the records' band needs at the identified model (:func:`ebb_model.space.grid_advice.grid_advice`).
``events``
    What happened to the run's workers (a Dask worker lost mid-run and its tasks run again), one sentence each.
``data_start``
    What the records said before the search (:mod:`identification.data_start`): the start, the resonance
    peaks, the records' level, notes.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ebb_model.space.adequacy import NumericalAdequacy, ParameterShift
from ebb_model.config import BeamConfig, config_from_dict
from ebb_model.errors import ConfigError

from .fisher import FisherReport
from .fit_hints import bound_flags
from .noise_model import NoiseModel
from .prior import PriorCheck
from .optimise import ParetoSet
from .parameters import ParameterSpace, parameter_space
from .settings import CONFIG_SECTIONS

__all__ = ["CRB_GAP_LIMIT", "IdentificationResult", "PolishedPoint", "RESULT_FILE"]

#: The result's file in an ``identify`` output directory.
RESULT_FILE = "pareto.json"
#: Largest fit residual (in noise variances, per sensor) at which the Cramér–Rao bound is reported as valid: the
#: bound assumes the model explains the data up to the noise.
CRB_GAP_LIMIT = 2.0


@dataclass(frozen=True, eq=False)
class PolishedPoint:
    """A Pareto point after the local polish.

    Attributes
    ----------
    from_index
        Index of the Pareto point it started from (into ``pareto.X``).
    x, objectives
        Polished parameters and their objective values.
    cramer_rao_std
        Cramér–Rao standard deviations at ``x``.
    growth_factor, stable
        Stabilising objective and stability of the discrete beam at ``x``.
    n_evaluations
        Model evaluations of this polish (including its Jacobians and the
        final objective evaluation).
    cost, success, message
        Final sum of squared residuals (whitened by the noise model: χ² in noise variances; with a given
        white noise level: normalised per sensor) and ``least_squares``'s verdict.
    """

    from_index: int
    x: np.ndarray
    objectives: np.ndarray
    cramer_rao_std: np.ndarray
    growth_factor: float
    stable: bool
    n_evaluations: int
    cost: float
    success: bool
    message: str


@dataclass(frozen=True, eq=False, kw_only=True)
class IdentificationResult:
    """Outcome of :func:`identification.run.identify`, or of a finished run read back (:meth:`read`).

    Attributes
    ----------
    config, space
        The identification config and its unknowns (:func:`identification.parameters.parameter_space`).
    pareto
        The GA's non-dominated set.
    cramer_rao_std, growth_factors, stable
        Per Pareto point.
    out_dir
        Where the run wrote its files.
    config_name
        Name of the config (its file's stem; ``beam`` for a config given as a value): titles of exported models.
    polished
        The polished points, knee first.
    adequacy
        Numerical share of the gap at :attr:`best`.
    fisher_nominal
        Fisher information at the nominal point (``None`` for a result read back: ``identifiability.json``
        keeps its summary only).
    fit_gap_ratio
        The identified model's residual per sensor whitened by the noise model (1 = the noise floor, whatever
        the noise's colour); ``None``: the numerical adequacy's white gap stands for it.
    noise_model
        One line per experiment: each sensor's noise level and colour
        (:meth:`identification.noise_model.NoiseModel.describe`).
    noise
        The noise model itself, under which the Cramér–Rao bounds and ``fit_gap_ratio`` were computed
        (``None`` for a result read back).
    priors
        The identified model against the user's priors (:class:`identification.prior.PriorCheck`: what moved
        each parameter, and any conflict).
    modal_agreement
        The identified model against the config's measured modes
        (:meth:`identification.modal_data.ModalData.agreement`), when it gives them.
    data_start
        What the records said before the search (:meth:`identification.data_start.DataStart.to_dict`: the
        start, the resonance peaks, the records' level and any notes), ``None`` when nothing was read.
    hints
        What a simple transformation would supply to a fit far above the floor (:mod:`identification.fit_hints`),
        and the records' notes before the search that the fit bears out.
    cramer_rao_note
        Why the identified model's Cramér–Rao standard deviations cannot be computed, when they cannot.
    grid_advice
        Which grid the records' band needs at the identified model (:func:`ebb_model.space.grid_advice.grid_advice`,
        the advice ``diagnose`` gives too), with its one-line ``summary``.
    events
        What happened to the run's workers worth telling (a Dask worker lost mid-run), one sentence each.
    """

    config: BeamConfig
    space: ParameterSpace
    pareto: ParetoSet
    cramer_rao_std: np.ndarray
    growth_factors: np.ndarray
    stable: np.ndarray
    out_dir: Path
    config_name: str = "beam"
    polished: tuple[PolishedPoint, ...] = ()
    adequacy: NumericalAdequacy | None = None
    fisher_nominal: FisherReport | None = None
    fit_gap_ratio: Mapping[str, float] | None = None
    noise_model: tuple[str, ...] = ()
    noise: NoiseModel | None = None
    priors: tuple[PriorCheck, ...] = ()
    modal_agreement: Mapping[str, Any] | None = None
    data_start: Mapping[str, Any] | None = None
    hints: tuple[str, ...] = ()
    cramer_rao_note: str | None = None
    grid_advice: Mapping[str, Any] | None = None
    events: tuple[str, ...] = ()

    @property
    def knee(self) -> dict[str, float]:
        """Parameters of the knee point of the GA's front."""
        p = self.pareto
        return dict(zip(p.parameter_names, map(float, p.X[p.knee])))

    @property
    def best(self) -> dict[str, float]:
        """Parameters of the polished knee when polished, otherwise of the knee."""
        if not self.polished:
            return self.knee
        return dict(zip(self.pareto.parameter_names, map(float, self.polished[0].x)))

    @property
    def identified(self) -> dict[str, Any]:
        """*The* identified model: the polished knee (else the GA's knee, marked as not polished), its
        Cramér–Rao standard deviations and the fit quality they assume (``cramer_rao_valid``: the fit's residual
        is within :data:`CRB_GAP_LIMIT` noise variances of every sensor)."""
        names = self.pareto.parameter_names
        if self.polished:
            q = self.polished[0]
            origin = "the records' start" if q.from_index < 0 else f"Pareto point {q.from_index}"
            source, x, crb = f"polished, from {origin}", q.x, q.cramer_rao_std
        else:
            i = self.pareto.knee
            source, x, crb = f"knee of the GA front, Pareto point {i}, NOT polished", self.pareto.X[i], \
                self.cramer_rao_std[i]
        doc: dict[str, Any] = {"from": source, "polished": bool(self.polished),
                               "parameters": dict(zip(names, map(float, x))),
                               "cramer_rao_std": dict(zip(names, map(float, crb)))}
        gap = None
        if self.fit_gap_ratio is not None:
            gap = dict(self.fit_gap_ratio)
        elif self.adequacy is not None:
            gap = dict(zip(self.adequacy.sensors, map(float, self.adequacy.gap)))
        if gap is not None:
            doc["fit_gap_ratio"] = gap
            doc["cramer_rao_valid"] = bool(max(gap.values(), default=0.0) <= CRB_GAP_LIMIT)
        on = bound_flags(names, self.space.lower, self.space.upper, np.asarray(x, dtype=float))
        if on:
            doc["on_bounds"] = on
        if self.cramer_rao_note:
            doc["cramer_rao_note"] = self.cramer_rao_note
        if self.hints:
            doc["hints"] = list(self.hints)
        if self.priors:
            doc["priors"] = {c.name: c.to_dict() for c in self.priors}
        if self.modal_agreement is not None:
            doc["against_measured_modes"] = dict(self.modal_agreement)
        return doc

    @property
    def n_evaluations(self) -> int:
        """Model evaluations of the search: GA plus polish."""
        return int(self.pareto.n_evaluations + sum(q.n_evaluations for q in self.polished))

    def models(self, points: Sequence[int] = (), polished: Sequence[int] = ()
               ) -> list[tuple[str, BeamConfig, dict[str, float]]]:
        """``(stem, config, parameter values)`` of the chosen Pareto points (``point_<i>``) and polished points
        (``polished_<j>``), positions moved for identified positions."""
        chosen = [(f"point_{i}", self.pareto.X[i]) for i in points]
        chosen += [(f"polished_{j}", self.polished[j].x) for j in polished]
        out = []
        for stem, x in chosen:
            cfg, params = self.space.apply(self.config, x)
            out.append((stem, cfg, dict(params)))
        return out

    def to_dict(self) -> dict[str, Any]:
        """The ``pareto.json`` document (the module docstring gives its schema)."""
        p = self.pareto
        points = [{"index": i, "knee": i == p.knee, **self._point(x, f, self.cramer_rao_std[i],
                                                                   self.growth_factors[i], self.stable[i])}
                  for i, (x, f) in enumerate(zip(p.X, p.F))]
        polished = [{"index": j, "from_index": int(q.from_index),
                     **self._point(q.x, q.objectives, q.cramer_rao_std, q.growth_factor, q.stable),
                     "n_evaluations": int(q.n_evaluations), "cost": float(q.cost), "success": bool(q.success),
                     "message": q.message} for j, q in enumerate(self.polished)]
        n_polish = sum(q["n_evaluations"] for q in polished)
        return {
            "config": self.config.to_dict(),
            "config_name": self.config_name,
            "identified": self.identified,
            "parameter_names": list(p.parameter_names),
            "objective_names": list(p.objective_names),
            "knee": int(p.knee),
            "n_evaluations": int(p.n_evaluations + n_polish),
            "n_evaluations_ga": int(p.n_evaluations),
            "n_evaluations_polish": int(n_polish),
            "generations": int(p.generations),
            "history": {"evaluations": [int(v) for v in p.history[:, 0]] if p.history.size else [],
                        "best": p.history[:, 1:].tolist() if p.history.size else []},
            "points": points,
            "polished": polished,
            # at the reported point (the polished knee, else the knee): how much of its gap is the grid's
            "numerical_adequacy": self.adequacy.to_dict() if self.adequacy is not None else None,
            "noise_model": list(self.noise_model),
            "data_start": None if self.data_start is None else dict(self.data_start),
            "grid_advice": None if self.grid_advice is None else dict(self.grid_advice),
            "events": list(self.events),
        }

    def _point(self, x: np.ndarray, f: np.ndarray, crb: np.ndarray, growth: float, stable: bool
               ) -> dict[str, Any]:
        p = self.pareto
        return {"parameters": dict(zip(p.parameter_names, map(float, x))),
                "objectives": dict(zip(p.objective_names, map(float, f))),
                "cramer_rao_std": {k: float(v) for k, v in zip(p.parameter_names, crb)},
                "growth_factor": float(growth), "stable": bool(stable)}

    @classmethod
    def read(cls, result_dir: str | Path) -> IdentificationResult:
        """The finished run in ``result_dir`` (its ``pareto.json``).

        Raises
        ------
        ConfigError
            No ``pareto.json``, or one that is not a result of this tool (the message names the file and what
            is wrong).
        """
        d = Path(result_dir)
        path = d / RESULT_FILE
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ConfigError(f"{d}: no {RESULT_FILE} (run `ebb identify` first)") from None
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise ConfigError(f"{path}: unreadable identification result ({exc})") from None
        try:
            return cls._from_dict(doc, d)
        except ConfigError as exc:
            raise ConfigError(f"{path}: {exc}") from None
        except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
            raise ConfigError(f"{path}: unreadable identification result ({type(exc).__name__}: {exc})") from None

    @classmethod
    def _from_dict(cls, doc: Mapping[str, Any], out_dir: Path) -> IdentificationResult:
        cfg = config_from_dict(doc["config"], extra_sections=CONFIG_SECTIONS)
        space = parameter_space(cfg)
        names = tuple(doc["parameter_names"])
        if names != tuple(space.names):
            raise ConfigError(f"parameter_names {list(names)} are not the config's unknowns {list(space.names)}")
        objectives = tuple(doc.get("objective_names", ()))

        def vec(q: Mapping[str, Any], key: str, keys: Sequence[str]) -> np.ndarray:
            values = q.get(key) or {}
            return np.array([float(values.get(k, np.nan)) for k in keys], dtype=float).reshape(len(keys))

        pts = list(doc["points"])
        X = np.array([vec(q, "parameters", names) for q in pts]).reshape(len(pts), len(names))
        F = np.array([vec(q, "objectives", objectives) for q in pts]).reshape(len(pts), len(objectives))
        hist = doc.get("history") or {}
        history = np.column_stack([np.asarray(hist.get("evaluations", []), dtype=float),
                                   np.asarray(hist.get("best", []), dtype=float).reshape(-1, len(objectives))]) \
            if hist.get("evaluations") else np.empty((0, 0))
        pareto = ParetoSet(X, F, names, objectives, int(doc.get("knee", 0)),
                           int(doc.get("n_evaluations_ga", doc.get("n_evaluations", 0))),
                           int(doc.get("generations", 0)), history)
        polished = tuple(
            PolishedPoint(int(q.get("from_index", 0)), vec(q, "parameters", names), vec(q, "objectives", objectives),
                          vec(q, "cramer_rao_std", names), float(q.get("growth_factor", np.nan)),
                          bool(q.get("stable", True)), int(q.get("n_evaluations", 0)), float(q.get("cost", np.nan)),
                          bool(q.get("success", True)), str(q.get("message", "")))
            for q in doc.get("polished") or ())
        return cls(config=cfg, space=space, pareto=pareto,
                   cramer_rao_std=np.array([vec(q, "cramer_rao_std", names) for q in pts]),
                   growth_factors=np.array([float(q.get("growth_factor", np.nan)) for q in pts]),
                   stable=np.array([bool(q.get("stable", True)) for q in pts]), out_dir=out_dir,
                   config_name=str(doc.get("config_name") or out_dir.name), polished=polished,
                   adequacy=_adequacy(doc.get("numerical_adequacy")), fisher_nominal=None,
                   fit_gap_ratio=(doc.get("identified") or {}).get("fit_gap_ratio"),
                   noise_model=tuple(doc.get("noise_model") or ()), data_start=doc.get("data_start"),
                   hints=tuple((doc.get("identified") or {}).get("hints") or ()),
                   cramer_rao_note=(doc.get("identified") or {}).get("cramer_rao_note"),
                   grid_advice=doc.get("grid_advice"), events=tuple(doc.get("events") or ()))


def _adequacy(doc: Mapping[str, Any] | None) -> NumericalAdequacy | None:
    """:class:`NumericalAdequacy` from its :meth:`~NumericalAdequacy.to_dict`."""
    if not doc:
        return None
    sensors = tuple(doc["sensors"])
    per = doc["sensors"]
    return NumericalAdequacy(sensors, np.array([float(per[s]["gap_ratio"]) for s in sensors]),
                             np.array([float(per[s]["gap_ratio_refined"]) for s in sensors]),
                             np.array([float(per[s]["change"]) for s in sensors]), int(doc["refined_nodes"]),
                             ParameterShift.from_dict(doc["parameter_shift"]) if doc.get("parameter_shift") else None)
