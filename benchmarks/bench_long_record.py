"""A long record identified with the defaults: 60 s sampled at 5 kHz (300,000 samples), three sensors.

The record comes from the repository's independent generator (:func:`ebb_model.reference.synthetic.synthesize`:
a Hermite FE beam integrated exactly in time; generated first, not timed) on the blind family's bench
(``tests/test_diagnosis_blind.py``: clamped–pinned, one force at 0.55 m, EI, ρA, c and N unknown, 60-node FD
model) with a third displacement sensor and the sample interval 2e-4 s; a 2–60 Hz multisine (modes 1–3), 1 %
noise.  :func:`identification.run.identify` then runs with the defaults of ``ebb identify`` (NSGA-II with its
population and generations, one process, the polish of the knee); its wall time from the call to its return —
reading the record, the Fisher check, the search, the bounds, the files it writes — is the figure (target
≤ 2 min), with the identified parameters' errors against the truth.

Run as ``python benchmarks/bench_long_record.py [--json PATH]``.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import test_diagnosis_blind as blind  # noqa: E402
from ebb_model.config import BeamConfig, config_from_dict  # noqa: E402
from ebb_model.reference.excitation import band_limited_input  # noqa: E402
from ebb_model.reference.synthetic import synthesize  # noqa: E402
from identification.run import identify  # noqa: E402

from figures import add_json_argument, write_figures  # noqa: E402  benchmarks/figures.py

SECONDS = 60.0
DT = 2e-4
N_SAMPLES = int(round(SECONDS / DT))
SENSORS = (("y1", 0.35), ("y2", 0.6), ("y3", 0.8))
F_MAX = 60.0


def long_config() -> BeamConfig:
    """The blind family's bench sampled at 5 kHz with three displacement sensors."""
    d = blind.bench_config().to_dict()
    d["time"]["dt"] = DT
    d["sensors"] = [{"name": n, "x": x, "kind": "displacement"} for n, x in SENSORS]
    return config_from_dict(d, extra_sections=("identification",))


def write_record(folder: Path, cfg: BeamConfig) -> Path:
    """The 60 s record from the independent generator (the family's truth, 1 % noise)."""
    u = band_limited_input(N_SAMPLES, DT, 2.0, F_MAX, seed=7)
    rec = synthesize(cfg, u, params=blind.TRUTH, noise=0.01, seed=107)
    path = folder / "long.npz"
    np.savez(path, time=rec.time, F1=rec.inputs[:, 0], **{name: rec.outputs[:, i] for i, (name, _) in
                                                          enumerate(SENSORS)})
    return path


def main() -> None:
    """Generate the record, identify with the defaults, print and write the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_json_argument(ap)
    args = ap.parse_args()
    cfg = long_config()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        path = write_record(Path(tmp), cfg)
        generated = time.perf_counter() - t0
        print(f"record: {SECONDS:g} s at {1 / DT:g} Hz ({N_SAMPLES} samples), {len(SENSORS)} sensors "
              f"(generated in {generated:.1f} s, not timed)")
        t0 = time.perf_counter()
        result = identify(cfg, [path], Path(tmp) / "out", progress=False)
        seconds = time.perf_counter() - t0
    errors = {k: 100.0 * (v / blind.TRUTH[k] - 1.0) for k, v in result.best.items()}
    print(f"identify with the defaults: {seconds:.1f} s (target <= 120 s)")
    print("errors against the truth [%]: " + ", ".join(f"{k} {e:+.3f}" for k, e in errors.items()))
    write_figures(args.json, {"seconds": seconds, "samples": N_SAMPLES, "sensors": len(SENSORS), "record_s": SECONDS,
                              "rate_hz": 1 / DT, "largest_error_percent": max(abs(e) for e in errors.values()),
                              "errors_percent": errors})


if __name__ == "__main__":
    main()
