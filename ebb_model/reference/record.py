"""The result of the blind data generator: one synthetic experiment (:class:`SyntheticRecord`)."""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np

from ..io.output import atomic_path
from ..errors import DataError
from .withheld import WithheldEffect

__all__ = ["SyntheticRecord"]


@dataclass(frozen=True, eq=False)
class SyntheticRecord:
    """A synthetic experiment.

    Attributes
    ----------
    time
        Sample instants :math:`t_k = k\\,\\Delta t` [s], shape ``(n,)``.
    inputs
        The measured actuator forces [N] exactly as given, ``(n, n_inputs)``.
    outputs_clean
        Noise-free sensor outputs (SI units), ``(n, n_outputs)``.
    outputs
        ``outputs_clean`` plus white Gaussian noise.
    noise_std
        Standard deviation of the added noise per sensor, ``(n_outputs,)``.
    input_names, output_names
        Actuator and sensor names of the config, in column order.
    parameters
        Physical parameters used (config values with ``params`` overrides,
        *without* the withheld effect).
    effects
        The withheld effects applied (empty: none).
    n_elements, substeps, richardson, interpolation, integrator
        Discretisation of the generator (``integrator``: ``"exact"`` or ``"newmark"``).
    """

    time: np.ndarray
    inputs: np.ndarray
    outputs_clean: np.ndarray
    outputs: np.ndarray
    noise_std: np.ndarray
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    parameters: Mapping[str, float]
    effects: tuple[WithheldEffect, ...]
    n_elements: int
    substeps: int
    richardson: bool
    interpolation: str
    integrator: str

    @property
    def dt(self) -> float:
        """Sample interval [s]."""
        return float(self.time[1] - self.time[0])

    def to_csv(self, path: str | Path, *, clean: bool = False) -> Path:
        """Write ``time``, the inputs and the (noisy, or ``clean``) outputs as a CSV file with a header row.

        The file has one column per actuator and sensor, named as in the
        config, so it loads with the project's CSV experiment reader.  The
        withheld effect is deliberately **not** written.
        """
        p = Path(path)
        y = self.outputs_clean if clean else self.outputs
        table = np.column_stack([self.time, self.inputs, y])
        try:
            with atomic_path(p) as tmp, tmp.open("w", newline="", encoding="utf-8") as fh:
                wr = csv.writer(fh)
                wr.writerow(("time",) + self.input_names + self.output_names)
                for row in table:
                    wr.writerow([repr(float(v)) for v in row])
        except OSError as exc:
            raise DataError(f"{p}: cannot write ({exc.strerror or exc})") from None
        return p
