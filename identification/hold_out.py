r"""The modes a joint fit did not use, predicted: each segment held out of the beam, its own unknowns from one mode.

A joint fit of a tracked record's segments (:func:`identification.joint_segments.fit_together`) matches every
frequency it is given as well as its unknowns allow; whether its model *predicts* is another question.  Here each
segment in turn is held out: the beam — the shared unknowns — is fitted to the other segments alone (started at
the fit of all), the held-out segment's own unknowns (a support's place) to **one** of its modes at that beam, and
its other modes are predicted:

.. math::  e_{ik} = f_k(\theta_{-i}, v_i^{(j)}) / \hat f_{ik} - 1, \qquad k \neq j

(``θ₋ᵢ`` the beam without segment ``i``, ``v_i^{(j)}`` the segment's own unknowns from its mode ``j``) — the second
mode when the first was fitted, the first when the second was, and so on.  A model that has the physics of the
set-up predicts them within the scatter of the set-up's own repeats; one that reproduces the frequencies only by
bending its unknowns does not.  The relative errors are returned as they are: which size of error is acceptable
is the user's (a design's tolerance), not a statistical test's — the frequencies' own σ (1e-4 relative on a ring
down) are far below any beam model's reach on a real bench.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
from scipy import optimize

from ebb_model.config import BeamConfig
from ebb_model.errors import EbbError

from .joint_segments import JointFit, fit_together
from .modal_data import ModalData
from .parameters import ParameterSpace, parameter_space

__all__ = ["HeldOut", "hold_out"]


@dataclass(frozen=True)
class HeldOut:
    """One prediction: segment ``segment`` (index into the fitted segments) held out, its own unknowns from its
    mode ``used`` (0-based), the model's frequency of each of its modes [Hz], the measured ones compared with
    them, and the relative errors (``nan`` at the mode used)."""

    segment: int
    used: int
    model_hz: list[float]
    measured_hz: list[float]
    error: list[float]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (a row of ``tracked.json``'s ``together.held_out``)."""
        return {"segment": self.segment, "mode_used": self.used + 1, "model_hz": self.model_hz,
                "measured_hz": self.measured_hz,
                "relative_error": [None if not np.isfinite(e) else e for e in self.error]}

    @property
    def largest(self) -> float:
        """The largest relative error of the predicted modes (absolute value)."""
        return float(np.nanmax(np.abs(self.error)))


def hold_out(config: BeamConfig, modes: Sequence[ModalData], varying: Sequence[str], joint: JointFit
             ) -> list[HeldOut]:
    """Every segment of ``joint`` (the fit of ``modes`` with ``varying`` per segment) held out in turn and its
    modes predicted from one of them (module docstring); segments with fewer modes than their own unknowns plus
    one predict nothing and are skipped, and so is a prediction whose model frequencies cannot be computed."""
    space = parameter_space(config)
    names = list(space.names)
    vary = np.array([n in varying for n in names])
    k_vary = np.flatnonzero(vary)

    def full(shared: dict[str, float], own: dict[str, float]) -> np.ndarray:
        return np.array([own[n] if n in own else shared[n] for n in names])

    starts = [full(joint.shared, v) for v in joint.varying]
    out: list[HeldOut] = []
    for i, m in enumerate(modes):
        if m.count < k_vary.size + 1:
            continue
        rest = [d for k, d in enumerate(modes) if k != i]
        beam = fit_together(config, rest, varying, [s for k, s in enumerate(starts) if k != i], search=False)
        x0 = full(beam.shared, joint.varying[i])
        for j in range(m.count):
            predicted = _predict(config, space, m, x0, k_vary, j)
            if predicted is None:
                continue
            f, measured = predicted
            err = f / measured - 1.0
            err[j] = np.nan
            out.append(HeldOut(i, j, f.tolist(), measured.tolist(), err.tolist()))
    return out


def _predict(config: BeamConfig, space: ParameterSpace, m: ModalData, x0: np.ndarray, k_vary: np.ndarray, j: int
             ) -> tuple[np.ndarray, np.ndarray] | None:
    """The model's frequencies of ``m``'s modes and the measured ones compared with them, the varying unknowns
    (indices ``k_vary`` of ``x0``) fitted to mode ``j`` alone at ``x0``'s shared values; ``None`` when they
    cannot be computed."""
    def at(v: np.ndarray) -> np.ndarray:
        x = x0.copy()
        x[k_vary] = v
        return x

    def residual(v: np.ndarray) -> np.ndarray:
        return m.residuals(*space.apply(config, at(v)))[j:j + 1]

    lo, hi = space.lower[k_vary], space.upper[k_vary]
    try:
        fit = optimize.least_squares(residual, np.clip(x0[k_vary], lo, hi), bounds=(lo, hi),
                                     x_scale=np.maximum(hi - lo, 1e-12), diff_step=1e-7)
        f = m.model_frequencies(*space.apply(config, at(fit.x)))
    except (EbbError, ValueError, np.linalg.LinAlgError):
        return None
    if f.size < m.count:
        return None
    return f, m.frequencies_hz[m.compared_with(f)]
