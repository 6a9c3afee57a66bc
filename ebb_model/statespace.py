"""Discrete-time state-space systems as immutable values.

.. math::

    x[k+1] = A x[k] + B u[k], \\qquad y[k] = C x[k] + D u[k], \\qquad t_k = k\\,dt.

Following python-control's ``statesp.py`` habit, every matrix passes through
one normaliser (:func:`ebb_model.arrays.as_matrix`) that makes a read-only
float 2-D copy and checks its shape; operations return new objects.  Signals carry names from
the start (actuator and sensor names of the config).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .arrays import as_matrix
from .checks import finite_scalar
from .errors import ConfigError

__all__ = ["DiscreteStateSpace", "common_timebase", "with_input_delays"]


def _matrix(name: str, value, shape: tuple[int | None, int | None]) -> np.ndarray:
    """Read-only float64 2-D copy of ``value`` with the expected shape (a :class:`ConfigError` otherwise)."""
    return as_matrix(value, name, shape=shape, vector=False, readonly=True, error=ConfigError, row="row")


def _names(kind: str, names: Sequence[str] | None, n: int, prefix: str) -> tuple[str, ...]:
    if names is None:
        return tuple(f"{prefix}[{i}]" for i in range(n))
    names = tuple(names)
    if len(names) != n:
        raise ConfigError(f"{kind} names: got {len(names)}, expected {n}")
    return names


def common_timebase(dt1: float, dt2: float, *, rtol: float = 1e-12) -> float:
    """The one place that decides whether two sample times are compatible.

    Raises
    ------
    ConfigError
        If the sample times differ by more than ``rtol`` relatively.
    """
    if abs(dt1 - dt2) > rtol * max(abs(dt1), abs(dt2)):
        raise ConfigError(f"incompatible sample times {dt1:g} s and {dt2:g} s")
    return dt1


@dataclass(frozen=True, eq=False)
class DiscreteStateSpace:
    """An immutable discrete-time LTI system with named signals.

    Parameters
    ----------
    A, B, C, D
        System matrices (n×n, n×m, p×n, p×m).
    dt
        Sample time [s], > 0.
    input_names, output_names, state_names
        Signal names; defaults ``u[i]``, ``y[i]``, ``x[i]``.
    hold
        Optional (n×m) matrix ``Γ₁`` of a first-order-hold realisation
        (:mod:`ebb_model.theta.theta_scheme`): the state is ``ξ = x − Γ₁ u``, so
        a start at rest is ``ξ[0] = −Γ₁ u[0]`` (what :func:`ebb_model.simulate`
        uses by default).  ``None``: a start at rest is ``ξ[0] = 0``.
    advance
        How many samples ahead of the record the input is read (0: none): the system's input ``u[k]`` is the
        record's ``u[k + advance]`` (:mod:`ebb_model.acquisition.bandlimited`: a reconstruction that reads samples
        ahead), as :func:`ebb_model.simulate` feeds it.
    output_delays
        Each output's channel delay in samples (:mod:`ebb_model.acquisition.channel_delay`), applied to the simulated
        outputs and the frequency response; ``()``: none.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    dt: float
    input_names: tuple[str, ...] = field(default=())
    output_names: tuple[str, ...] = field(default=())
    state_names: tuple[str, ...] = field(default=())
    hold: np.ndarray | None = None
    advance: int = 0
    output_delays: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        A = _matrix("A", self.A, (None, None))
        n = A.shape[0]
        if A.shape != (n, n):
            raise ConfigError(f"A has shape {A.shape}, expected a square matrix")
        B = _matrix("B", self.B, (n, None))
        C = _matrix("C", self.C, (None, n))
        D = _matrix("D", self.D, (C.shape[0], B.shape[1]))
        if self.hold is not None:
            object.__setattr__(self, "hold", _matrix("hold", self.hold, (n, B.shape[1])))
        dt = finite_scalar("dt", self.dt, minimum=0.0, strict=True, error=ConfigError)
        if isinstance(self.advance, bool) or not isinstance(self.advance, (int, np.integer)) or self.advance < 0:
            raise ConfigError(f"advance must be a whole number of samples >= 0, got {self.advance!r}")
        delays = tuple(float(d) for d in self.output_delays)
        if delays and (len(delays) != C.shape[0] or not all(math.isfinite(d) for d in delays)):
            raise ConfigError(f"output_delays: one finite delay per output ({C.shape[0]}), got {delays!r}")
        object.__setattr__(self, "output_delays", delays if any(delays) else ())
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "B", B)
        object.__setattr__(self, "C", C)
        object.__setattr__(self, "D", D)
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "input_names", _names("input", self.input_names or None, B.shape[1], "u"))
        object.__setattr__(self, "output_names", _names("output", self.output_names or None, C.shape[0], "y"))
        object.__setattr__(self, "state_names", _names("state", self.state_names or None, n, "x"))

    @property
    def nstates(self) -> int:
        """Number of states."""
        return self.A.shape[0]

    @property
    def ninputs(self) -> int:
        """Number of inputs."""
        return self.B.shape[1]

    @property
    def noutputs(self) -> int:
        """Number of outputs."""
        return self.C.shape[0]

    def poles(self) -> np.ndarray:
        """Eigenvalues of ``A``."""
        return np.linalg.eigvals(self.A)

    def spectral_radius(self) -> float:
        """Largest modulus of the eigenvalues of ``A``."""
        return float(np.max(np.abs(self.poles()))) if self.nstates else 0.0

    def similarity(self, T: np.ndarray, state_names: Sequence[str] | None = None) -> "DiscreteStateSpace":
        """The same system in coordinates ``x = T z`` (a new object)."""
        Ti = np.linalg.inv(T)
        return DiscreteStateSpace(Ti @ self.A @ T, Ti @ self.B, self.C @ T, self.D, self.dt,
                                  self.input_names, self.output_names, tuple(state_names or ()),
                                  advance=self.advance, output_delays=self.output_delays)

    def to_control(self):
        """Convert to a :class:`control.StateSpace` (discrete, named signals), the channels' converter delays
        (``output_delays``) realised as delay-line states (:func:`ebb_model.acquisition.delay_line.delay_line`).

        Raises
        ------
        ConfigError
            The system reads its input ahead of the record (``advance`` > 0), which a StateSpace cannot say:
            realise it from :func:`ebb_model.acquisition.bandlimited.causal_config` (the design models do); or a
            delay has no causal delay line (ahead of the force, or a fraction of a sample too short).
        """
        import control

        from .acquisition.delay_line import delay_line

        if self.advance:
            raise ConfigError(f"this system reads its input {self.advance} samples ahead of the record (a band-limited "
                              "force between samples), which a StateSpace cannot carry: build it from "
                              "ebb_model.acquisition.bandlimited.causal_config(config)")
        s = delay_line(self)
        return control.ss(s.A, s.B, s.C, s.D, s.dt, inputs=list(s.input_names), outputs=list(s.output_names),
                          states=list(s.state_names))

    def __repr__(self) -> str:
        return (f"DiscreteStateSpace(nstates={self.nstates}, inputs={list(self.input_names)}, "
                f"outputs={list(self.output_names)}, dt={self.dt:g})")


def with_input_delays(A: np.ndarray, G: Sequence[np.ndarray], C: np.ndarray, D: np.ndarray, dt: float,
                      input_names: Sequence[str], output_names: Sequence[str], state_names: Sequence[str],
                      hold: np.ndarray | None = None, *, D_taps: np.ndarray | None = None,
                      advance: int = 0, output_delays: tuple[float, ...] = ()) -> DiscreteStateSpace:
    """``x[k+1] = A x[k] + Σ_j G[j] u[k − j]`` (``j = 0 … d``) as one system, past inputs as delay states.

    State ``(x, u[k−1], …, u[k−d])``; a start at rest has ``x[0] = −hold·u[0]`` and the delay line at ``u[0]``
    (the input constant before the record), encoded in the returned system's ``hold``.  ``D_taps`` (p, m·d), when
    given, is the feedthrough of the past samples (column ``(j − 1) m + l``: input ``l`` at sample ``k − j``),
    read from the delay states; ``advance`` and ``output_delays`` are passed on (:class:`DiscreteStateSpace`).
    """
    d = len(G) - 1
    nx, m = np.shape(G[0])
    if d == 0:
        return DiscreteStateSpace(A, G[0], C, D, dt, tuple(input_names), tuple(output_names), tuple(state_names),
                                  hold, advance, output_delays)
    n = nx + d * m
    Af = np.zeros((n, n))
    Af[:nx, :nx] = A
    for j in range(1, d + 1):
        Af[:nx, nx + (j - 1) * m:nx + j * m] = G[j]
        if j < d:                                         # u[k−j−1]⁺ = u[k−j]
            Af[nx + j * m:nx + (j + 1) * m, nx + (j - 1) * m:nx + j * m] = np.eye(m)
    B = np.vstack([G[0], np.eye(m), np.zeros(((d - 1) * m, m))])
    Cf = np.hstack([C, np.zeros((np.shape(C)[0], d * m)) if D_taps is None else D_taps])
    h = np.vstack([hold if hold is not None else np.zeros((nx, m)), -np.tile(np.eye(m), (d, 1))])
    names = tuple(state_names) + tuple(f"{u}[k-{j}]" for j in range(1, d + 1) for u in input_names)
    return DiscreteStateSpace(Af, B, Cf, D, dt, tuple(input_names), tuple(output_names), names, h, advance,
                              output_delays)
