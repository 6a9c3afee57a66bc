"""An experiment: time vector, input forces and measured outputs, with names and SI units.

An :class:`Experiment` is an immutable value (python-control's
``TimeResponseData`` habit, minus the mutability): every array passes through
one normaliser that makes a read-only float copy and reports a wrong shape as
``"inputs has shape (100, 2), expected (100, 1)"``.  Operations
(:meth:`Experiment.select`, :meth:`Experiment.split`) return new objects.
"""
from __future__ import annotations

import json
import math
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import BinaryIO, Mapping

import numpy as np

from ebb_model.arrays import as_matrix
from ebb_model.io.output import atomic_path
from ebb_model.config import BeamConfig
from ebb_model.errors import DataError
from ebb_model.io.signals_io import check_time_vector

__all__ = ["Experiment", "NPZ_META_KEY"]

#: Key of the JSON metadata entry written by :meth:`Experiment.to_npz`.
NPZ_META_KEY = "__experiment__"


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float, copy=True)
    a.setflags(write=False)
    return a


def _matrix(name: str, value: object, n: int, k: int, where: str) -> np.ndarray:
    if k == 0 and np.asarray(value).shape == (n, 0):     # no signal of this kind: a record without a force
        return _frozen(np.zeros((n, 0)))
    return as_matrix(value, f"{where}: {name}", shape=(n, k), finite=False, readonly=True)


def _savez(fh: BinaryIO, /, **arrays: np.ndarray) -> None:
    """``np.savez(fh, **arrays)`` (the same archive) for any names: savez takes a signal named ``file`` or
    ``allow_pickle`` for its own argument (a TypeError, or the signal left out of the file)."""
    with zipfile.ZipFile(fh, mode="w", compression=zipfile.ZIP_STORED, allowZip64=True) as zf:
        for key, val in arrays.items():
            with zf.open(key + ".npy", "w", force_zip64=True) as fid:
                np.lib.format.write_array(fid, np.asanyarray(val), allow_pickle=True)


@dataclass(frozen=True, eq=False)
class Experiment:
    """One measured experiment, tied by its signal names to a beam config.

    Parameters
    ----------
    name
        Short name (the file stem by default); used to label objectives.
    time
        Sample times [s], shape (n,), finite and strictly increasing.
    inputs
        Actuator forces [N], shape (n, n_in), columns named by ``input_names``.
    outputs
        Sensor signals [SI], shape (n, n_out), columns named by ``output_names``.
    input_names, output_names
        Signal names as in the config's actuators and sensors.
    units
        SI unit of every signal, ``{"force": "N", "accel": "m/s2", ...}``.
    source
        Where the data came from (a file path), used in error messages.

    Raises
    ------
    DataError
        Wrong shapes, duplicate names, non-finite values (naming the signal and
        the sample) or a time vector that is not strictly increasing.
    """

    name: str
    time: np.ndarray
    inputs: np.ndarray
    outputs: np.ndarray
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    units: Mapping[str, str] = field(default_factory=lambda: MappingProxyType({}))
    source: str = ""

    def __post_init__(self) -> None:
        where = self.source or self.name or "experiment"
        t = np.asarray(self.time, dtype=float)
        if t.ndim != 1:
            raise DataError(f"{where}: time has shape {t.shape}, expected (n,)")
        check_time_vector(t, where=f"{where}: time")
        n = t.size
        in_names = tuple(str(s) for s in self.input_names)
        out_names = tuple(str(s) for s in self.output_names)
        names = in_names + out_names
        dup = sorted({s for s in names if names.count(s) > 1})
        if dup:
            raise DataError(f"{where}: signal name(s) used more than once: {', '.join(dup)}")
        u = _matrix("inputs", self.inputs, n, len(in_names), where)
        y = _matrix("outputs", self.outputs, n, len(out_names), where)
        for label, arr, cols in (("input", u, in_names), ("output", y, out_names)):
            bad = np.argwhere(~np.isfinite(arr))
            if bad.size:
                i, j = bad[0]
                raise DataError(f"{where}: {label} {cols[j]!r} has a non-finite value ({float(arr[i, j])!r}) "
                                f"at sample {i} (t = {t[i]:.9g} s)")
        units = {str(k): str(v) for k, v in dict(self.units).items()}
        extra = sorted(set(units) - set(names))
        if extra:
            raise DataError(f"{where}: units given for unknown signal(s) {', '.join(extra)}")
        object.__setattr__(self, "time", _frozen(t))
        object.__setattr__(self, "inputs", u)
        object.__setattr__(self, "outputs", y)
        object.__setattr__(self, "input_names", in_names)
        object.__setattr__(self, "output_names", out_names)
        object.__setattr__(self, "units", MappingProxyType(units))

    # ------------------------------------------------------------------ access
    @property
    def n_samples(self) -> int:
        """Number of samples n."""
        return int(self.time.size)

    @property
    def dt(self) -> float:
        """Mean sample time ``(t[-1] - t[0]) / (n - 1)`` [s] (NaN for a single sample)."""
        n = self.time.size
        return float((self.time[-1] - self.time[0]) / (n - 1)) if n > 1 else math.nan

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` [s]."""
        return float(self.time[-1] - self.time[0])

    def signal(self, name: str) -> np.ndarray:
        """The column of one input or output signal, shape (n,)."""
        if name in self.input_names:
            return self.inputs[:, self.input_names.index(name)]
        if name in self.output_names:
            return self.outputs[:, self.output_names.index(name)]
        raise DataError(f"{self.source or self.name}: no signal {name!r}; "
                        f"have {', '.join(self.input_names + self.output_names)}")

    # -------------------------------------------------------------- validation
    def check_against(self, config: BeamConfig, *, rtol: float = 1e-6) -> None:
        """Check that this experiment can be compared with simulations of ``config``.

        * the inputs are exactly the config's actuators, in the config's order
          (the model needs every input force);
        * every output is one of the config's sensors;
        * the samples are uniform at ``config.time.dt`` within ``rtol``
          (:func:`ebb_model.io.signals_io.check_time_vector`, the one timebase rule).

        Raises
        ------
        DataError
            Listing every mismatch of names at once; the first sample whose
            step disagrees with ``dt``.
        """
        where = self.source or self.name
        problems: list[str] = []
        if self.input_names != config.input_names:
            missing = [a for a in config.input_names if a not in self.input_names]
            unknown = [a for a in self.input_names if a not in config.input_names]
            if missing:
                problems.append(f"actuator(s) of the config without data: {', '.join(missing)}")
            if unknown:
                problems.append(f"input(s) that are not actuators of the config: {', '.join(unknown)} "
                                f"(actuators: {', '.join(config.input_names)})")
            if not missing and not unknown:
                problems.append(f"inputs are ordered {', '.join(self.input_names)}, the config's actuators "
                                f"{', '.join(config.input_names)}")
        unknown_out = [s for s in self.output_names if s not in config.output_names]
        if unknown_out:
            problems.append(f"output(s) that are not sensors of the config: {', '.join(unknown_out)} "
                            f"(sensors: {', '.join(config.output_names)})")
        if self.time.size < 2:
            problems.append("needs at least 2 samples")
        if problems:
            if len(problems) == 1:
                raise DataError(f"{where}: {problems[0]}")
            raise DataError(f"{where}: {len(problems)} problems:\n" + "\n".join(f"  - {p}" for p in problems))
        check_time_vector(self.time, config.time.dt, where=f"{where}: time", rtol=rtol)

    # ---------------------------------------------------------------- slicing
    def select(self, t0: float | None = None, t1: float | None = None, *, name: str | None = None
               ) -> "Experiment":
        """The samples with ``t0 <= t < t1`` (absolute times kept) as a new experiment.

        ``None`` means "from the start" / "to the end".  A segment that starts
        mid-record does not start from rest: a simulation compared with it
        needs the initial state (or a discarded transient).

        Raises
        ------
        DataError
            If the window contains no sample.
        """
        lo = -np.inf if t0 is None else float(t0)
        hi = np.inf if t1 is None else float(t1)
        keep = (self.time >= lo) & (self.time < hi)
        if not keep.any():
            raise DataError(f"{self.source or self.name}: no sample in the window [{lo:g}, {hi:g}) s; "
                            f"the record spans [{self.time[0]:g}, {self.time[-1]:g}] s")
        return self._subset(keep, name or self.name)

    def split(self, fraction: float) -> tuple["Experiment", "Experiment"]:
        """Split in time into a fitting part (the first ``fraction`` of the samples) and a hold-out.

        Returns
        -------
        fit, holdout : Experiment
            Named ``"<name>_fit"`` and ``"<name>_holdout"``.

        Raises
        ------
        DataError
            Unless ``0 < fraction < 1`` leaves at least one sample on each side.
        """
        f = float(fraction)
        k = int(round(f * self.n_samples))
        if not 0.0 < f < 1.0 or not 0 < k < self.n_samples:
            raise DataError(f"{self.source or self.name}: split fraction {fraction!r} must lie in (0, 1) "
                            f"and leave samples on both sides of {self.n_samples}")
        idx = np.arange(self.n_samples)
        return self._subset(idx < k, f"{self.name}_fit"), self._subset(idx >= k, f"{self.name}_holdout")

    def _subset(self, keep: np.ndarray, name: str) -> "Experiment":
        return Experiment(name=name, time=self.time[keep], inputs=self.inputs[keep], outputs=self.outputs[keep],
                          input_names=self.input_names, output_names=self.output_names, units=self.units,
                          source=self.source)

    # ----------------------------------------------------------------- export
    def to_npz(self, path: str | Path) -> Path:
        """Write ``time`` and one array per signal (SI units) to an ``.npz`` file.

        Names, units and source go to a JSON entry ``__experiment__``, so that
        :func:`~identification.data.load_experiment` reads the file back with
        the same names and units (no pickling involved).

        Returns
        -------
        pathlib.Path
            The file written.
        """
        p = Path(path)
        meta = {"name": self.name, "input_names": list(self.input_names),
                "output_names": list(self.output_names), "units": dict(self.units), "source": self.source}
        arrays = {"time": np.asarray(self.time)}
        for j, s in enumerate(self.input_names):
            arrays[s] = np.asarray(self.inputs[:, j])
        for j, s in enumerate(self.output_names):
            arrays[s] = np.asarray(self.outputs[:, j])
        with atomic_path(p) as tmp, tmp.open("wb") as fh:
            _savez(fh, **arrays, **{NPZ_META_KEY: np.array(json.dumps(meta))})
        return p

    def to_csv(self, path: str | Path) -> Path:
        """Write ``time`` and one column per signal (SI units, full precision) to a CSV file."""
        p = Path(path)
        header = ",".join(("time",) + self.input_names + self.output_names)
        data = np.column_stack([self.time, self.inputs, self.outputs])
        with atomic_path(p) as tmp:
            np.savetxt(tmp, data, delimiter=",", header=header, comments="", fmt="%.17g")
        return p

    def __repr__(self) -> str:
        return (f"Experiment(name={self.name!r}, n_samples={self.n_samples}, dt={self.dt:.6g}, "
                f"inputs={list(self.input_names)}, outputs={list(self.output_names)}, source={self.source!r})")

