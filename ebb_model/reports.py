"""What ``ebb modes`` reports about a config, as one JSON-ready dict (:func:`modes_report`)."""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any, Callable, Mapping

from .errors import ConfigError

__all__ = ["PROGRESS_NODES", "modes_report"]

#: Grids from this size on report their stages to ``progress`` (smaller ones take well under a second).
PROGRESS_NODES = 200


def modes_report(config_path: str | Path, *, n_modes: int = 10, params: Mapping[str, float] | None = None,
                 band_hz: float | None = None, progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Modes, damping, grid advice and stability of the beam of a config, as a JSON-ready dict.

    Parameters
    ----------
    config_path : str or Path
        TOML config file.
    n_modes : int, optional
        Number of modes to list.
    params : mapping, optional
        Parameter values instead of the config's nominal ones.
    band_hz : float, optional
        The record's top frequency, for the grid advice (default: the listed modes).
    progress : callable, optional
        Receives one line before each stage (modes, grid advice, stability) with the time so far, for grids of
        at least :data:`PROGRESS_NODES` nodes: the work grows as nodes³ (tens of seconds at the limit,
        :data:`~ebb_model.config.types.MAX_NODES`).

    Returns
    -------
    dict
        ``frequencies_hz``, ``damping_ratios``, ``discrete_frequencies_hz``, ``discrete_damping_ratios``, the
        stability analysis (``max_growth_factor``, ``spectral_radius``, ``stable``, ``bistritz_bounds``, …)
        and the ``grid`` advice with its ``summary``.

    Raises
    ------
    ConfigError, ParameterError
        Invalid config, parameter values or ``band_hz``.
    """
    from . import analyse_stability, discrete_frequencies, fast_model, load_config, modes
    from .space.grid_advice import grid_advice
    from .io.jsonio import jsonable
    from .parameter_values import resolve_parameters

    if band_hz is not None and not (math.isfinite(band_hz) and band_hz > 0):
        raise ConfigError(f"`band_hz` must be a positive frequency in Hz, got {band_hz:g}")
    cfg = load_config(config_path)
    p = resolve_parameters(cfg, params)
    t0 = time.perf_counter()

    def stage(what: str) -> None:
        if progress is not None and cfg.beam.nodes >= PROGRESS_NODES:
            progress(f"{cfg.beam.nodes} nodes: {what} ({time.perf_counter() - t0:.0f} s so far; the work grows as "
                     "nodes³)")

    stage("modes")
    ma = modes(cfg, p, n_modes=n_modes)
    stage("grid advice")
    grid = grid_advice(cfg, p, n_modes=n_modes, band_hz=band_hz)
    stage("stability")
    fm = fast_model(cfg, p)
    fd, zd = discrete_frequencies(cfg, p)
    rep = analyse_stability(cfg, p, spectral_radius=fm.spectral_radius())
    return jsonable({
        "frequencies_hz": ma.frequencies_hz.tolist(),
        "damping_ratios": ma.damping_ratios.tolist(),
        "discrete_frequencies_hz": fd[:n_modes].tolist(),
        "discrete_damping_ratios": zd[:n_modes].tolist(),
        "max_growth_factor": rep.max_growth_factor,
        "spectral_radius": rep.spectral_radius,
        "stable": rep.stable,
        "grid_stable": rep.grid_stable,
        "marginal": rep.marginal,
        "analyses_agree": rep.agree,
        "bistritz_bounds": {k: list(v) for k, v in rep.bounds.items()},
        "dt_max": rep.dt_max,
        "messages": list(rep.messages),
        "proportional_damping": ma.proportional,
        "grid": grid.to_dict() | {"summary": grid.summary()},
    })
