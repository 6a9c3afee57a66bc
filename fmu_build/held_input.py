"""Sampled forces for a model-exchange master: each sample held until the next, each change an event
(:func:`held_input`, :func:`at_samples`).

A model-exchange master integrates the FMU's state equations itself, so the input between samples is the master's
choice.  fmpy's ``simulate_fmu`` interpolates a sampled input linearly and its CVode right-hand side does not stop
at the samples: the kinks cost accuracy (3.4 % off on the seed bench) and, at a tight tolerance, the solver gives up
("the error test failed repeatedly").  A force held over each sample — what a zero-order-hold DAQ output or the
model's ``time.input = "zoh"`` means — is given to fmpy as steps: every sample time twice, the old value then the
new one, which fmpy treats as events.  The result then has two rows at each sample time; :func:`at_samples` keeps
the one after the event (the input of that sample applied), the rows ``ebb_model.simulate`` gives.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ebb_model.arrays import as_matrix

__all__ = ["held_input", "at_samples"]


def held_input(u: Any, dt: float, names: Sequence[str]) -> np.ndarray:
    """fmpy's ``input`` for the samples ``u`` (n, inputs) at ``t_k = k dt``, each held until ``t_{k+1}``: a
    structured array (``time`` and one field per name) with every sample time but the first twice."""
    u = as_matrix(np.asarray(u, dtype=float), "u")
    if u.shape[1] != len(names):
        raise ValueError(f"u has {u.shape[1]} columns for {len(names)} names")
    n = u.shape[0]
    t = np.repeat(np.arange(n + 1) * float(dt), 2)[1:-1]
    values = np.repeat(u, 2, axis=0)
    out = np.empty(2 * n, dtype=[("time", float)] + [(name, float) for name in names])
    out["time"] = t
    for j, name in enumerate(names):
        out[name] = values[:, j]
    return out


def at_samples(result: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """The rows of fmpy's result (``simulate_fmu``) at each output time after its event, as an array
    (n, len(names)) of the named outputs."""
    t = result["time"]
    last = np.r_[t[1:] != t[:-1], True]
    return np.column_stack([result[name][last] for name in names])
