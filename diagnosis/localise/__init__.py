"""Where model and measurement disagree: :func:`localise` (``core``) and its parts.

``core`` — the localisation itself (per sensor, mode, band, time window, amplitude level, residual tests);
``spectra`` — input checks, FRF estimates, local SDOF fits, the data's best linear prediction;
``trends`` — time and amplitude trends, residual whiteness and input cross-correlation;
``results`` — the result types; ``summary`` — what is significant, in words; ``thresholds`` — the constants.
"""
from __future__ import annotations

from .core import localise
from .results import (AmplitudeGap, BandGap, CrossCorrelation, Localisation, ModeGap, SensorGap, Whiteness,
                      WindowGap)
from .spectra import FrfEstimate, choose_nperseg, estimate_frf
from .residual_tests import residual_correlations

__all__ = [
    "AmplitudeGap",
    "BandGap",
    "CrossCorrelation",
    "FrfEstimate",
    "Localisation",
    "ModeGap",
    "SensorGap",
    "Whiteness",
    "WindowGap",
    "choose_nperseg",
    "estimate_frf",
    "localise",
    "residual_correlations",
]
