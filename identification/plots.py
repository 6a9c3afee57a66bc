"""Report plots of an identification run (matplotlib, Agg backend, PNG files)."""
from __future__ import annotations

from itertools import combinations
from typing import Any

import numpy as np

from ebb_model.beam import PARAMETER_UNITS
from ebb_model.output import atomic_path

__all__ = ["plot_results"]


def _save(fig: Any, path: Any) -> None:
    """Write ``fig`` as a PNG to ``path`` atomically and close it."""
    import matplotlib.pyplot as plt

    try:
        with atomic_path(path, suffix=".png") as tmp:
            fig.savefig(tmp, dpi=110)
    finally:
        plt.close(fig)


def _objective_label(name: str) -> str:
    return f"{name} [-]" if name.startswith("nrmse") or name == "growth_factor" else name


def _parameter_label(name: str) -> str:
    unit = PARAMETER_UNITS.get(name, "m" if name.startswith("x_") else "")
    return f"{name} [{unit}]" if unit else name


def plot_results(res: Any, evaluator: Any) -> list[str]:
    """Pareto front (every pair of objectives), measured vs simulated per sensor, parameter spread.

    Returns the file names.  Every axis carries its unit; the knee and the identified model (polished knee)
    are marked in every panel, with a legend.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = res.pareto
    out = res.out_dir
    files = []
    polished = getattr(res, "polished", ())
    f_pol = np.asarray(polished[0].objectives) if polished else None
    pairs = list(combinations(range(p.F.shape[1]), 2))
    if pairs:
        fig, axes = plt.subplots(1, len(pairs), figsize=(4.6 * len(pairs), 4), squeeze=False)
        for ax, (a, b) in zip(axes[0], pairs):
            ax.scatter(p.F[:, a], p.F[:, b], c="C0", s=18, label="Pareto set (GA)")
            ax.scatter(p.F[p.knee, a], p.F[p.knee, b], c="C3", marker="*", s=150, label="knee (not polished)")
            if f_pol is not None:
                ax.scatter(f_pol[a], f_pol[b], c="k", marker="x", s=80, label="identified (polished knee)")
            ax.set_xlabel(_objective_label(p.objective_names[a]))
            ax.set_ylabel(_objective_label(p.objective_names[b]))
        axes[0, 0].legend(fontsize=8)
        fig.suptitle("Pareto front" + (" (all pairs of objectives)" if len(pairs) > 1 else ""))
    else:
        fig, ax = plt.subplots(figsize=(5, 4))
        ax.plot(p.F[:, 0], "o", label="Pareto set (GA)")
        if f_pol is not None:
            ax.axhline(f_pol[0], color="k", ls="--", label="identified (polished knee)")
        ax.set_xlabel("point")
        ax.set_ylabel(_objective_label(p.objective_names[0]))
        ax.legend(fontsize=8)
        ax.set_title("Pareto front")
    fig.tight_layout()
    _save(fig, out / "pareto_front.png")
    files.append("pareto_front.png")

    sims = evaluator.simulate(p.X[p.knee]).outputs
    sims_pol = evaluator.simulate(polished[0].x).outputs if polished else ()
    if sims:
        e0 = evaluator.experiments[0]
        n_out = e0.outputs.shape[1]
        fig, axes = plt.subplots(n_out, 1, figsize=(8, 2.5 * n_out), squeeze=False)
        dt = evaluator.config.time.dt
        t = np.arange(e0.outputs.shape[0]) * dt
        for j, ax in enumerate(axes[:, 0]):
            sensor = evaluator.config.sensors[j]
            ax.plot(t, e0.outputs[:, j], lw=0.8, label="measured")
            ax.plot(t, sims[0][:, j], lw=0.8, label="simulated (knee, not polished)")
            if sims_pol:
                ax.plot(t, sims_pol[0][:, j], lw=0.8, ls="--", label="simulated (identified: polished knee)")
            ax.set_ylabel(f"{sensor.name} [{sensor.unit}]")
        axes[0, 0].legend(loc="upper right", fontsize=8)
        axes[-1, 0].set_xlabel("time [s]")
        fig.tight_layout()
        _save(fig, out / "knee_fit.png")
        files.append("knee_fit.png")

    fig, axes = plt.subplots(1, p.X.shape[1], figsize=(2.4 * p.X.shape[1], 3.2), squeeze=False)
    for j, ax in enumerate(axes[0]):
        ax.plot(np.zeros(len(p.X)), p.X[:, j], "o", alpha=0.5, label="Pareto set (GA)")
        ax.plot([0], [p.X[p.knee, j]], "r*", ms=12, label="knee (not polished)")
        if polished:
            ax.plot([0], [polished[0].x[j]], "kx", ms=10, label="identified (polished knee)")
        ax.set_ylabel(_parameter_label(p.parameter_names[j]))
        ax.set_xticks([])
    axes[0, 0].legend(fontsize=7, loc="best")
    fig.tight_layout()
    _save(fig, out / "parameter_spread.png")
    files.append("parameter_spread.png")
    return files
