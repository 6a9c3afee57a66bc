"""Report plots of a diagnosis: ranked effects, held-out residual before/after, localisation."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ebb_model.io.figureio import save_figure
from ebb_model.io.output import make_dir

from .result import GapReport

__all__ = ["plot_diagnosis", "next_experiment_figure", "residual_spectrum", "running_rms"]

#: Windows of the held-out residual's running RMS over the window (a long broadband record's residual drawn sample by
#: sample is a solid block; its level over time is what tells a transient or a drift from the noise).
RMS_WINDOWS = 60


def running_rms(r: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The RMS of ``r`` (in noise standard deviations) over :data:`RMS_WINDOWS` consecutive stretches of equal
    length (fewer on a short record: at least 8 samples each; the last samples that fill no stretch left out):
    each stretch's centre time [s] and RMS — 1 where the residual is the noise."""
    r = np.asarray(r, dtype=float)
    m = max(1, min(RMS_WINDOWS, r.size // 8))
    width = r.size // m
    rms = np.sqrt(np.mean(r[:m * width].reshape(m, width) ** 2, axis=1))
    return (np.arange(m) + 0.5) * width * dt, rms


def residual_spectrum(r: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Welch's power spectral density of ``r`` (in noise standard deviations) over white noise's: 1 at every
    frequency where the residual is the noise, above it where the model misses the records (a mode's peak, a
    band).  Frequencies [Hz] without the mean's bin."""
    from scipy.signal import welch

    r = np.asarray(r, dtype=float)
    f, p = welch(r, fs=1.0 / dt, nperseg=max(64, min(1024, r.size // 8)))   # about 15 averages
    return f[1:], p[1:] / (2.0 * dt)       # unit white noise: 2 dt per Hz, one-sided


def plot_diagnosis(report: GapReport, problem: Any, ranking: Any, localisations: Sequence[Any], out_dir: Path
                   ) -> list[Path]:
    """Write ``effects.png``, ``heldout_residuals.png``, ``next_experiment.png`` (when one was designed) and the
    localisation plots into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    paths: list[Path] = []
    rows = [r for r in report.effects if r.refit is not None]
    if rows:
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 0.5 * len(report.effects) + 2))
        labels = [r.label for r in report.effects][::-1]
        scores = [r.score for r in report.effects][::-1]
        drawn = [s for s in scores if s is not None and s > 0]
        # a bar only for a positive score (log axis); a zero score and a pair (no score test) are said in words
        a1.barh(labels, [s if s is not None and s > 0 else 0.0 for s in scores])
        a1.set_xscale("log")
        left = min(drawn) / 10 if drawn else 1.0
        a1.set_xlim(left=left)
        for k, s in enumerate(scores):
            if s is None or s <= 0:
                a1.text(left, k, "  pair: no score test" if s is None else "  0", va="center", fontsize=8)
        a1.set_xlabel("score-test statistic (LM)")
        a2.barh([r.label for r in rows][::-1],
                [100 * (r.refit.closed or 0.0) for r in rows if r.refit is not None][::-1])  # (each row has one)
        a2.axvline(80, color="k", lw=0.5, ls="--")
        a2.set_xlabel("held-out gap closed after refit [%]")
        fig.suptitle(f"verdict: {report.verdict}")
        fig.tight_layout()
        paths.append(save_figure(fig, out_dir / "effects.png"))
    _, before = problem.heldout(ranking.baseline.beta)
    after = None
    named = report.judged.label
    if named is not None and named in ranking.refits:
        rf = ranking.refits[named]
        _, after = problem.heldout(rf.fit.beta, ranking.effects[named], rf.fit.s)
    dt = problem.config.time.dt
    rb = before[0]
    n_s = rb.shape[1]
    fig, axes = plt.subplots(n_s, 2, figsize=(11, 2.3 * n_s + 0.6), squeeze=False,
                             gridspec_kw={"width_ratios": (3, 2)})
    for j, name in enumerate(problem.config.output_names):
        shown = [(rb[:, j], "C0", "baseline")]
        if after is not None:
            shown.append((after[0][:, j], "C1", f"with {named}"))
        for r, color, label in shown:
            t, rms = running_rms(r, dt)
            axes[j, 0].plot(t, rms, color=color, lw=1.0, label=label)
            f, level = residual_spectrum(r, dt)
            axes[j, 1].semilogy(f, level, color=color, lw=0.8, label=label)
        for ax in axes[j]:
            ax.axhline(1.0, color="k", lw=0.6, ls="--")
        axes[j, 0].set_ylim(bottom=0.0)
        axes[j, 0].set_ylabel(f"{name}: RMS / σ [-]")
        axes[j, 1].set_ylabel("power / noise floor [-]")
        axes[j, 1].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, borderaxespad=0.0)
    axes[-1, 0].set_xlabel("time in the held-out window [s] (running RMS; dashed: the noise floor)")
    axes[-1, 1].set_xlabel("frequency [Hz] (Welch)")
    fig.tight_layout()
    paths.append(save_figure(fig, out_dir / "heldout_residuals.png"))
    nxt = report.next_experiment
    if nxt is not None and nxt.designs:
        paths.append(save_figure(next_experiment_figure(plt, nxt), out_dir / "next_experiment.png"))
    try:
        from .plots import plot_localisation
    except ImportError:  # pragma: no cover - localisation plots are optional
        return paths
    r0 = problem.records[0]
    y0 = problem.simulate(ranking.baseline.beta, until="all")[0]
    sub = out_dir / "localisation"
    make_dir(sub, exist_ok=True)
    cfg = problem.config
    units = {s.name: s.unit for s in cfg.sensors} | {a.name: "N" for a in cfg.actuators}   # point forces
    paths += [Path(p) for p in plot_localisation(localisations[0], cfg.time.dt, r0.inputs, r0.outputs, y0, sub,
                                                 units=units)]
    return paths


def _design_label(design: Any, setups: bool) -> str:
    """A design in two short lines for the chart's axis: the band, then the sensors (and the set-up when the
    bench has several)."""
    lo, hi = design.band_hz
    where = ("the records' sensors" if design.sensor is None
             else f"+ {design.sensor[0]} sensor at x = {design.sensor[1]:.3g} m")
    return (f"{lo:.3g}-{hi:.3g} Hz ({design.band_name})\n" + (f"{design.setup}: " if setups else "") + where)


def next_experiment_figure(plt: Any, nxt: Any) -> Any:
    """The designed experiments' expected log Bayes factors (the worst pair's, each direction of every pair
    marked), the records' own design and the decisive level: :class:`diagnosis.design.NextExperiment`.  Each
    design is labelled in two short lines and the legend sits below the axes, so the chart fits the page at its
    natural size (:mod:`ebb_model.io.figureio`)."""
    shown = list(nxt.designs)
    if nxt.as_recorded is not None and nxt.as_recorded not in shown:
        shown.append(nxt.as_recorded)
    setups = len({d.design.setup for d in shown}) > 1
    names = [_design_label(d.design, setups) + ("\n(the records' own)" if d is nxt.as_recorded else "")
             for d in shown]
    floor = 1e-3
    rows = np.arange(len(shown))[::-1]          # the best at the top
    # the legend below the axes, two entries a row: every ordered pair ("a>b": a true, against b), "decisive" and
    # "worst pair"
    legend_rows = -(-(len(nxt.designs[0].pairs) + 2) // 2)
    legend = 0.2 * legend_rows + 0.1             # inches
    height = 0.55 * len(shown) + 1.8 + legend     # inches
    fig, ax = plt.subplots(figsize=(8.5, height))
    ax.barh(rows, [max(d.rate * nxt.seconds, floor) for d in shown], color="0.6", label="worst pair")
    for pair in nxt.designs[0].pairs:
        ax.plot([max(d.pairs[pair] * nxt.seconds, floor) for d in shown], rows, "o", ms=4,
                label=pair.replace(">", " true, against "))
    ax.set_yticks(rows, names)
    ax.axvline(nxt.decisive, color="k", lw=0.8, ls="--", label="decisive")
    ax.set_xscale("log")
    ax.set_xlabel(f"random force: expected ln Bayes factor in a {nxt.seconds:.3g} s record")
    ax.tick_params(axis="y", labelsize=8)
    ax.set_title("next experiment: " + " / ".join(nxt.candidates), fontsize=10)
    fig.legend(*ax.get_legend_handles_labels(), fontsize=8, loc="lower center", ncol=2, frameon=False)
    fig.tight_layout(rect=(0.0, legend / height, 1.0, 1.0))      # the legend's rows below the axes
    return fig
