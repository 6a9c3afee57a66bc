"""The standalone C FMU of the beam (FMI 2.0 model exchange + co-simulation, no Python at run time).

::

    from fmu_build.standalone import build_standalone_fmu
    build_standalone_fmu("examples/seed_clamped.toml", "beam.fmu")

See :mod:`fmu_build.standalone.builder` and the "Standalone FMU" section of docs/fmu.md.
"""
from .builder import build_standalone_fmu, check_standalone

__all__ = ["build_standalone_fmu", "check_standalone"]
