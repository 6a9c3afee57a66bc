"""The diagnosis' candidates stage: the catalogue of effects for the fitted baseline, their search bounds set by
its scales."""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ebb_model.assemble import field_config
from ebb_model.config import BeamConfig
from ebb_model.simulate import fast_model, simulate

from ..problem.axial_terms import stretch_of_nodes
from ..effects import Catalogue, Scales
from ..effects.delay import read_delay
from ..problem.augmented import simulate_effects
from ..problem.fitting import GapProblem
from ..problem.records import Record

__all__ = ["catalogue_of"]


def catalogue_of(problem: GapProblem, base_cfg: BeamConfig, base_params: Mapping[str, float], mf: np.ndarray,
               f_hi: float, *, absent: frozenset[str] = frozenset()) -> Catalogue:
    """The candidate effects of the fitted baseline, their search bounds set by its scales (the in-band modes
    ``mf`` [Hz], the excited band's top ``f_hi`` [Hz], the fit records' length and largest stretch); none that
    models a rig part ``absent`` from the records' set-up (:mod:`diagnosis.setups`)."""
    fit_records = [r for r in problem.records if r.has_fit]
    scales = Scales(EI=base_params["EI"], rhoA=base_params["rhoA"], N=base_params["N"],
                    length=base_cfg.beam.length, omega_low=2 * np.pi * float(mf[0]),
                    omega_high=2 * np.pi * max(float(mf[-1]), f_hi),
                    duration=max(r.fit_end for r in fit_records) * base_cfg.time.dt,
                    stretch_max=stretch_max(base_cfg, base_params, fit_records),
                    output_rms=tuple(float(v) for v in np.sqrt(np.mean(np.concatenate(
                        [r.outputs[:r.fit_end] for r in fit_records]) ** 2, axis=0))),
                    read_delay=read_delay([(r.outputs[:r.fit_end], simulate_effects(base_cfg, base_params,
                                                                                   r.inputs[:r.fit_end]))
                                           for r in fit_records]))
    return Catalogue(base_cfg, scales, tuple(problem.space.names), absent=absent)


def stretch_max(config: BeamConfig, params: Mapping[str, float], records: Sequence[Record]) -> float:
    """Largest ``∫ w_x² dx`` of the baseline response over the records.

    The deflection at every grid node (:func:`ebb_model.field_config`) and the
    integral of its piecewise-linear interpolant — the quadrature the
    stretching simulation itself uses (:func:`diagnosis.problem.axial_terms.stretch_of_nodes`).
    """
    n_s = len(config.sensors)
    model = fast_model(field_config(config), params)
    h = config.beam.length / (config.beam.nodes + 1)
    best = 0.0
    for r in records:
        w = simulate(model, r.inputs).outputs[:, n_s:]
        best = max(best, float(np.max(stretch_of_nodes(w, h))))
    return best
