"""Report plots of an identification run (matplotlib, Agg backend, PNG files)."""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["plot_results"]


def plot_results(res: Any, evaluator: Any) -> list[str]:
    """Pareto front, measured vs simulated per sensor at the knee, parameter spread. Returns file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = res.pareto
    out = res.out_dir
    files = []
    fig, ax = plt.subplots(figsize=(5, 4))
    if p.F.shape[1] >= 2:
        ax.scatter(p.F[:, 0], p.F[:, 1], c="C0", label="Pareto set")
        ax.scatter(p.F[p.knee, 0], p.F[p.knee, 1], c="C3", marker="*", s=150, label="knee")
        ax.set_xlabel(p.objective_names[0])
        ax.set_ylabel(p.objective_names[1])
    else:
        ax.plot(p.F[:, 0], "o")
        ax.set_ylabel(p.objective_names[0])
    ax.legend()
    ax.set_title("Pareto front")
    fig.tight_layout()
    fig.savefig(out / "pareto_front.png", dpi=110)
    plt.close(fig)
    files.append("pareto_front.png")

    sims, _ = evaluator.simulate(p.X[p.knee])
    polished = getattr(res, "polished", ())
    sims_pol = evaluator.simulate(polished[0].x)[0] if polished else []
    if sims:
        e0 = evaluator.experiments[0]
        n_out = e0.outputs.shape[1]
        fig, axes = plt.subplots(n_out, 1, figsize=(8, 2.5 * n_out), squeeze=False)
        dt = evaluator.config.time.dt
        t = np.arange(e0.outputs.shape[0]) * dt
        for j, ax in enumerate(axes[:, 0]):
            ax.plot(t, e0.outputs[:, j], lw=0.8, label="measured")
            ax.plot(t, sims[0][:, j], lw=0.8, label="simulated (knee)")
            if sims_pol:
                ax.plot(t, sims_pol[0][:, j], lw=0.8, ls="--", label="simulated (polished knee)")
            ax.set_ylabel(evaluator.config.sensors[j].name)
        axes[0, 0].legend(loc="upper right")
        axes[-1, 0].set_xlabel("time [s]")
        fig.tight_layout()
        fig.savefig(out / "knee_fit.png", dpi=110)
        plt.close(fig)
        files.append("knee_fit.png")

    fig, axes = plt.subplots(1, p.X.shape[1], figsize=(2.2 * p.X.shape[1], 3), squeeze=False)
    for j, ax in enumerate(axes[0]):
        ax.plot(np.zeros(len(p.X)), p.X[:, j], "o", alpha=0.5)
        ax.plot([0], [p.X[p.knee, j]], "r*", ms=12)
        if polished:
            ax.plot([0], [polished[0].x[j]], "kx", ms=10)
        ax.set_title(p.parameter_names[j])
        ax.set_xticks([])
    fig.tight_layout()
    fig.savefig(out / "parameter_spread.png", dpi=110)
    plt.close(fig)
    files.append("parameter_spread.png")
    return files
