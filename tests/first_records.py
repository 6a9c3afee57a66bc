"""A blind family of "first own records": benches and configs as a new user makes and writes them.

Each case is a bench (ends, length, sensors of one or mixed kinds, a shaker or a hammer, the excitation, the
noise) whose record comes from the independent truth (:func:`ebb_model.reference.synthesize`: cubic Hermite
finite elements integrated exactly in time under the spline force — no code shared with the identified model),
and a config as a newcomer writes it: every nominal value 30–60 % off the truth, bounds ×0.25…×4 around the
nominal, the grid of the examples.  The identification sees the config and the record only.

Read by ``tests/test_first_records.py`` (the accuracy) and ``benchmarks/bench_first_records.py`` (the time).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import signal

from ebb_model.config import BeamConfig, config_from_dict
from ebb_model.reference import band_limited_input, synthesize
from ebb_model.reference.synthetic import WithheldEffect
from ebb_model.io.tomlio import dumps as dumps_toml

__all__ = ["BROADBAND", "CASES", "DECLARED", "FirstRecord", "write_case"]


@dataclass(frozen=True)
class FirstRecord:
    """One bench of the family.

    Attributes
    ----------
    name
        Short name (test id).
    left, right, length
        The beam's ends and free length [m].
    truth
        EI [N m²], ρA [kg/m], c [N s/m²], N [N] of the truth.
    guess
        The newcomer's nominal value per unknown, as a factor of the truth (0.4–0.7 or 1.3–1.6).
    actuator
        Shaker or hammer position [m].
    sensors
        ``(name, x, kind)`` per sensor.
    excitation
        ``random`` (filtered white noise), ``chirp``, ``multisine`` (band 1 Hz to a tenth of the sampling rate: a
        lab samples well above its band), ``hammer`` (a 10 ms sin² blow), and what a modal test feeds a shaker:
        ``broadband`` (white noise through an 8th-order low-pass at fs/2.56) or ``white`` (to the Nyquist
        frequency).
    noise
        Noise std relative to each sensor's clean RMS.
    dt, duration
        Sample time and record length [s].
    band
        A ``broadband`` force's band edge as a fraction of the sampling rate (the modal-test convention 1/2.56).
    masses, springs
        Point masses ``(name, x, kg)`` and springs ``(name, x, N/m)`` on the beam, declared in the config as the
        newcomer knows them (an accelerometer on its clamp block, a support): parts a common scale of EI, ρA, c
        and N leaves alone, so the records' level moves their modes.
    elements
        The truth's finite elements: 64 suffice for a force within a tenth of the sampling rate; a broadband force
        through an accelerometer needs 128 (the strip: 64 elements 0.46 noise variances off 256, 128 0.004; the
        demo beam under white noise 0.18 and 0.007), the clamped beam in tension with three sensors 256: its 128
        elements were 546 noise variances off 256 over the accelerometer's record (321 the velocity sensor's; 256
        elements 2.1 and 1.3 off 512) — enough for a weak segment 0.1 m from the clamp to take up half the posterior
        probability of a record without an effect.  Summed over the record, 128 → 256 → 512 elements move the
        strip's 10.4 → 0.35, the pinned beam's accelerometer 67 → 0.27, the demo beam's 11.8 → 0.05.
    """

    name: str
    left: str
    right: str
    length: float
    truth: dict[str, float]
    guess: dict[str, float]
    actuator: float
    sensors: tuple[tuple[str, float, str], ...]
    excitation: str
    noise: float
    dt: float = 1e-3
    duration: float = 4.0
    band: float = 1.0 / 2.56
    elements: int = 64
    masses: tuple[tuple[str, float, float], ...] = ()
    springs: tuple[tuple[str, float, float], ...] = ()

    @property
    def interpolation(self) -> str:
        """The truth's force between samples: band-limited for what a shaker is fed through a DAQ (broadband,
        white), the spline otherwise."""
        return "bandlimited" if self.excitation in ("broadband", "white") else "cubic"

    @property
    def unknowns(self) -> tuple[str, ...]:
        """What the config identifies: EI, ρA and c, and N on an axially loaded beam."""
        return ("EI", "rhoA", "c", "N") if self.truth.get("N", 0.0) != 0.0 else ("EI", "rhoA", "c")

    @property
    def euler_load(self) -> float:
        """The Euler load scale ``EI π²/L²`` [N] (the yardstick of N's error)."""
        return self.truth["EI"] * math.pi ** 2 / self.length ** 2

    def config_dict(self, nodes: int = 80) -> dict[str, Any]:
        """The newcomer's config (module docstring)."""
        params: dict[str, Any] = {}
        for k in ("EI", "rhoA", "c", "eta", "N"):
            true = self.truth.get(k, 0.0)
            if k in self.unknowns:
                v = true * self.guess[k]
                lo, hi = sorted((0.25 * v, 4.0 * v))
                if k == "N":      # a load of either sign may be bounded across zero by a cautious user
                    lo, hi = -4.0 * abs(v), 4.0 * abs(v)
                params[k] = {"value": v, "bounds": [lo, hi], "identify": True}
            else:
                params[k] = {"value": true}
        out = {"beam": {"length": self.length, "nodes": nodes, "left": self.left, "right": self.right},
               "time": {"dt": self.dt}, "parameters": params,
               "actuators": [{"name": "F1", "x": self.actuator}],
               "sensors": [{"name": n, "x": x, "kind": k} for n, x, k in self.sensors]}
        if self.masses:
            out["masses"] = [{"name": n, "x": x, "mass": m} for n, x, m in self.masses]
        if self.springs:
            out["springs"] = [{"name": n, "x": x, "k": k} for n, x, k in self.springs]
        return out

    def truth_config(self) -> BeamConfig:
        """The bench with the truth's values (what the generator reads)."""
        d = self.config_dict()
        for k, v in self.truth.items():
            d["parameters"][k] = {"value": v}
        return config_from_dict(d)

    def force(self) -> np.ndarray:
        """The excitation [N], from rest (module docstring of the case kinds)."""
        n = int(round(self.duration / self.dt))
        fs = 1.0 / self.dt
        if self.excitation == "hammer":
            u = np.zeros(n)
            width = 10e-3
            t = np.arange(n) * self.dt - 0.05
            inside = (t >= 0) & (t <= width)
            u[inside] = 50.0 * np.sin(np.pi * t[inside] / width) ** 2     # smooth: a blow has no kinks
            return u
        if self.excitation == "random":
            rng = np.random.default_rng(7)
            b, a = signal.butter(8, 0.1 * fs, fs=fs)
            u = signal.lfilter(b, a, rng.standard_normal(n))
            ramp = np.minimum(1.0, np.arange(n) / (0.05 * n))
            return u * ramp / np.std(u)
        if self.excitation in ("broadband", "white"):
            # white to the Nyquist frequency, or to fs/2.56 through an 8th-order low-pass; faded in and out (raised
            # cosine over 5 %): the shaker recorded from before it starts to after it stops, a band-limited force
            u = np.random.default_rng(7).standard_normal(n)
            if self.excitation == "broadband":
                u = signal.sosfiltfilt(signal.butter(8, self.band * fs, fs=fs, output="sos"), u)
            k = max(2, n // 20)
            fade = 0.5 - 0.5 * np.cos(np.pi * np.arange(k) / k)
            u[:k] *= fade
            u[-k:] *= fade[::-1]
            return u / np.std(u)
        return band_limited_input(n, self.dt, 1.0, 0.1 * fs, kind=self.excitation, seed=3)[:, 0]


def write_case(case: FirstRecord, folder: Path, effect: WithheldEffect | None = None) -> tuple[Path, Path]:
    """The newcomer's ``config.toml`` and the truth's ``record.csv`` in ``folder`` (with ``effect`` in the truth
    and not in the config, when given)."""
    folder.mkdir(parents=True, exist_ok=True)
    cfg_path = folder / "config.toml"
    cfg_path.write_text(dumps_toml(case.config_dict()), encoding="utf-8")
    u = case.force()
    rec = synthesize(case.truth_config(), u[:, None], noise=case.noise, seed=11, interpolation=case.interpolation,
                     n_elements=case.elements, effect=effect)
    data = np.column_stack([rec.time, rec.inputs, rec.outputs])
    header = ",".join(["time", *rec.input_names, *rec.output_names])
    rec_path = folder / "record.csv"
    np.savetxt(rec_path, data, delimiter=",", header=header, comments="", fmt="%.12g")
    return cfg_path, rec_path


def _g(ei: float, rho: float, c: float, n: float | None = None) -> dict[str, float]:
    out = {"EI": ei, "rhoA": rho, "c": c}
    if n is not None:
        out["N"] = n
    return out


#: The family: every sensor kind alone and mixed, four pairs of ends, four excitations, 1–5 % noise.
CASES = (
    FirstRecord("cantilever-accel-random", "clamped", "free", 0.8, {"EI": 7.0, "rhoA": 0.9, "c": 0.6},
                _g(1.43, 1.33, 1.67), 0.6, (("a1", 0.8, "acceleration"),), "random", 0.02),
    FirstRecord("cantilever-velocity-chirp", "clamped", "free", 1.0, {"EI": 12.0, "rhoA": 1.5, "c": 1.2},
                _g(0.6, 1.5, 0.5), 0.7, (("v1", 0.95, "velocity"),), "chirp", 0.03),
    FirstRecord("cantilever-displacement-hammer", "clamped", "free", 0.6, {"EI": 4.0, "rhoA": 0.5, "c": 0.4},
                _g(1.55, 0.65, 1.4), 0.55, (("d1", 0.6, "displacement"),), "hammer", 0.01, dt=5e-4),
    FirstRecord("pinned-tension-mixed-multisine", "pinned", "pinned", 1.2,
                {"EI": 15.0, "rhoA": 1.2, "c": 0.8, "N": 60.0}, _g(0.65, 1.4, 1.5, 0.6), 0.37,
                (("d1", 0.5, "displacement"), ("a1", 0.8, "acceleration")), "multisine", 0.02),
    FirstRecord("clamped-compression-mixed-random", "clamped", "clamped", 1.0,
                {"EI": 10.0, "rhoA": 1.0, "c": 0.5, "N": -80.0}, _g(1.4, 0.6, 0.6, 1.5), 0.3,
                (("v1", 0.45, "velocity"), ("a1", 0.7, "acceleration")), "random", 0.02),
    FirstRecord("clamped-pinned-accel-hammer", "clamped", "pinned", 0.9, {"EI": 9.0, "rhoA": 1.1, "c": 0.9},
                _g(0.55, 1.35, 1.6), 0.4, (("a1", 0.6, "acceleration"),), "hammer", 0.02, dt=5e-4),
    FirstRecord("pinned-tension-velocity-chirp", "pinned", "pinned", 1.0,
                {"EI": 8.0, "rhoA": 0.8, "c": 0.6, "N": 40.0}, _g(1.5, 0.7, 0.5, 1.4), 0.23,
                (("v1", 0.61, "velocity"),), "chirp", 0.05),
    FirstRecord("clamped-compression-displacement-multisine", "clamped", "clamped", 1.1,
                {"EI": 20.0, "rhoA": 2.0, "c": 1.5, "N": -50.0}, _g(0.7, 1.6, 1.45, 0.55), 0.33,
                (("d1", 0.55, "displacement"),), "multisine", 0.01),
    FirstRecord("cantilever-mixed-chirp", "clamped", "free", 0.75, {"EI": 5.0, "rhoA": 0.7, "c": 0.5},
                _g(1.6, 0.6, 1.3), 0.65, (("d1", 0.4, "displacement"), ("a1", 0.75, "acceleration")), "chirp",
                0.04),
)


#: What labs record most: a shaker fed broadband random noise, one to three sensors (the broadband issue's benches):
#: the demo's clamped–pinned beam with two displacement sensors and a white force, 10 s at 2 kHz; a steel strip
#: clamped–free with one tip accelerometer (its first mode 40 dB below its fifth there), random to fs/2.56; a
#: compressed pinned–pinned beam read by a velocity sensor and an accelerometer, random to 0.2 fs; a clamped–clamped
#: beam in tension with a sensor of every kind, random to fs/2.56.  White noise to the Nyquist frequency is read by
#: displacement sensors only: between 0.4 and 0.5 of the sampling rate a force is not determined by its samples to
#: the noise of a velocity or acceleration sensor (that beam under white noise at the truth, on 323 nodes with the
#: band-limited force: 55 and 167 noise variances; the demo beam's displacement sensors: 0.07 and 0.03).
BROADBAND = (
    FirstRecord("demo-beam-white-displacement", "clamped", "pinned", 1.0,
                {"EI": 10.0, "rhoA": 1.0, "c": 2.0, "N": 20.0}, _g(1.2, 1.2, 0.5, 1.5), 0.55,
                (("y1", 0.35, "displacement"), ("y2", 0.8, "displacement")), "white", 0.01, dt=5e-4, duration=10.0,
                elements=128),
    FirstRecord("strip-cantilever-tip-accelerometer", "clamped", "free", 0.6,
                {"EI": 210e9 * 0.04 * 0.004 ** 3 / 12, "rhoA": 7850 * 0.04 * 0.004, "c": 0.5}, _g(0.6, 1.4, 1.5), 0.5,
                (("a1", 0.6, "acceleration"),), "broadband", 0.01, dt=5e-4, duration=3.0, elements=128),
    FirstRecord("pinned-compression-velocity-accel-band20", "pinned", "pinned", 1.0,
                {"EI": 12.0, "rhoA": 1.1, "c": 0.8, "N": -60.0}, _g(1.5, 0.65, 1.4, 0.6), 0.3,
                (("v1", 0.45, "velocity"), ("a1", 0.8, "acceleration")), "broadband", 0.02, dt=5e-4,
                duration=4.0, band=0.2, elements=128),
    FirstRecord("clamped-tension-three-sensors-broadband", "clamped", "clamped", 0.9,
                {"EI": 8.0, "rhoA": 0.8, "c": 1.0, "N": 50.0}, _g(0.6, 1.45, 0.6, 1.4), 0.35,
                (("d1", 0.3, "displacement"), ("v1", 0.5, "velocity"), ("a1", 0.7, "acceleration")), "broadband",
                0.02, dt=5e-4, duration=4.0, elements=256),
)


#: Benches with parts the newcomer declares (``masses``, ``springs``): an accelerometer on its clamp block at the
#: strip's tip (6 % of the strip's mass), a beam on a spring support with a sensor's mass.  A common scale of EI, ρA,
#: c and N moves their modes, so the start takes the records' level from the modes' pattern instead of their
#: amplitude where the pattern determines it (:mod:`identification.start_modes`; from the amplitude alone the
#: strip's start was 2.4 times the truth and the run ended at 4,657 noise variances).
DECLARED = (
    FirstRecord("strip-tip-mass-accelerometer", "clamped", "free", 0.6,
                {"EI": 210e9 * 0.04 * 0.004 ** 3 / 12, "rhoA": 7850 * 0.04 * 0.004, "c": 0.5}, _g(0.6, 1.4, 1.5), 0.5,
                (("a1", 0.6, "acceleration"),), "broadband", 0.01, dt=5e-4, duration=3.0, elements=128,
                masses=(("accelerometer", 0.6, 0.045),)),
    FirstRecord("cantilever-spring-support-velocity", "clamped", "free", 1.0, {"EI": 10.0, "rhoA": 1.0, "c": 0.8},
                _g(1.5, 0.6, 1.4), 0.9, (("v1", 0.7, "velocity"),), "broadband", 0.02, dt=5e-4, duration=4.0,
                band=0.3, elements=128, masses=(("sensor", 0.7, 0.03),), springs=(("support", 0.45, 300.0),)),
)
