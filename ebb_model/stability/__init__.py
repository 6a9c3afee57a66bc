"""Stability of the θ-scheme: Bistritz zero-location test and the dispersion relation."""
from .bistritz import ZeroLocation, bistritz, bistritz_sequence
from .dispersion import (
    StabilityReport,
    analyse_stability,
    bistritz_values,
    critical_wavenumbers,
    dispersion_coefficients,
    grid_omega_max,
    growth_factors,
    max_growth_factor,
    stability_bounds,
    wavenumbers,
)

__all__ = [
    "ZeroLocation", "bistritz", "bistritz_sequence", "StabilityReport", "analyse_stability",
    "bistritz_values", "critical_wavenumbers", "dispersion_coefficients", "grid_omega_max",
    "growth_factors", "max_growth_factor", "stability_bounds", "wavenumbers",
]
