"""The seed's simulation case: clamped–clamped undamped beam under tension.

Builds the discrete state space, lists modes and stability, simulates the
bundled force pulse and compares the first natural frequency with the
analytic value of the axially loaded beam.

Run: ``python examples/seed_simulation.py``
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

import ebb_model as em
from ebb_model.reference import analytic_frequencies_hz

HERE = Path(__file__).resolve().parent


def main() -> None:
    cfg = em.load_config(HERE / "seed_clamped.toml")
    p = cfg.parameter_values()
    sys = em.assemble(cfg)
    print(sys)
    m = em.modes(cfg, n_modes=5)
    exact = analytic_frequencies_hz("clamped", "clamped", length=cfg.beam.length, EI=p["EI"],
                                    rhoA=p["rhoA"], N=p["N"], n_modes=5)
    for i, (f, fe) in enumerate(zip(m.frequencies_hz, exact), start=1):
        print(f"mode {i}: FD {f:9.4f} Hz   analytic {fe:9.4f} Hz   error {100 * (f / fe - 1):+.3f} %")
    rep = em.analyse_stability(cfg)
    print(f"max growth factor {rep.max_growth_factor:.15f}, spectral radius {rep.spectral_radius:.15f}, "
          f"stable: {rep.stable}")
    data = np.genfromtxt(HERE / "seed_input.csv", delimiter=",", names=True)
    res = em.simulate(em.fast_model(cfg), data["F1"])
    print(f"peak |y1| = {np.max(np.abs(res.outputs[:, 0])):.3e} m, peak |y2| = "
          f"{np.max(np.abs(res.outputs[:, 1])):.3e} m over {res.time[-1]:.3f} s")


if __name__ == "__main__":
    main()
