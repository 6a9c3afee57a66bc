"""ebb_model — axially loaded Euler–Bernoulli beam as a discrete state-space system.

Data flow: :func:`load_config` (:mod:`ebb_model.config`) → :func:`discretise` (finite differences with ghost
nodes, :mod:`ebb_model.space`) → the modes (:mod:`ebb_model.modal`) → :func:`assemble`: the realisation exact in
time by default (:mod:`ebb_model.exact`), the seed's three-level θ-scheme on request (:func:`discretise_time`,
:mod:`ebb_model.theta`), the acquisition's channels on it (:mod:`ebb_model.acquisition`) → :func:`simulate`
(compiled recursion; modal fast path :func:`fast_model`); analysis with :func:`modes`, :func:`frequency_response`
and :func:`analyse_stability` (Bistritz test of the θ-scheme's dispersion relation, :mod:`ebb_model.stability`).
Files in and out: :mod:`ebb_model.io`.
"""
from .acquisition.bandlimited import causal_config
from .assemble import assemble, assemble_modal, check_stable, field_config, field_matrix
from .beam import PARAMETER_NAMES, Actuator, End, PointMass, Sensor
from .config import BeamConfig, ParameterSpec, config_from_dict, load_config
from .space.discretisation import SemiDiscreteBeam, discretise
from .errors import (ConfigError, ConfigWarning, DataError, DataWarning, EbbError, FmuError, OutputError,
                     ParameterError, StabilityError)
from .modal.modal import FrequencyResponse, ModalAnalysis, discrete_frequencies, frequency_response, modes
from .theta.modal_form import ModalStateSpace
from .simulate import SimulationResult, fast_model, simulate, simulate_batch, simulate_config
from .stability import StabilityReport, analyse_stability, bistritz, max_growth_factor, stability_bounds
from .statespace import DiscreteStateSpace
from .theta.theta_scheme import discretise_time

__version__ = "0.1.0"

__all__ = [
    "PARAMETER_NAMES", "Actuator", "End", "PointMass", "Sensor",
    "BeamConfig", "ParameterSpec", "config_from_dict", "load_config",
    "SemiDiscreteBeam", "discretise", "discretise_time", "DiscreteStateSpace", "ModalStateSpace",
    "assemble", "assemble_modal", "causal_config", "check_stable", "field_config", "field_matrix",
    "simulate", "simulate_config", "simulate_batch", "fast_model", "SimulationResult",
    "modes", "ModalAnalysis", "frequency_response", "FrequencyResponse", "discrete_frequencies",
    "analyse_stability", "StabilityReport", "bistritz", "max_growth_factor", "stability_bounds",
    "EbbError", "ConfigError", "ParameterError", "StabilityError", "DataError", "FmuError", "OutputError",
    "DataWarning", "ConfigWarning",
]
