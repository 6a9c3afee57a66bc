"""Package the beam model as an FMI 2.0 co-simulation FMU (pythonfmu + a C loader).

Flat functional API in FMPy's style::

    from fmu_build import build_fmu
    build_fmu("examples/seed_clamped.toml", "beam.fmu", field=False)
    build_standalone_fmu("examples/seed_clamped.toml", "beam_c.fmu")   # C, no Python at run time

The ``ebb build-fmu`` sub-command lives in :mod:`ebb_cli.fmu`.  See docs/fmu.md.
"""
from .builder import build_fmu
from .standalone import build_standalone_fmu

__all__ = ["build_fmu", "build_standalone_fmu"]
