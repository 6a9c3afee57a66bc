"""Export of identified models as python-control discrete ``StateSpace`` systems.

A system is saved as an ``.npz`` with ``A, B, C, D, dt``, the signal names, the first-order hold's ``hold``
(``Γ₁``: the state at rest under a constant input ``u0`` is ``−Γ₁ u0``, :func:`rest_state`) and what a control
designer needs
to know where it came from: the system's name, its parameter values with units and the config it was built from
(JSON inside the archive; reloadable without pickle: :func:`load_statespace`, :func:`load_metadata`).
Optionally a reduced model by square-root balanced truncation, with its Hankel singular values and
the a-priori error bound ``‖G - G_r‖_∞ ≤ 2 Σ_{i>r} σ_i`` (Enns/Glover), which
requires an asymptotically stable system (damping > 0): an undamped beam has
no Gramians and is refused with that explanation.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, cast

import numpy as np
import scipy.linalg as sla

from ebb_model import DiscreteStateSpace
from ebb_model.io.output import atomic_path
from ebb_model.errors import ConfigError, StabilityError
from ebb_model.io.jsonio import jsonable
from .parameters import unit

__all__ = ["save_statespace", "load_statespace", "load_metadata", "rest_state", "BalancedModel",
           "balanced_truncation", "continuous_equivalent"]


def save_statespace(sys: DiscreteStateSpace, path: str | Path, *, name: str = "",
                    parameters: Mapping[str, float] | None = None, config: Mapping[str, Any] | None = None,
                    modes: Mapping[str, Any] | None = None) -> Path:
    """Write ``sys`` to ``path`` (``.npz``), atomically, with its name, parameter values (and units), config,
    the hold matrix of a first-order-hold realisation (:func:`rest_state`) and — ``modes`` — which modes it keeps
    with each one's frequency error estimate (:meth:`ebb_model.modal.truncation.ModeResolution.to_dict`)."""
    path = Path(path)
    meta = {"name": name or path.stem,
            "parameters": {k: float(v) for k, v in (parameters or {}).items()},
            "units": {k: unit(k)
                      for k in (parameters or {})},
            "signal_units": {**{u: "N" for u in sys.input_names},
                             **({s.name: s.unit for s in _sensors(config)} if config else {})},
            "config": jsonable(dict(config)) if config else None}
    if modes is not None:
        meta["modes"] = jsonable(dict(modes))
    with atomic_path(path, suffix=".npz") as tmp:
        np.savez(tmp, A=sys.A, B=sys.B, C=sys.C, D=sys.D, dt=np.array(sys.dt),
                 inputs=np.array(sys.input_names), outputs=np.array(sys.output_names),
                 states=np.array(sys.state_names), metadata=np.array(json.dumps(meta)),
                 # as dict[str, Any]: mypy matches a dict[str, ndarray] against savez's allow_pickle (not a key here)
                 **cast("dict[str, Any]", {"hold": sys.hold} if sys.hold is not None else {}))
    return path


def _sensors(config: Mapping[str, Any]):
    from ebb_model.beam import Sensor

    return [Sensor(s["name"], float(s["x"]), s.get("kind", "displacement")) for s in config.get("sensors", [])]


def load_metadata(path: str | Path) -> dict[str, Any]:
    """The name, parameter values, units and config saved with a system (empty for files without them)."""
    with np.load(path, allow_pickle=False) as z:
        return json.loads(str(z["metadata"])) if "metadata" in z.files else {}


def rest_state(path: str | Path, u0: np.ndarray) -> np.ndarray:
    """The initial state of a saved system at rest under the constant input ``u0`` before the record.

    A first-order-hold realisation (the default input reconstruction) has ``y = C x + D u`` with the state
    shifted by the hold: at rest ``x[0] = −Γ₁ u[0]``, not zero — started from zero the system sees a step of
    ``u[0]`` at ``t = 0``.  Pass it as the initial state, e.g. ``control.forced_response(sys, T, U.T,
    X0=rest_state(path, U[0]))``.

    Parameters
    ----------
    path
        A file written by :func:`save_statespace`.
    u0
        The input at the first sample, shape ``(n_inputs,)``.

    Returns
    -------
    numpy.ndarray
        ``−Γ₁ u0`` (zeros for a zero-order hold or a file without a hold).

    Raises
    ------
    ConfigError
        ``u0`` does not have one value per input.
    """
    u0 = np.asarray(u0, dtype=float).ravel()
    with np.load(path, allow_pickle=False) as z:
        n, m = z["A"].shape[0], z["B"].shape[1]
        if u0.shape != (m,):
            raise ConfigError(f"rest_state: u0 has {u0.size} values, the system has {m} inputs")
        return -(z["hold"] @ u0) if "hold" in z.files else np.zeros(n)


def load_statespace(path: str | Path):
    """Load a saved system as a discrete :class:`control.StateSpace` with named signals (and its saved name)."""
    import control

    name = load_metadata(path).get("name") or None
    with np.load(path, allow_pickle=False) as z:
        return control.ss(z["A"], z["B"], z["C"], z["D"], float(z["dt"]), inputs=[str(v) for v in z["inputs"]],
                          outputs=[str(v) for v in z["outputs"]],
                          states=[str(v) for v in z["states"]], name=name)


def continuous_equivalent(sys):
    """The continuous-time system whose transfer function is the discrete ``sys``'s on the bilinear (Tustin) map
    ``z = (1 + sT/2)/(1 − sT/2)`` — for the continuous-only tools of python-control (``hinfsyn``, ``h2syn``);
    a controller designed on it maps back with ``control.sample_system(K, T, "tustin")``.

    With ``E = (I + A)⁻¹``, ``α = 2/T``: ``A_c = α E (A − I)``, ``B_c = √(2α) E B``, ``C_c = √(2α) C E``,
    ``D_c = D − C E B`` (from ``zI − A = (I + A)(sI − A_c)/(α − s)``).  A pole at ``z = −1`` has no image.

    Parameters
    ----------
    sys : control.StateSpace
        A discrete system (e.g. from :func:`load_statespace`).

    Returns
    -------
    control.StateSpace
        Continuous, with the same signal names.

    Raises
    ------
    ConfigError
        ``sys`` is continuous already, or has a pole at ``z = −1``.
    """
    import control

    T = sys.dt
    if not T or T is True:
        raise ConfigError("continuous_equivalent: the system is not discrete (no sample time)")
    A, B, C, D = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
    eye = np.eye(A.shape[0])
    try:
        E = np.linalg.inv(eye + A)
    except np.linalg.LinAlgError:
        raise ConfigError("continuous_equivalent: the system has a pole at z = -1 (no Tustin image)") from None
    alpha = 2.0 / T
    root = np.sqrt(2.0 * alpha)
    return control.ss(alpha * E @ (A - eye), root * E @ B, root * C @ E, D - C @ E @ B,
                      inputs=list(sys.input_labels), outputs=list(sys.output_labels), name=sys.name)


@dataclass(frozen=True, eq=False)
class BalancedModel:
    """A balanced-truncation reduced model and its certificate."""

    system: Any            # a DiscreteStateSpace, or a control.StateSpace for one
    hankel_singular_values: np.ndarray
    order: int
    error_bound: float


def balanced_truncation(sys: Any, order: int) -> BalancedModel:
    """Square-root balanced truncation of a stable discrete system to ``order`` states — the designer's reduction
    of an export: python-control's ``balred`` and ``hsvd`` are SLICOT's continuous-time routines (``balred`` of a
    discrete export returns a *continuous* model with only a warning).

    Parameters
    ----------
    sys
        A discrete :class:`ebb_model.statespace.DiscreteStateSpace`, or a discrete ``control.StateSpace`` (an
        export read by :func:`load_statespace`).
    order
        States kept, ``1 … nstates``.

    Returns
    -------
    BalancedModel
        The reduced system of the same kind and sample time (a ``control.StateSpace`` for one, its states
        ``balanced1 …``), the Hankel singular values and the a-priori bound ``‖G − G_r‖∞ ≤ 2 Σ_{i>r} σ_i``.

    Raises
    ------
    StabilityError
        If the spectral radius is not below one (no Gramians exist).
    ConfigError
        If ``order`` is not in ``1 … nstates``, or ``sys`` is not discrete.
    """
    if not isinstance(sys, DiscreteStateSpace):
        return _control_truncation(sys, order)
    n = sys.nstates
    if isinstance(order, bool) or not 1 <= order <= n:
        raise ConfigError(f"order must lie in 1 … {n}, got {order}")
    rho = sys.spectral_radius()
    if rho >= 1.0 - 1e-12:
        raise StabilityError(f"balanced truncation needs an asymptotically stable system (spectral radius "
                             f"{rho:.12g} ≥ 1: add damping, c > 0 or eta > 0)")
    Wc = sla.solve_discrete_lyapunov(sys.A, sys.B @ sys.B.T)
    Wo = sla.solve_discrete_lyapunov(sys.A.T, sys.C.T @ sys.C)
    Lc = _psd_factor(Wc)
    Lo = _psd_factor(Wo)
    U, s, Vt = np.linalg.svd(Lo.T @ Lc)
    r = order
    S_half = np.diag(1.0 / np.sqrt(s[:r]))
    T = Lc @ Vt[:r].T @ S_half          # n × r
    Ti = S_half @ U[:, :r].T @ Lo.T     # r × n
    red = DiscreteStateSpace(Ti @ sys.A @ T, Ti @ sys.B, sys.C @ T, sys.D, sys.dt, sys.input_names,
                             sys.output_names)
    return BalancedModel(red, s, r, float(2 * np.sum(s[r:])))


def _control_truncation(sys: Any, order: int) -> BalancedModel:
    """:func:`balanced_truncation` of a discrete ``control.StateSpace``, returned as one (same sample time and
    signal names)."""
    import control

    dt = getattr(sys, "dt", None)
    if not isinstance(sys, control.StateSpace) or dt is None or dt is True or not dt:
        raise ConfigError("balanced_truncation: needs a discrete system with its sample time (an export read by "
                          "load_statespace); a continuous one reduces with control.balred")
    inputs, outputs = list(sys.input_labels), list(sys.output_labels)
    own = DiscreteStateSpace(np.asarray(sys.A, float), np.asarray(sys.B, float), np.asarray(sys.C, float),
                             np.asarray(sys.D, float), float(dt), tuple(inputs), tuple(outputs))
    bm = balanced_truncation(own, order)
    red = bm.system
    out = control.ss(red.A, red.B, red.C, red.D, float(dt), inputs=inputs, outputs=outputs,
                     states=[f"balanced{i + 1}" for i in range(red.nstates)],
                     name=f"{sys.name}_reduced{order}" if sys.name else None)
    return BalancedModel(out, bm.hankel_singular_values, bm.order, bm.error_bound)


def _psd_factor(W: np.ndarray) -> np.ndarray:
    """A factor ``L`` with ``W = L Lᵀ`` for a symmetric positive semi-definite ``W``."""
    W = 0.5 * (W + W.T)
    lam, V = np.linalg.eigh(W)
    return V * np.sqrt(np.clip(lam, 0.0, None))
