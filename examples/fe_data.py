"""Synthetic "measured" data for the examples from an independent discretisation.

The identification fits the finite-difference model of :mod:`ebb_model`; fitting
data made by that same model would be an *inverse crime* (the model error is
zero by construction).  The examples therefore generate their data with the
cubic-Hermite finite-element beam and the Newmark average-acceleration scheme
of :mod:`ebb_model.reference.hermite_fe` (a different space *and* time
discretisation, run on a finer grid with sub-steps), then add white Gaussian
noise with a standard deviation proportional to each sensor's signal spread.

Used by ``seed_undamped.py`` and ``seed_two_sensors.py``; not a library module.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
from threadpoolctl import threadpool_limits

from ebb_model.config import BeamConfig
from ebb_model.reference import hermite_beam, newmark_simulate

__all__ = ["half_sine_pulse", "fe_measurements", "write_csv"]


def half_sine_pulse(n: int, dt: float, width: float, amplitude: float = 1.0) -> np.ndarray:
    """A half-sine force pulse of ``width`` seconds at the start of an ``n``-sample record (N)."""
    t = np.arange(n) * dt
    return np.where(t < width, amplitude * np.sin(np.pi * t / width), 0.0)


def fe_measurements(config: BeamConfig, truth: Mapping[str, float], u: np.ndarray, *, n_elements: int = 60,
                    substeps: int = 8, noise: Sequence[float] | float = 0.0, seed: int = 0) -> np.ndarray:
    """Sensor signals of the Hermite-FE/Newmark beam with the ``truth`` parameters, plus noise.

    Parameters
    ----------
    config
        Set-up (length, ends, actuators, sensors, dt); its grid and θ are *not* used.
    truth
        Physical parameters ``EI, rhoA, c, eta, N`` of the data-generating beam.
    u
        Forces, shape (n_samples, n_actuators).
    n_elements, substeps
        FE mesh and Newmark sub-steps per sample (fine enough that the data's
        discretisation error is far below the noise).
    noise
        Noise standard deviation per sensor as a fraction of that sensor's
        standard deviation (one number for all sensors, or one per sensor).
    seed
        Seed of the noise generator.

    Returns
    -------
    numpy.ndarray
        Measured outputs, shape (n_samples, n_sensors), in the config's sensor order.
    """
    b = config.beam
    beam = hermite_beam(b.length, n_elements, EI=truth["EI"], rhoA=truth["rhoA"], N=truth.get("N", 0.0),
                        c=truth.get("c", 0.0), eta=truth.get("eta", 0.0),
                        left=(b.left.kt, b.left.kr), right=(b.right.kt, b.right.kr),
                        point_masses=[(m.mass, m.x) for m in config.masses])
    y = newmark_simulate(beam, forces_x=[a.x for a in config.actuators],
                         sensors=[(s.x, s.kind) for s in config.sensors],
                         u=np.atleast_2d(np.asarray(u, float).T).T, dt=config.time.dt, substeps=substeps)
    rel = np.broadcast_to(np.asarray(noise, dtype=float), (y.shape[1],))
    rng = np.random.default_rng(seed)
    return y + rel * y.std(axis=0) * rng.standard_normal(y.shape)


def write_csv(path: str | Path, dt: float, columns: Mapping[str, np.ndarray]) -> Path:
    """Write ``time`` plus the named columns as the CSV the identification reads."""
    cols = {k: np.asarray(v, dtype=float).reshape(-1) for k, v in columns.items()}
    n = len(next(iter(cols.values())))
    t = np.arange(n) * dt
    p = Path(path)
    np.savetxt(p, np.column_stack([t, *cols.values()]), delimiter=",", header=",".join(["time", *cols]),
               comments="", fmt="%.17g")
    return p


def example_main(doc: str, prefix: str, run_case: Callable[..., dict], report: Callable[[dict], str],
                 argv: Sequence[str] | None = None, *, data: Path | None = None) -> int:
    """The command line shared by the examples: parse, run ``run_case`` into an output directory, report.

    With ``data`` the example takes an optional positional data file (default
    ``data``) and ``run_case(data, out, ...)``; otherwise ``run_case(out, ...)``.
    Writes ``summary.json``; returns the exit code (2 when the data file is missing).
    """
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    if data is not None:
        ap.add_argument("data", nargs="?", type=Path, default=data, help=f"the record (default {data})")
    ap.add_argument("--quick", action="store_true", help="small population and record (for tests)")
    ap.add_argument("--out", type=Path, default=None, help="output directory (new or empty)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--pop", type=int, default=None)
    ap.add_argument("--generations", type=int, default=None)
    ap.add_argument("--export", action="store_true", help="also export every Pareto point (FMU, StateSpace)")
    args = ap.parse_args(argv)
    if data is not None and not args.data.is_file():
        print(f"error: data file {args.data} not found (the ARTS-Lab record is not part of the repository)",
              file=sys.stderr)
        return 2
    out = args.out or Path(tempfile.mkdtemp(prefix=f"ebb-{prefix}-"))
    out.mkdir(parents=True, exist_ok=True)
    kwargs = dict(quick=args.quick, seed=args.seed, pop=args.pop, generations=args.generations, export=args.export)
    with threadpool_limits(limits=1, user_api="blas"):
        summary = run_case(args.data, out, **kwargs) if data is not None else run_case(out, **kwargs)
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    print(report(summary))
    print(f"\nresults in {out}")
    return 0
