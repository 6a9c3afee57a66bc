"""Measured natural frequencies as data: a small table with uncertainties, fitted together with the records.

Labs measure modes by other tests than the one they record in time — an impact hammer's FFT, a sine sweep's
peaks.  Such numbers are evidence of another kind: they fix the beam's frequency ratios and √(EI/ρA) however
the time record was excited (three tones near one mode say little about the others).  The config gives them::

    [identification.modes]
    frequencies_hz = [6.64, 41.35, 115.8, 117.5]   # the lowest modes, in order
    std_hz = [0.1, 0.3, 0.6, 0.6]                  # their standard uncertainties
    groups = [0, 1, 2, 2]                          # optional: 115.8 and 117.5 Hz, one mode's candidates

or a spectrum file gives them (:mod:`identification.spectrum_modes`; ``--modes FILE`` on the command line,
:func:`with_modes`). Mode ``k`` of the table is the model's ``k``-th lowest mode (with ``groups``, the
modes of group ``k`` are its candidates, the nearest compared: a doublet, :class:`ModalData`); its residual
``(f_model − f)/σ`` is appended to the whitened residuals of the time records, so fits, evidence and Cramér–Rao
bounds use both kinds of data.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError, EbbError

from .settings import identification_table

__all__ = ["ModalData", "modal_data", "with_modes"]


@dataclass(frozen=True, eq=False)
class ModalData:
    """Measured natural frequencies [Hz] of the lowest modes, in order, with their standard uncertainties.

    ``groups`` (``(m,)`` integers from 0, non-decreasing in steps of 0 or 1; ``None``: one measured mode per model
    mode) says which of the model's lowest modes each measured one may be: modes sharing a number are candidates
    for one mode of the beam — a doublet an estimator resolved, one member the beam's bending mode, the other a
    torsional mode or a support's — and the model's mode is compared with the member nearest it (in its
    uncertainties).  The rest of the group is set aside, neither a residual nor evidence against the model."""

    frequencies_hz: np.ndarray
    std_hz: np.ndarray
    groups: np.ndarray | None = None

    @property
    def count(self) -> int:
        """Number of compared modes (of residuals :meth:`residuals` gives): the model's lowest ones."""
        return int(self.frequencies_hz.size if self.groups is None else self.groups[-1] + 1)

    @property
    def chi2_limit(self) -> float:
        """The 99.9 % point of χ² with :attr:`count` degrees of freedom: a model beyond it disagrees."""
        from scipy import stats

        return float(stats.chi2.ppf(0.999, self.count))

    def model_frequencies(self, config: BeamConfig, params: Mapping[str, float]) -> np.ndarray:
        """The model's lowest :attr:`count` natural frequencies [Hz] (damped, of the discrete model)."""
        from ebb_model.modal.modal import discrete_frequencies

        f, _ = discrete_frequencies(config, params, self.count)
        return np.asarray(f[:self.count], dtype=float)

    def compared_with(self, f: np.ndarray) -> np.ndarray:
        """The measured mode compared with each of the model's :attr:`count` lowest frequencies ``f`` (indices):
        in each group the one nearest the model's mode in its own uncertainty."""
        if self.groups is None:
            return np.arange(self.count)
        distance = np.abs(np.asarray(f)[self.groups] - self.frequencies_hz) / self.std_hz
        order = np.lexsort((distance, self.groups))
        return order[np.r_[True, np.diff(self.groups[order]) != 0]]

    def choices(self) -> list["ModalData"]:
        """Every way to take one member of each group: the table without groups, one per combination (itself
        alone when it has none)."""
        if self.groups is None:
            return [self]
        members = [np.flatnonzero(self.groups == g) for g in range(self.count)]
        picks = np.array(np.meshgrid(*members, indexing="ij")).reshape(self.count, -1).T
        return [ModalData(self.frequencies_hz[k], self.std_hz[k]) for k in picks]

    def widened(self, error_hz: np.ndarray) -> "ModalData":
        """The same modes, each uncertainty combined with ``error_hz`` ``(count,)`` of the model mode it is
        compared with (a model grid's own error, say)."""
        e = np.abs(np.asarray(error_hz, dtype=float))
        return replace(self, std_hz=np.hypot(self.std_hz, e if self.groups is None else e[self.groups]))

    def residuals(self, config: BeamConfig, params: Mapping[str, float]) -> np.ndarray:
        """``(f_model − f)/σ`` per compared mode; a model whose modes cannot be computed gets 1e6 each."""
        try:
            f = self.model_frequencies(config, params)
        except (EbbError, ValueError, np.linalg.LinAlgError):
            return np.full(self.count, 1e6)
        if f.size < self.count:
            return np.full(self.count, 1e6)
        k = self.compared_with(f)
        return (f - self.frequencies_hz[k]) / self.std_hz[k]

    def agreement(self, config: BeamConfig, params: Mapping[str, float]) -> dict[str, Any]:
        """χ² of the model against the table, its degrees of freedom and whether it agrees (χ² below the 99.9 %
        point of its distribution), with the model's frequencies, the measured ones compared with them and those
        set aside (``aside_hz``: a group's other members)."""
        r = self.residuals(config, params)
        chi2 = float(r @ r)
        limit = self.chi2_limit
        model = self.model_frequencies(config, params) if chi2 < 1e11 else None
        k = self.compared_with(model) if model is not None else np.arange(self.count)
        aside = np.setdiff1d(np.arange(self.frequencies_hz.size), k)
        return {"chi2": chi2, "modes": self.count, "agrees": bool(chi2 <= limit), "chi2_limit": limit,
                "model_hz": None if model is None else [float(v) for v in model],
                "measured_hz": [float(v) for v in self.frequencies_hz[k]],
                "aside_hz": [float(v) for v in self.frequencies_hz[aside]]}


def modal_data(config: BeamConfig) -> ModalData | None:
    """The ``[identification.modes]`` table of ``config``, checked; ``None`` when there is none.

    Raises
    ------
    ConfigError
        Not a table, lengths that differ, non-increasing frequencies, uncertainties not > 0 — every problem at
        once.
    """
    table = identification_table(config, "modes", "{ frequencies_hz = [...], std_hz = [...] }")
    if table is None:
        return None
    where = "identification.modes"
    bad = [f"{where}.{k}: unknown key; allowed: frequencies_hz, std_hz, groups" for k in table
           if k not in ("frequencies_hz", "std_hz", "groups")]
    values = {}
    for key in ("frequencies_hz", "std_hz"):
        v = table.get(key)
        if not isinstance(v, (list, tuple)) or not v or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v):
            bad.append(f"{where}.{key}: must be a non-empty list of finite numbers, got {v!r}")
            continue
        values[key] = np.array(v, dtype=float)
    if len(values) == 2:
        f, s = values["frequencies_hz"], values["std_hz"]
        if f.size != s.size:
            bad.append(f"{where}: {f.size} frequencies but {s.size} uncertainties")
        if np.any(f <= 0) or np.any(np.diff(f) <= 0):
            bad.append(f"{where}.frequencies_hz: must be > 0 and increasing (the lowest modes, in order)")
        if np.any(s <= 0):
            bad.append(f"{where}.std_hz: every uncertainty must be > 0")
    groups = table.get("groups")
    if groups is not None:
        g = np.array(groups, dtype=float) if isinstance(groups, (list, tuple)) and all(
            isinstance(x, int) and not isinstance(x, bool) for x in groups) else None
        n = values["frequencies_hz"].size if "frequencies_hz" in values else None
        if (g is None or (n is not None and g.size != n) or g.size == 0 or g[0] != 0
                or np.any((np.diff(g) != 0) & (np.diff(g) != 1))):
            bad.append(f"{where}.groups: one integer per frequency, from 0, each the one before or one more "
                       f"(modes sharing a number: candidates for one mode of the beam), got {groups!r}")
        else:
            groups = g.astype(int)
    if bad:
        raise ConfigError(bad)
    return ModalData(values["frequencies_hz"], values["std_hz"], groups)


def with_modes(config: BeamConfig, modes: ModalData) -> BeamConfig:
    """``config`` with ``modes`` as its ``[identification.modes]`` table (peaks picked from a spectrum file, say).

    Raises
    ------
    ConfigError
        The config has a table already: measured modes are stated once.
    """
    from dataclasses import replace
    from types import MappingProxyType

    if modal_data(config) is not None:
        raise ConfigError("identification.modes: the config has a table of measured modes already; give them "
                          "once (drop the table or the spectrum file)")
    ident = dict(config.extra.get("identification", {}) or {})
    ident["modes"] = {"frequencies_hz": [float(v) for v in modes.frequencies_hz],
                      "std_hz": [float(v) for v in modes.std_hz]}
    if modes.groups is not None:
        ident["modes"]["groups"] = [int(v) for v in modes.groups]
    return replace(config, extra=MappingProxyType({**config.extra, "identification": ident}))
