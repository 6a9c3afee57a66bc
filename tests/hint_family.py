"""A family of broadband records on which a sign, level or units hint is false: every force and sensor is read with
its true sign, in its true units, and the truth's parameters lie inside the newcomer's bounds.

Each bench is drawn from its index: one of four pairs of ends (every pair with every kind below, in turn by
the index's quarter: the first draw took both from the index's remainder, so every correct record was a
cantilever without axial load and every withheld effect clamped–pinned), no axial load, tension (0.5–4 Euler
loads) or compression (0.1–0.5), one to three sensors of random kinds and places, a shaker at a random place fed
noise to fs/2.56, to 0.2 fs or white to the Nyquist frequency (then displacement sensors only:
``tests/first_records.py``), 1–5 % noise, 2 s at 1 kHz, a config as a newcomer writes it (every unknown 30–60 % off,
bounds ×0.25…×4).  The record is one of four kinds, in turn: **correct** (the model's physics, the truth from the
independent FE generator), a **withheld effect** (a point mass, a crack, a compliant clamp, an intermediate spring —
what a diagnosis is for), an **undeclared delay** of the sensor channels (2–10 samples: a sigma-delta card's group
delay) or an **undeclared anti-alias filter** on the sensor channels (a 4th-order Butterworth at 0.3–0.45 fs).  The last
three are records the model does not describe, and where hints have claimed false things: an undeclared delay made
the records' start say "opposite in sign" and "the records' level asks for EI 49".

Read by ``tests/test_hint_rates.py`` (the rates) and ``benchmarks/bench_hint_rates.py`` (the printed hints of a
full default ``identify`` on the same family).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any
from pathlib import Path

import numpy as np
from scipy import signal

from ebb_model.reference import WithheldEffect, synthesize
from ebb_model.io.tomlio import dumps as dumps_toml

from first_records import FirstRecord

__all__ = ["KINDS", "HintBench", "first_draw", "hint_bench", "write_hint_case"]

#: What the record holds beyond the model, in turn by index.
KINDS = ("correct", "withheld effect", "undeclared delay", "undeclared filter")
ENDS = (("clamped", "free"), ("clamped", "pinned"), ("pinned", "pinned"), ("clamped", "clamped"))


@dataclass(frozen=True)
class HintBench:
    """One record of the family: the bench, what the record holds beyond the model, and how much."""

    bench: FirstRecord
    kind: str
    effect: WithheldEffect | None = None
    lag: int = 0                 # undeclared delay of every sensor channel [samples]
    filter_edge: float = 0.0     # undeclared low-pass on every sensor channel [fraction of fs]; 0: none

    @property
    def name(self) -> str:
        """Test id: the index, the kind and what it holds."""
        what = (self.effect.name if self.effect is not None else f"lag{self.lag}" if self.lag
                else f"lowpass{self.filter_edge:.2f}" if self.filter_edge else "")
        return f"{self.bench.name}-{self.kind.replace(' ', '_')}{'-' + what if what else ''}"


def _effect(rng: np.random.Generator, b: FirstRecord) -> WithheldEffect:
    """One withheld effect of a diagnosable size, drawn for bench ``b``."""
    L, EI, rhoA = b.length, b.truth["EI"], b.truth["rhoA"]
    which = int(rng.integers(4))
    if which == 0:
        return WithheldEffect("point_mass", {"mass": float(rng.uniform(0.05, 0.2)) * rhoA * L,
                                             "x": float(rng.uniform(0.2, 0.9)) * L})
    if which == 1:
        return WithheldEffect("stiffness_loss", {"x": float(rng.uniform(0.15, 0.85)) * L, "length": 0.04 * L,
                                                 "factor": float(rng.uniform(0.4, 0.7))})
    if which == 2:
        return WithheldEffect("boundary_rotational_left", {"kr": float(rng.uniform(5.0, 20.0)) * EI / L})
    return WithheldEffect("grounded_spring", {"k": float(rng.uniform(20.0, 100.0)) * EI / L ** 3,
                                              "x": float(rng.uniform(0.3, 0.7)) * L})


def hint_bench(i: int, elements: int = 64, ends: tuple[str, str] | None = None) -> HintBench:
    """The family's record ``i`` (module docstring); the same for the same ``i``.  ``ends``: the pair of ends, by
    default ``ENDS[(i // 4) % 4]``; the regression tests that name a record of the first draw pass the ends it had
    (``ENDS[i % 4]``, the only draw that differs).  ``elements``: the truth's
    finite elements — a hint on these records is false whatever the truth's convergence, and 64 make them fast; a
    correct record is within the noise of the model only with 128 (an accelerometer under noise to fs/2.56: two
    of 16 correct records left 1.75 noise variances at the identified model with 64, 1.0 with 128)."""
    rng = np.random.default_rng(1000 + i)
    left, right = ENDS[(i // 4) % 4] if ends is None else ends
    L = float(rng.uniform(0.5, 1.2))
    EI = float(np.exp(rng.uniform(np.log(3.0), np.log(20.0))))
    rhoA = float(np.exp(rng.uniform(np.log(0.5), np.log(2.0))))
    c = float(rng.uniform(0.3, 1.5))
    axial = ("none", "tension", "compression")[(i // 4) % 3] if right != "free" else "none"
    euler = EI * math.pi ** 2 / L ** 2
    N = {"none": 0.0, "tension": float(rng.uniform(0.5, 4.0)) * euler,
         "compression": -float(rng.uniform(0.1, 0.5)) * euler}[axial]
    excitation = ("broadband", "band20", "white")[(i // 12) % 3]
    n_sensors = 1 + i % 3
    kinds = (["displacement"] * n_sensors if excitation == "white"
             else [str(k) for k in rng.choice(["displacement", "velocity", "acceleration"], n_sensors)])
    places = sorted(rng.uniform(0.2, 0.95, n_sensors) * L)
    sensors = tuple((f"s{j + 1}", round(float(x), 3), k) for j, (x, k) in enumerate(zip(places, kinds)))

    def off() -> float:          # a newcomer's nominal value: 30–60 % off, either way
        return float(1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(0.3, 0.6))

    truth = {"EI": EI, "rhoA": rhoA, "c": c}
    guess = {"EI": off(), "rhoA": off(), "c": off()}
    if N != 0.0:
        truth["N"], guess["N"] = N, off()
    bench = FirstRecord(f"h{i}", left, right, L, truth, guess, round(float(rng.uniform(0.25, 0.9)) * L, 3), sensors,
                        "white" if excitation == "white" else "broadband", float(rng.uniform(0.01, 0.05)),
                        dt=1e-3, duration=2.0, band=0.2 if excitation == "band20" else 1.0 / 2.56, elements=elements)
    kind = KINDS[i % 4]
    if kind == "withheld effect":
        return HintBench(bench, kind, effect=_effect(rng, bench))
    if kind == "undeclared delay":
        return HintBench(bench, kind, lag=int(rng.integers(2, 11)))
    if kind == "undeclared filter":
        return HintBench(bench, kind, filter_edge=float(rng.uniform(0.3, 0.45)))
    return HintBench(bench, kind)


def first_draw(i: int, elements: int = 64) -> HintBench:
    """Record ``i`` as the family's first draw had it (its ends from ``i % 4``, as its kind): the records the
    regression tests name were found there."""
    return hint_bench(i, elements, ENDS[i % 4])


def write_hint_case(case: HintBench, folder: Path) -> tuple[Path, Path]:
    """The newcomer's ``config.toml`` and the record ``record.csv`` (what it holds beyond the model applied to the
    sensor channels after the truth's noise, as a DAQ would) in ``folder``."""
    b = case.bench
    folder.mkdir(parents=True, exist_ok=True)
    cfg_path = folder / "config.toml"
    cfg_path.write_text(dumps_toml(b.config_dict()), encoding="utf-8")
    rec = synthesize(b.truth_config(), b.force()[:, None], noise=b.noise, seed=11, interpolation=b.interpolation,
                     n_elements=b.elements, effect=case.effect)
    y = np.asarray(rec.outputs, float)
    if case.lag:
        y = np.vstack([np.zeros((case.lag, y.shape[1])), y[:-case.lag]])
    if case.filter_edge:
        sos = signal.butter(4, case.filter_edge, fs=1.0, output="sos")
        y = signal.sosfilt(sos, y, axis=0)
    data = np.column_stack([rec.time, rec.inputs, y])
    header = ",".join(["time", *rec.input_names, *rec.output_names])
    rec_path = folder / "record.csv"
    np.savetxt(rec_path, data, delimiter=",", header=header, comments="", fmt="%.12g")
    return cfg_path, rec_path


def diagnosed(case: HintBench, folder: Path) -> Any:
    """The default diagnosis (one process, no plots, no export) of record ``case`` written in ``folder``/bench,
    its outputs in ``folder``/gap: a :class:`diagnosis.run.Diagnosis`."""
    from diagnosis.run import diagnose

    cfg, rec = write_hint_case(case, folder / "bench")
    return diagnose(cfg, [rec], folder / "gap", plots=False, workers=1, export=False)
