"""The experiments a bench can make next (:func:`bench_designs`) and one design's simulations (:class:`DesignBench`).

A design is what a user changes on the bench for one more record: the band the exciter drives (a band-limited
random force at each actuator, as strong as the records' measured force), one more sensor of a kind already on
the bench at a position along the beam, and the set-up (as recorded, or without a rig part that a leading
candidate models — a shaker's armature is tested by exciting the bare beam at the same point, a hammer's route).
The bands on offer: the records' own band, broadband up to the bench's top (``[diagnosis] design_top_hz``; by
default 0.4 of the sampling rate, below an anti-alias filter's edge) and a narrow band around each of the
baseline's first modes there.  The sensor positions: ten, evenly along the beam.

All added positions are simulated in one model run (a config with every candidate sensor appended), so a design
is a choice of columns: the cost is one run per candidate, band and set-up, plus its Jacobian.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ebb_model.beam import Sensor
from ebb_model.errors import EbbError
from ebb_model.reference.excitation import band_limited_input

from ..effects import Effect
from ..problem.augmented import simulate_effects
from ..problem.fitting import GapProblem
from ..problem.records import Record

__all__ = ["Design", "DesignBench", "bench_designs", "SENSOR_POSITIONS", "DESIGN_SAMPLES"]

#: Positions offered for an added sensor, as fractions of the beam's length.
SENSOR_POSITIONS = tuple(0.05 + 0.1 * i for i in range(10))
#: Largest design record simulated [samples]; a longer record's figures scale with its duration.
DESIGN_SAMPLES = 8192
#: The baseline's modes (below the bench's top) each given a narrow band of their own.
MODE_BANDS = 6
#: Half-width of a mode's band, relative to its frequency.
MODE_BAND_WIDTH = 0.15


@dataclass(frozen=True)
class Design:
    """One experiment: the set-up, the band driven and the sensor added (``None``: the records' sensors)."""

    setup: str                              # "as recorded" or "without <rig part>"
    band_hz: tuple[float, float]
    band_name: str                          # "the records' band", "broadband", "around mode 2"
    sensor: tuple[str, float] | None        # (kind, position [m]) of the added sensor

    def describe(self) -> str:
        """One phrase."""
        where = ("the records' sensors" if self.sensor is None
                 else f"the records' sensors and {'an' if self.sensor[0][0] in 'aeiou' else 'a'} {self.sensor[0]} "
                      f"sensor at x = {self.sensor[1]:.3g} m")
        lo, hi = self.band_hz
        return f"{self.setup}: random force over {lo:.3g}-{hi:.3g} Hz ({self.band_name}), {where}"

    def to_dict(self) -> dict[str, Any]:
        """JSON values."""
        return {"setup": self.setup, "band_hz": list(self.band_hz), "band": self.band_name,
                "added_sensor": None if self.sensor is None else {"kind": self.sensor[0], "x": self.sensor[1]}}


def _samples(problem: GapProblem) -> int:
    """Samples of the design record: the longest fit window, at most :data:`DESIGN_SAMPLES`."""
    return min(DESIGN_SAMPLES, max(r.fit_end for r in problem.records if r.has_fit))


def _added_sensors(problem: GapProblem) -> list[tuple[str, float]]:
    """The sensors on offer: one of each kind on the bench at each of :data:`SENSOR_POSITIONS`."""
    kinds = sorted({s.kind for s in problem.config.sensors})
    return [(k, round(p * problem.config.beam.length, 12)) for k in kinds for p in SENSOR_POSITIONS]


def _bands(problem: GapProblem, band: tuple[float, float], mode_hz: np.ndarray, top: float
           ) -> list[tuple[str, tuple[float, float]]]:
    """The bands on offer (module docstring), each within ``[lowest, top]``."""
    lowest = 2.0 / (_samples(problem) * problem.config.time.dt)         # two periods in the design record
    out = [("the records' band", (max(band[0], lowest), min(band[1], top)))]
    out.append(("broadband", (lowest, top)))
    for i, f in enumerate(np.asarray(mode_hz)[:MODE_BANDS]):
        if f * (1 + MODE_BAND_WIDTH) <= top and f * (1 - MODE_BAND_WIDTH) > lowest:
            out.append((f"around mode {i + 1}", (f * (1 - MODE_BAND_WIDTH), f * (1 + MODE_BAND_WIDTH))))
    # a band needs a few lines of the design record's spectrum (a short record cannot drive a narrow band)
    return [(name, b) for name, b in out if b[1] - b[0] >= 2.0 * lowest]


def bench_designs(problem: GapProblem, band: tuple[float, float], mode_hz: np.ndarray, setups: tuple[str, ...],
                  top_hz: float) -> list[Design]:
    """Every design on offer (module docstring): set-ups × bands × (no sensor added, or one of each kind on the
    bench at each of :data:`SENSOR_POSITIONS`).  ``top_hz`` 0: 0.4 of the sampling rate."""
    top = top_hz if top_hz > 0 else 0.4 / problem.config.time.dt
    sensors: list[tuple[str, float] | None] = [None, *_added_sensors(problem)]
    return [Design(setup, b, name, s) for setup in setups for name, b in _bands(problem, band, mode_hz, top)
            for s in sensors]


@dataclass(frozen=True, eq=False)
class DesignBench:
    """The bench of one set-up and band, every added sensor on it at once: simulates a candidate's whitened
    outputs and their Jacobian on the design record.

    ``columns(sensor)`` picks a design's outputs: the records' sensors, plus the added one.
    """

    problem: GapProblem                  # the design record, every added sensor appended, no priors or modes
    n_record_sensors: int
    added: tuple[tuple[str, float], ...]

    @classmethod
    def build(cls, problem: GapProblem, band: tuple[float, float], lack: frozenset[str], seed: int = 0
              ) -> "DesignBench":
        """The design record for ``band`` (the records' force RMS per actuator) with the rig parts ``lack`` off."""
        cfg = problem.config
        kinds = sorted({s.kind for s in cfg.sensors})
        added = tuple(_added_sensors(problem))
        sigma = np.asarray(problem.noise_std, dtype=float)
        first = {k: float(sigma[[s.kind for s in cfg.sensors].index(k)]) for k in kinds}
        extra = tuple(Sensor(f"design_{k}_{i}", x, k) for i, (k, x) in enumerate(added))
        dcfg = replace(cfg, sensors=cfg.sensors + extra)
        n = _samples(problem)
        fit = [r.inputs[:r.fit_end] for r in problem.records if r.has_fit]
        rms = np.sqrt(np.mean(np.concatenate(fit) ** 2, axis=0))
        u = band_limited_input(n, cfg.time.dt, band[0], band[1], n_inputs=len(cfg.actuators), seed=seed)
        u = u * np.where(rms > 0, rms, 1.0)
        record = Record("design", u, np.zeros((n, len(dcfg.sensors))), n, n)
        dsigma = np.concatenate([sigma, [first[k] for k, _ in added]])
        dp = replace(problem, config=dcfg, records=(record,), noise_std=dsigma, noise=None, prior=None,
                     modes=None, other_starts=(), modes_lack=lack)
        return cls(dp, len(cfg.sensors), added)

    @property
    def duration(self) -> float:
        """The design record's duration [s]."""
        return self.problem.records[0].n * self.problem.config.time.dt

    def outputs(self, z: np.ndarray, effect: Effect | None) -> np.ndarray | None:
        """Whitened outputs ``(n, sensors)`` of the model of unknowns and effect values ``z`` (``None``: refused)."""
        p = self.problem.space.dim
        try:
            m = self.problem.modes_model(z[:p], effect, z[p:] if effect is not None else None)
            y = simulate_effects(m.config, m.params, self.problem.records[0].inputs, m.signals)
        except (EbbError, ValueError, np.linalg.LinAlgError):
            return None
        y = y / self.problem.noise_std
        return y if np.all(np.isfinite(y)) else None

    def jacobian(self, z: np.ndarray, effect: Effect | None, y0: np.ndarray, step: float = 1e-3) -> np.ndarray:
        """Forward differences of :meth:`outputs` in the unit box ``(n, sensors, unknowns)``; a step the model
        refuses leaves its column zero.  Steps move away from the nearer bound."""
        box = self.problem.box(effect)
        u0 = box.to_unit(z)
        J = np.zeros(y0.shape + (z.size,))
        for j in range(z.size):
            u1 = u0.copy()
            u1[j] += step if u0[j] + step <= 1.0 else -step
            y1 = self.outputs(box.from_unit(u1), effect)
            if y1 is not None:
                J[..., j] = (y1 - y0) / (u1[j] - u0[j])
        return J

    def columns(self, sensor: tuple[str, float] | None) -> list[int]:
        """Output columns of a design: the records' sensors and, with ``sensor``, the added one."""
        cols = list(range(self.n_record_sensors))
        if sensor is not None:
            cols.append(self.n_record_sensors + self.added.index(sensor))
        return cols
