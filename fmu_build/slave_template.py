"""The beam as a pythonfmu (FMI 2.0) co-simulation slave: a thin adapter over ``ebb_model``.

The model, its variables and its step are :class:`fmu_build.slave_base.BeamModel`'s (shared with the FMI 3.0
slave, ``slave_template_fmi3``); this module binds them to pythonfmu's ``Fmi2Slave`` calls.  Semantics (see
``slave_base``): at ``t_k`` the master sets ``u_k``; ``fmi2GetReal`` returns ``y_k = C x_k + D u_k``;
``fmi2DoStep(t_k, h)`` with ``h = n dt`` applies the recursion ``n`` times with ``u`` held, any other ``h`` is
refused.  The deflection field is ``nodes + 2`` scalar outputs ``w[i]`` (FMI 2.0 has no arrays).

Errors never escape as Python exceptions, which pythonfmu would report as
``fmi2Fatal``: they are logged with status ``fmi2Error`` and the FMU's C
loader returns ``fmi2Error`` for that call (see ``loader.c``).

This module is a template.  :func:`fmu_build.builder.build_fmu` copies it into
the FMU's resources as ``<modelIdentifier>_slave.py`` with the class renamed
and its import of ``slave_base`` pointing at the FMU's copy of it (``<modelIdentifier>_base.py``, whose
``CORE_PACKAGE`` names the FMU's private copy of ``ebb_model``), so that FMUs built from different configs can
run side by side in one process (pythonfmu imports the slave module by name and Python caches it).
"""
from __future__ import annotations

from typing import Any, Sequence

from fmu_build.slave_base import (CORE_MODULES, CORE_PACKAGE, FIELD_NAME, MODEL_FILE, REQUIRED_PACKAGES,
                                  SPEC_FILE, STEP_TOLERANCE, BeamModel)
from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Status

__all__ = ["BeamSlave", "CORE_PACKAGE", "CORE_MODULES", "SPEC_FILE", "STEP_TOLERANCE", "FIELD_NAME",
           "REQUIRED_PACKAGES", "MODEL_FILE"]


class BeamSlave(BeamModel, Fmi2Slave):
    """pythonfmu slave iterating the beam's discrete state-space system (:class:`~fmu_build.slave_base.BeamModel`).

    Parameters
    ----------
    **kwargs
        Passed by pythonfmu: ``instance_name``, ``resources`` (directory with
        :data:`SPEC_FILE`), ``visible``, ``logger``.
    """

    FMI = "fmi2"
    ERROR_STATUS = Fmi2Status.error

    def __init__(self, **kwargs: Any) -> None:
        Fmi2Slave.__init__(self, **kwargs)
        self._init_model(kwargs.get("resources"))
        self.default_experiment = DefaultExperiment(start_time=0.0, step_size=self._dt)

    # ----------------------------------------------------------- variables
    def _real_variable(self, name: str, getter: Any, *, causality: str, variability: str | None, description: str,
                       unit: str | None, size: int) -> Any:
        kw = {} if variability is None else {"variability": Fmi2Variability[variability]}
        return Real(name, causality=Fmi2Causality[causality], description=description, getter=getter, **kw)

    def _constant_variable(self, name: str, value: float | int | str, description: str, unit: str | None) -> Any:
        cls = {float: Real, int: Integer, str: String}[type(value)]
        return cls(name, causality=Fmi2Causality.calculatedParameter, variability=Fmi2Variability.fixed,
                   description=description, getter=lambda: value)

    def _add_field(self, xs: Sequence[float]) -> None:
        for i, x in enumerate(xs):
            self._add_real(f"{FIELD_NAME}[{i}]", float("nan"), "m", None, causality="output",
                           description=f"deflection at grid node x = {x:g} m")

    # ----------------------------------------------------------- FMI calls
    def setup_experiment(self, start_time: float = 0.0, *args: Any) -> None:
        pass

    def enter_initialization_mode(self) -> None:
        pass

    def exit_initialization_mode(self) -> None:
        self._exit_initialization()

    def do_step(self, current_time: float, step_size: float) -> bool:
        return self._advance(step_size)

    def terminate(self) -> None:
        pass

    def get_real(self, vrs: Sequence[int]) -> list[float]:
        return self._read("GetReal", vrs)

    def set_real(self, vrs: Sequence[int], values: Sequence[float]) -> None:
        self._write("SetReal", vrs, values)

    def get_integer(self, vrs: Sequence[int]) -> list[int]:
        try:
            return super().get_integer(vrs)
        except Exception as exc:
            self._error("GetInteger", f"{type(exc).__name__}: {exc}")
            return [0] * len(vrs)

    def get_boolean(self, vrs: Sequence[int]) -> list[bool]:
        self._error("GetBoolean", "this FMU has no Boolean variables")
        return [False] * len(vrs)

    def get_string(self, vrs: Sequence[int]) -> list[str]:
        try:
            return super().get_string(vrs)
        except Exception as exc:
            self._error("GetString", f"{type(exc).__name__}: {exc}")
            return [""] * len(vrs)

    def set_integer(self, vrs: Sequence[int], values: Sequence[int]) -> None:
        self._refuse("SetInteger", vrs)

    def set_boolean(self, vrs: Sequence[int], values: Sequence[bool]) -> None:
        self._refuse("SetBoolean", vrs)

    def set_string(self, vrs: Sequence[int], values: Sequence[str]) -> None:
        self._refuse("SetString", vrs)
