"""Report plots of an identification run (matplotlib, Agg backend, PNG files).

Each figure is built by a function of arrays (:func:`fit_figure`, :func:`spread_figure`, :func:`front_figure`)
and written by :func:`plot_results`; every axis carries its unit, signal names come from the config, legends sit
outside the data, and tick labels are plain numbers (no offset such as ``+3.499``).
"""
from __future__ import annotations

from itertools import combinations
from typing import Any, Mapping, Sequence

import numpy as np

from ebb_model.io.figureio import save_figure
from .parameters import unit

__all__ = ["plot_results", "fit_figure", "spread_figure", "front_figure", "zoom_window", "dominant_hz",
           "plain_ticks", "trace", "LINE_SAMPLES"]

#: A panel draws a signal of at most this many samples as a line; a longer one as its envelope (:func:`trace`):
#: a broadband record of 20,000 samples drawn as a line is a solid block.
LINE_SAMPLES = 4000
#: Stretches of an envelope across a panel: the smallest and largest value in each.
ENVELOPE_BINS = 800


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, path: Any) -> None:
    """Write ``fig`` as a PNG to ``path`` atomically and close it."""
    save_figure(fig, path)


def _objective_label(name: str) -> str:
    return f"{name} [-]" if name.startswith("nrmse") or name == "growth_factor" else name


def _parameter_label(name: str) -> str:
    u = unit(name)
    return f"{name} [{u}]" if u else name


def plain_ticks(ax: Any) -> None:
    """Tick labels as plain numbers: no offset (``+3.499``) and no shared exponent on a linear axis."""
    for axis in (ax.xaxis, ax.yaxis):
        fmt = axis.get_major_formatter()
        if hasattr(fmt, "set_useOffset"):
            fmt.set_useOffset(False)


def trace(ax: Any, t: np.ndarray, y: np.ndarray, *, color: str, label: str, lw: float = 0.6, alpha: float = 1.0,
          zorder: float | None = None) -> Any:
    """``y(t)`` on ``ax``: a line up to :data:`LINE_SAMPLES` samples, else its envelope — the smallest and largest
    value in each of :data:`ENVELOPE_BINS` stretches, filled, labelled ``"<label> (envelope)"``."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    if t.size <= LINE_SAMPLES:
        return ax.plot(t, y, lw=lw, color=color, alpha=alpha, label=label, zorder=zorder)
    k = -(-t.size // ENVELOPE_BINS)
    m = t.size // k * k
    tb = np.append(t[:m:k], t[m - 1])
    lo = np.append(y[:m].reshape(-1, k).min(axis=1), y[m - k:].min())
    hi = np.append(y[:m].reshape(-1, k).max(axis=1), y[m - k:].max())
    return ax.fill_between(tb, lo, hi, step="post", color=color, alpha=alpha, lw=0, label=f"{label} (envelope)",
                           zorder=zorder)


def dominant_hz(y: np.ndarray, dt: float) -> float:
    """The frequency [Hz] of the largest spectral line of ``y`` (mean removed)."""
    spectrum = np.abs(np.fft.rfft(y - np.mean(y)))
    return float(np.fft.rfftfreq(y.size, dt)[int(np.argmax(spectrum))])


def zoom_window(n: int, dt: float, *, periods_hz: float | None = None) -> slice:
    """A readable stretch of an ``n``-sample record: ten periods of ``periods_hz`` (else a twentieth of the
    record), at least 200 samples, from the middle of the record."""
    if periods_hz is not None and periods_hz > 0:
        width = int(round(10.0 / (periods_hz * dt)))
    else:
        width = n // 20
    width = int(min(n, max(200, width)))
    start = max(0, min(n - width, n // 2))
    return slice(start, start + width)


def fit_figure(t: np.ndarray, measured: np.ndarray, models: Mapping[str, np.ndarray], names: Sequence[str],
               units: Sequence[str], *, zoom: slice | None = None) -> Any:
    """Measured against simulated outputs, one row per sensor: the whole record (left) and a zoom (right).

    The models are drawn first and the measurement on top (black, thin), so the data stay visible where the
    model fits them.  A record longer than :data:`LINE_SAMPLES` is drawn whole as envelopes (:func:`trace`): the
    measurement's (grey) and each model's residual, measured − model (coloured) — where the misfit lies along the
    record; the zoom shows the cycles.
    """
    plt = _pyplot()
    n_out = measured.shape[1]
    zoom = zoom if zoom is not None else zoom_window(t.size, float(t[1] - t[0]) if t.size > 1 else 1.0)
    fig, axes = plt.subplots(n_out, 2, figsize=(11, 2.5 * n_out + 0.6), squeeze=False,
                             gridspec_kw={"width_ratios": [2, 1]})
    for j in range(n_out):
        for ax, sl in ((axes[j, 0], slice(None)), (axes[j, 1], zoom)):
            if t[sl].size > LINE_SAMPLES:
                trace(ax, t[sl], measured[sl, j], color="0.75", label="measured")
                for k, (label, y) in enumerate(models.items()):
                    trace(ax, t[sl], measured[sl, j] - y[sl, j], color=f"C{k}", alpha=0.8,
                          label=f"measured − {label}")
            else:
                for k, (label, y) in enumerate(models.items()):
                    ax.plot(t[sl], y[sl, j], lw=1.4, color=f"C{k}", alpha=0.8, label=label)
                ax.plot(t[sl], measured[sl, j], lw=0.6, color="k", label="measured", zorder=5)
            plain_ticks(ax)
        axes[j, 0].set_ylabel(f"{names[j]} [{units[j]}]")
        axes[j, 1].set_title(f"{names[j]}: zoom {t[zoom][0]:.4g}–{t[zoom][-1]:.4g} s", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    axes[0, 0].axvspan(t[zoom][0], t[zoom][-1], color="0.85", zorder=0, label="zoomed (right)")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    if t.size > LINE_SAMPLES:                       # the zoom's lines are named too
        more = axes[0, 1].get_legend_handles_labels()
        handles, labels = handles + more[0], labels + more[1]
    _legend_below(fig, handles, labels)
    return fig


#: Columns of a legend below a figure's panels: a long record's fit figure names up to seven lines, whose labels
#: in one row made the saved figure twice as wide as its panels.
LEGEND_COLUMNS = 3
#: Height of one legend row at font size 8, and the legend's padding [inch].
_LEGEND_ROW, _LEGEND_PAD = 0.22, 0.12


def _legend_below(fig: Any, handles: Sequence[Any], labels: Sequence[str], *, top: float = 1.0) -> None:
    """One legend for the whole figure, centred below its panels in rows of at most :data:`LEGEND_COLUMNS`
    entries, and the panels laid out above it (``top``: the share of the height they may reach)."""
    ncol = max(1, min(len(labels), LEGEND_COLUMNS))
    rows = -(-len(labels) // ncol)
    fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=8, bbox_to_anchor=(0.5, 0.0))
    bottom = (rows * _LEGEND_ROW + _LEGEND_PAD) / fig.get_size_inches()[1]
    fig.tight_layout(rect=(0, min(bottom, 0.5), 1, top))


def spread_figure(X: np.ndarray, names: Sequence[str], knee: int, identified: np.ndarray | None) -> Any:
    """The unknowns over the Pareto set, the knee and the identified model marked; legend below the panels."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, X.shape[1], figsize=(2.6 * X.shape[1] + 0.4, 3.6), squeeze=False)
    for j, ax in enumerate(axes[0]):
        ax.plot(np.zeros(len(X)), X[:, j], "o", alpha=0.5, label="Pareto set (GA)")
        ax.plot([0], [X[knee, j]], "r*", ms=12, label="knee (not polished)")
        if identified is not None:
            ax.plot([0], [identified[j]], "kx", ms=10, label="identified (polished knee)")
        ax.set_ylabel(_parameter_label(names[j]))
        ax.set_xticks([])
        plain_ticks(ax)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    _legend_below(fig, handles, labels)
    return fig


def front_figure(F: np.ndarray, names: Sequence[str], knee: int, identified: np.ndarray | None,
                 history: np.ndarray | None = None) -> Any:
    """The Pareto front, every pair of objectives.  One objective has no front: the GA's convergence (the best
    value against the model evaluations, from ``history`` — :attr:`~identification.optimise.ParetoSet.history`),
    or without a history the final set's values, sorted."""
    plt = _pyplot()
    pairs = list(combinations(range(F.shape[1]), 2))
    if pairs:
        fig, axes = plt.subplots(1, len(pairs), figsize=(4.6 * len(pairs), 4.2), squeeze=False)
        for ax, (a, b) in zip(axes[0], pairs):
            ax.scatter(F[:, a], F[:, b], c="C0", s=18, label="Pareto set (GA)")
            ax.scatter(F[knee, a], F[knee, b], c="C3", marker="*", s=150, label="knee (not polished)")
            if identified is not None:
                ax.scatter(identified[a], identified[b], c="k", marker="x", s=80, label="identified (polished knee)")
            ax.set_xlabel(_objective_label(names[a]))
            ax.set_ylabel(_objective_label(names[b]))
            plain_ticks(ax)
        fig.suptitle("Pareto front" + (" (all pairs of objectives)" if len(pairs) > 1 else ""))
        ax0 = axes[0, 0]
    elif history is not None and history.size:
        fig, ax0 = plt.subplots(figsize=(5.5, 4.2))
        best = np.minimum.accumulate(history[:, 1])
        ax0.plot(history[:, 0], best, "o-", ms=3, label="GA: best so far")
        if identified is not None:
            ax0.axhline(identified[0], color="k", ls="--", label="identified (polished knee)")
        if np.all(best > 0) and (identified is None or identified[0] > 0):
            from matplotlib.ticker import FuncFormatter

            ax0.set_yscale("log")
            for set_formatter in (ax0.yaxis.set_major_formatter, ax0.yaxis.set_minor_formatter):
                set_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))    # 0.06, not 6×10⁻²
        ax0.set_xlabel("model evaluations [-]")
        ax0.set_ylabel(_objective_label(names[0]))
        ax0.set_title("one objective: the GA's convergence (no front)")
        plain_ticks(ax0)
    else:
        fig, ax0 = plt.subplots(figsize=(5, 4.2))
        order = np.argsort(F[:, 0])
        ax0.plot(np.arange(1, len(F) + 1), F[order, 0], "o", label="GA's final set")
        if identified is not None:
            ax0.axhline(identified[0], color="k", ls="--", label="identified (polished knee)")
        ax0.set_xlabel("member of the GA's final set, best first [-]")
        ax0.set_ylabel(_objective_label(names[0]))
        ax0.set_title("one objective: no front, the GA's best members")
        plain_ticks(ax0)
    handles, labels = ax0.get_legend_handles_labels()
    _legend_below(fig, handles, labels, top=0.97)
    return fig


def plot_results(res: Any, evaluator: Any) -> list[str]:
    """``pareto_front.png``, ``knee_fit.png`` (measured vs simulated per sensor) and ``parameter_spread.png``
    into the run's directory; returns the file names.  The knee and the identified model (polished knee) are
    marked in every panel."""
    p = res.pareto
    out = res.out_dir
    polished = getattr(res, "polished", ())
    identified_f = np.asarray(polished[0].objectives) if polished else None
    files = ["pareto_front.png"]
    _save(front_figure(p.F, p.objective_names, p.knee, identified_f, p.history), out / files[-1])

    sims = evaluator.simulate(p.X[p.knee]).outputs
    sims_pol = evaluator.simulate(polished[0].x).outputs if polished else ()
    if sims:
        e0 = evaluator.experiments[0]
        dt = evaluator.config.time.dt
        t = np.arange(e0.outputs.shape[0]) * dt
        models = {"simulated (knee, not polished)": sims[0]}
        if sims_pol:
            models["simulated (identified: polished knee)"] = sims_pol[0]
        sensors = evaluator.config.sensors
        files.append("knee_fit.png")
        zoom = zoom_window(t.size, dt, periods_hz=dominant_hz(e0.outputs[:, 0], dt))
        _save(fit_figure(t, e0.outputs, models, [s.name for s in sensors], [s.unit for s in sensors], zoom=zoom),
              out / files[-1])

    files.append("parameter_spread.png")
    _save(spread_figure(p.X, p.parameter_names, p.knee, np.asarray(polished[0].x) if polished else None),
          out / files[-1])
    return files


def _together(ax: Any, name: str, tracked: Sequence[Any], together: Mapping[str, Any]) -> None:
    """The joint fit's value of ``name`` on its axis: per segment when it varies, a band when shared."""
    label = "segments together" + ("" if together.get("agrees") else " (no one beam reproduces them)")
    if name in together["varies"]:
        mid = [0.5 * (tracked[i - 1].start_s + tracked[i - 1].stop_s) for i in together["segments"]]
        ax.errorbar(mid, [v[name] for v in together["varying"]], yerr=[s[name] for s in together["varying_std"]],
                    fmt="s", color="k", ms=4, capsize=3, label=label)
    elif name in together["shared"]:
        v, sd = together["shared"][name], together["shared_std"][name]
        ax.axhline(v, color="k", lw=1.0, label=label)
        ax.axhspan(v - sd, v + sd, color="k", alpha=0.15, lw=0)


def tracking_figure(t: np.ndarray, channel: np.ndarray, tracked: Sequence[Any], channel_name: str, path: Any,
                    together: Mapping[str, Any] | None = None) -> None:
    """``tracked.png``: the declared channel over the record (its envelope when long) with each segment's level,
    and below it every unknown a segment fixed, at the segment's middle with its 1σ bar (hollow and grey where the
    segment's model does not reproduce its modes: no measurement) — the tracked parameters as a time series beside
    the channel that says when the set-up changed (:func:`identification.tracking.track`).  With ``together``
    (:func:`identification.tracking.together_lines`' record) the segments' joint fit beside: each varying unknown
    per segment (black squares), each shared one as its band (value ± σ)."""
    plt = _pyplot()
    names: list[str] = []
    for row in tracked:
        if row.identified is not None:
            names += [n for n in row.identified.parameters if n not in row.identified.held and n not in names]
    fig, axes = plt.subplots(1 + len(names), 1, figsize=(7.0, 2.0 + 1.6 * len(names)), sharex=True,
                             squeeze=False)
    ax = axes[0, 0]
    trace(ax, t, channel, color="0.6", label=channel_name)
    for row in tracked:
        ax.plot([row.start_s, row.stop_s], [row.segment.level] * 2, color="C0", lw=2.0)
    ax.set_ylabel(channel_name)
    plain_ticks(ax)
    misfit = False
    for ax, name in zip(axes[1:, 0], names):
        points: dict[bool, tuple[list[float], list[float], list[float]]] = {True: ([], [], []), False: ([], [], [])}
        for row in tracked:
            ident = row.identified
            if ident is not None and name in ident.parameters and name not in ident.held:
                mid, val, sd = points[bool(ident.agreement["agrees"])]
                mid.append(0.5 * (row.start_s + row.stop_s))
                val.append(ident.parameters[name])
                sd.append(ident.std[name])
        ax.errorbar(*points[True][:2], yerr=points[True][2], fmt="o", color="C1", ms=4, capsize=3)
        if points[False][0]:        # a value whose model does not reproduce its segment's modes: no measurement
            misfit = True
            ax.errorbar(*points[False][:2], yerr=points[False][2], fmt="o", mfc="none", color="0.55", ms=4,
                        capsize=3)
        if together is not None and "varying" in together:
            _together(ax, name, tracked, together)
        ax.set_ylabel(_parameter_label(name))
        plain_ticks(ax)
    if together is not None and "varying" in together:
        axes[1 if names else 0, 0].legend(fontsize="small", loc="best")
    if misfit:
        hollow = axes[-1, 0].plot([], [], "o", mfc="none", color="0.55")[0]
        fig.legend([hollow], ["the model does not reproduce the segment's modes"], loc="upper center",
                   bbox_to_anchor=(0.5, 0.0), fontsize="small", frameon=False)
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle("tracked per still segment (1σ bars)")
    _save(fig, path)
