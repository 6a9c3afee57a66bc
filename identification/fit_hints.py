"""What a fit far from the noise floor may be missing that a simple transformation would supply.

A fit that stays hundreds of noise variances above the floor is either a model that lacks something (the
diagnosis' question) or records that differ from the model by something simple: a sensor's gain or sign (a
calibration, a unit — a record in mm read as m is a gain of 1000), or the level of the whole model (EI, ρA, c and
N scaled together) that the bounds kept out of reach.  Each is one inner product away: the best gain of a
sensor's simulated output, ``a = ⟨ŷ, y⟩ / ⟨ŷ, ŷ⟩``, and what it would leave.  :func:`fit_hints` names each
transformation that would remove most of the misfit above the floor (:data:`REMOVES`), with its value, so that a user
reads "units, calibration or the bounds" instead of a bare "the fit leaves 1.04e4 noise variances"; and
:func:`bound_flags` names every unknown that ended on a bound of its search (its value is then the bound's, not
the data's, and its Cramér–Rao standard deviation describes a point that is not an optimum).
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

__all__ = ["ON_BOUND", "bound_flags", "fit_hints"]

#: An unknown within this share of its search range of a bound is on that bound.
ON_BOUND = 1e-4
#: A transformation is named when it removes at least this share of the misfit above the noise floor.  A wrong unit
#: or calibration is removed by its gain almost entirely (a record in mm read as m, the fit stopped on a bound:
#: 95 %); a misfit of another cause projects partly onto a gain (an undeclared anti-alias filter at 0.43 fs: a gain
#: of 1.04 removed 66 %, and at 0.5 was called "units or calibration" — ``tests/test_hint_rates.py``).
REMOVES = 0.8
#: Only fits above this many noise variances (on some sensor) are examined.
EXAMINED_ABOVE = 2.0


def bound_flags(names: Sequence[str], lower: np.ndarray, upper: np.ndarray, x: np.ndarray) -> dict[str, dict[str, Any]]:
    """``{name: {"bound": "lower" | "upper", "value": bound}}`` for every unknown on a bound of its range."""
    out: dict[str, dict[str, Any]] = {}
    for n, lo, hi, v in zip(names, lower, upper, np.asarray(x, float)):
        tol = ON_BOUND * (hi - lo)
        if v <= lo + tol:
            out[n] = {"bound": "lower", "value": float(lo)}
        elif v >= hi - tol:
            out[n] = {"bound": "upper", "value": float(hi)}
    return out


def fit_hints(sensor_names: Sequence[str], measured: Sequence[np.ndarray], simulated: Sequence[np.ndarray],
              gap: Mapping[str, float], level_free: bool, start: Any = None) -> list[str]:
    """The simple transformations that would bring a fit far above the floor down (module docstring).

    Parameters
    ----------
    sensor_names
        The sensors, in column order.
    measured, simulated
        Per experiment, the records' and the model's outputs ``(n, n_sensors)``.
    gap
        The fit's residual per sensor in noise variances (1: the floor).
    level_free
        Whether a common scale of EI, ρA, c and N is a change of the unknowns that moves no frequency (both EI and
        ρA unknown, no declared mass or spring the scale leaves alone), named as such when all sensors want the
        same gain.
    start
        The records' start (:class:`~identification.data_start.DataStart`) or ``None``: its note of a level beyond
        the bounds comes first when this fit bears it out (some sensor wants a gain that removes most of its misfit
        above the floor); a reversed sign is said by these gains where it holds.  Measured: an
        undeclared converter delay of 10 samples made the start say "opposite in sign" and "the records' level asks
        for EI 49" of records whose sign and level were right (only their channel lagged).
    """
    gaps = np.array([float(gap.get(s, np.nan)) for s in sensor_names])
    if not np.any(gaps > EXAMINED_ABOVE):
        return []
    y = np.concatenate([np.asarray(m, float) for m in measured])
    h = np.concatenate([np.asarray(s, float) for s in simulated])
    hy, hh, yy = np.sum(h * y, axis=0), np.sum(h * h, axis=0), np.sum(y * y, axis=0)
    rr = np.sum((y - h) ** 2, axis=0)
    hints: list[str] = []
    gains = np.where(hh > 0, hy / np.where(hh > 0, hh, 1.0), np.nan)
    # min over a of |y - a h|^2 = |y|^2 - <h, y>^2 / |h|^2
    after = np.maximum(yy - np.where(hh > 0, hy * hy / np.where(hh > 0, hh, 1.0), 0.0), 0.0)
    wants = []
    for j, s in enumerate(sensor_names):
        if not (gaps[j] > EXAMINED_ABOVE and np.isfinite(gains[j]) and rr[j] > 0):
            continue
        left = gaps[j] * after[j] / rr[j]
        if gaps[j] - left >= REMOVES * (gaps[j] - 1.0):
            wants.append(j)
            what = "a reversed sign" if gains[j] < 0 else "units or calibration"
            hints.append(f"the records' level suggests a gain of {gains[j]:.4g} on {s}: it would leave "
                         f"{max(left, 0.0):.3g} noise variances instead of {gaps[j]:.3g} — {what} of that channel "
                         "([identification.data] units or gains), or the search")
    if wants and start is not None and start.level_note is not None:
        hints.insert(0, start.level_note)
    if level_free and len(wants) == len(sensor_names) and len(sensor_names) > 0:
        g = gains[wants]
        if np.all(g > 0) and np.max(g) / np.min(g) < 1.1:
            common = float(np.exp(np.mean(np.log(g))))
            hints.append(f"every sensor wants the same gain {common:.4g}: a common scale of {1.0 / common:.4g} on EI, "
                         "rhoA, c and N gives it without changing a frequency — widen their bounds if the scale is "
                         "physical, else check the records' units")
    return hints

