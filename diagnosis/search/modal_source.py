"""The measured modes a diagnosis compares its patterns with: estimated once from the fit windows, starting from
the baseline's modes or, when those miss a mode, from the records' own stable poles
(:func:`modal_source`; :mod:`diagnosis.search.modal_pattern` compares them)."""
from __future__ import annotations

from typing import Callable

import numpy as np

from ebb_model.acquisition.channel_delay import effective_delays
from identification.start_modes import alignment_miss
from identification.record_poles import record_modes

from ..problem.fitting import GapProblem
from .modal_estimate import SEARCH, MeasuredModes, estimate_modes, seen
from .modal_pattern import modal_evidence
from .mode_match import ModalEvidence

__all__ = ["SCALES", "modal_source"]

#: Ratios of the model's modes to the records' tried for their common scale (:func:`_recorded_start`): 0.25 % steps.
SCALES = np.geomspace(0.25, 4.0, 1111)


def _recorded_start(rec_hz: np.ndarray, rec_zeta: np.ndarray, support: np.ndarray, model_hz: np.ndarray,
                    model_zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where a scan starts from the records' stable poles ``rec_hz`` (their damping ``rec_zeta`` and
    stability-chart ``support``): those poles, and the model's modes ``model_hz`` above the highest of them,
    scaled by the common ratio that best places the records' poles on the model's modes
    (:func:`identification.start_modes.alignment_miss`, over :data:`SCALES`).  The model's modes above the records'
    are fitted, not held: the first mode above a band's edge is excited by the filter's skirt, and held at a
    baseline's frequency 17 % off it left 2.2 noise variances on a velocity sensor where fitted leaves 0.99."""
    misses = [alignment_miss(rec_hz, support, r * model_hz) for r in SCALES]
    scaled = SCALES[int(np.argmin(misses))] * model_hz
    above = scaled > rec_hz.max() * (1.0 + SEARCH)
    return np.concatenate([rec_hz, scaled[above]]), np.concatenate([rec_zeta, model_zeta[above]])


def modal_source(problem: GapProblem, freq_hz: np.ndarray, damping: np.ndarray, above_hz: np.ndarray,
                  band_hz: float) -> Callable[[np.ndarray], ModalEvidence]:
    """The measured modes' evidence at baseline unknowns ``beta`` (:func:`modal_evidence`); the modes
    are estimated from the fit windows once, when first asked for, starting from the baseline's ``freq_hz``.

    Only the modes the baseline puts inside the excited band (up to ``band_hz``) and estimated inside it (the
    first always) are evidence: a mode above it is seen only through the band's edge, and its oscillator takes up
    what the others leave — its frequency, with a standard error that knows nothing of that, can be far from any
    mode (measured: a cantilever's fourth mode at 60.8 Hz, the top of a 60 Hz multisine, estimated at 74.9 Hz 73
    standard errors away, which then dominated every modal match) or land on the edge inside the band (a
    compressed beam's fifth mode, 118.6 Hz, above a 2–100 Hz sweep, estimated at 99.0 Hz in one run).  It still
    takes part in the modal fit as a regressor; so does an oscillator the records do not need
    (:func:`~diagnosis.search.modal_estimate.seen`), and the set is ordered by frequency.  When the scan from the
    baseline's modes leaves more than the gap threshold (a mode outside every scan window: a baseline that
    compensated an effect holds its modes in the wrong places), the scan starts again from the records' own stable poles
    (:func:`identification.record_poles.record_modes`) and the estimate that leaves less is kept (measured: a
    clamped–pinned beam with a withheld stiff spring, the baseline's modes 1.3× the records', 2.78 noise variances
    left from the baseline's modes).  The match with the model passes over the modes the records do not show
    (:func:`~diagnosis.search.mode_match.matched`)."""
    measured: list[MeasuredModes] = []

    def evidence(beta: np.ndarray) -> ModalEvidence:
        if not measured:
            fit = [r for r in problem.records if r.has_fit]
            inputs, outputs = [r.inputs[:r.fit_end] for r in fit], [r.outputs[:r.fit_end] for r in fit]
            delays = effective_delays(problem.config)

            def estimate(f0: np.ndarray, z0: np.ndarray, above: np.ndarray | tuple[()]) -> MeasuredModes:
                modes = estimate_modes(inputs, outputs, problem.noise_std, problem.config.time.dt, f0, z0,
                                       above_hz=above, bandlimited=problem.config.time.input_hold == "bandlimited",
                                       delays=delays)
                keep = (modes.freq_hz <= band_hz) & (f0 <= band_hz) & seen(modes)
                keep[0] = True
                return modes.select(keep).in_order()

            found = estimate(freq_hz, damping, above_hz)
            if found.gap_ratio > 1.0 + problem.settings.gap_threshold:
                # the scan from the model's modes misses one: from the records' own stable poles instead
                recorded = record_modes(inputs, outputs, problem.config.time.dt, delays)
                inside = recorded.frequencies_hz <= band_hz
                if np.any(inside):
                    f0, z0 = _recorded_start(recorded.frequencies_hz[inside], recorded.damping[inside],
                                             recorded.support[inside], np.concatenate([freq_hz, above_hz]),
                                             np.concatenate([damping, damping[-1:] * np.ones(len(above_hz))]))
                    other = estimate(f0, z0, ())
                    found = other if other.gap_ratio < found.gap_ratio else found
            measured.append(found)
        return modal_evidence(problem, beta, measured[0])

    return evidence
