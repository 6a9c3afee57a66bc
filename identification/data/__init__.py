"""Experiment data for the identification: measured inputs and outputs tied to a beam config.

An :class:`Experiment` is an immutable value (time, input forces, measured
outputs, names, SI units, source).  :func:`load_experiment` reads one from a
CSV, NPZ, MATLAB, LabVIEW ``.lvm`` or UFF58 file, maps the file's channels to
the config's actuators and sensors, converts units to SI (lbf -> N, g ->
m/s2, ...), optionally removes offsets and resamples to the config's dt, and
checks everything, raising :class:`ebb_model.errors.DataError` with the file,
column and sample of the problem.  :func:`load_experiments` loads several
experiments to be fitted together.

Example (the ARTS-Lab record, ``../shared/data/arts-lab-cantilever/``)::

    from ebb_model import load_config
    from identification.data import load_experiment

    cfg = load_config("examples/arts_cantilever.toml")
    exp = load_experiment("../shared/data/arts-lab-cantilever/test_1_3200Hz.lvm", cfg,
                          mapping={"force": 2, "accel": 3}, units={"force": "lbf", "accel": "g"},
                          remove_offset="mean")
    fit, holdout = exp.split(0.8)
"""
from .experiment import Experiment
from .loaders import EXTENSIONS, FORMATS, OFFSET_MODES, load_experiment, load_experiments
from .timebase import regularise_time, resample_uniform
from .units import LBF, STANDARD_GRAVITY, UNITS, to_si_factor

__all__ = [
    "Experiment",
    "load_experiment",
    "load_experiments",
    "FORMATS",
    "EXTENSIONS",
    "OFFSET_MODES",
    "UNITS",
    "LBF",
    "STANDARD_GRAVITY",
    "to_si_factor",
    "regularise_time",
    "resample_uniform",
]
