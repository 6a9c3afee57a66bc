"""The beam as a pythonfmu3 (FMI 3.0) co-simulation slave: :class:`~fmu_build.slave_base.BeamModel` behind
``pythonfmu3.Fmi3Slave``'s calls.

The same model, variables, units, causalities and step as the FMI 2.0 slave (``slave_template``), with what
FMI 3.0 adds or names differently:

* the deflection field (``field=True``) is one ``Float64`` array ``w`` with one dimension (``nodes + 2``
  elements, read whole by ``fmi3GetFloat64``) instead of the scalars ``w[0] …``; pythonfmu3 expresses arrays
  (``Float64(..., dimensions=[Dimension(start=...)])``) and returns their elements flattened;
* the independent variable ``time`` (an FMI 3.0 model description has one): the communication point reached;
* Real variables are ``Float64``, Integer ``Int32``; ``fmi3DoStep`` returns its status (``Fmi3StepResult``).

Errors are logged with status ``fmi3Error`` and the FMU's C loader (``loader3.c``) returns that status for the
call; the loader also checks the number of values a host passes for the array (pythonfmu3's library does not)
and answers the calls this FMU does not support itself.

This module is a template: :func:`fmu_build.builder.build_fmu` copies it into the FMU's resources as
``<modelIdentifier>_slave.py`` with the class renamed and its import of ``slave_base`` pointing at the FMU's
copy; pythonfmu3 imports the module named in ``slavemodule.txt`` and looks there for the line defining a class
derived from ``Fmi3Slave``.
"""
from __future__ import annotations

from typing import Any, Sequence

from fmu_build.slave_base import FIELD_NAME, BeamModel
from pythonfmu3 import DefaultExperiment, Fmi3Causality, Fmi3Slave, Fmi3Variability, Float64, Int32, String
from pythonfmu3.enums import Fmi3Status
from pythonfmu3.fmi3slave import Fmi3StepResult
from pythonfmu3.variables import Dimension

__all__ = ["BeamSlave3"]

#: What ``do_step`` returns (pythonfmu3 reads its ``status``).
_STEPPED, _REFUSED = Fmi3StepResult(status=Fmi3Status.ok), Fmi3StepResult(status=Fmi3Status.error)


class BeamSlave3(BeamModel, Fmi3Slave):
    """pythonfmu3 slave iterating the beam's discrete state-space system.

    Parameters
    ----------
    **kwargs
        Passed by pythonfmu3: ``instance_name``, ``resources`` (directory with the FMU's spec), ``visible``,
        ``logger``.
    """

    FMI = "fmi3"
    ERROR_STATUS = Fmi3Status.error

    def __init__(self, **kwargs: Any) -> None:
        Fmi3Slave.__init__(self, **kwargs)
        self._init_model(kwargs.get("resources"))
        self._time_at = len(self._reals)
        self._add_real("time", 0.0, "s", None, causality="independent", variability="continuous",
                       description="the communication point reached")
        self.default_experiment = DefaultExperiment(start_time=0.0, step_size=self._dt)

    # ----------------------------------------------------------- variables
    def _real_variable(self, name: str, getter: Any, *, causality: str, variability: str | None, description: str,
                       unit: str | None, size: int) -> Any:
        kw: dict[str, Any] = {} if variability is None else {"variability": Fmi3Variability[variability]}
        if size > 1:
            kw["dimensions"] = [Dimension(start=str(size))]
        return Float64(name, causality=Fmi3Causality[causality], description=description, getter=getter, **kw)

    def _constant_variable(self, name: str, value: float | int | str, description: str, unit: str | None) -> Any:
        cls = {float: Float64, int: Int32, str: String}[type(value)]
        return cls(name, causality=Fmi3Causality.calculatedParameter, variability=Fmi3Variability.fixed,
                   description=description, getter=lambda: value)

    def _add_field(self, xs: Sequence[float]) -> None:
        self._add_real(FIELD_NAME, float("nan"), "m", None, causality="output", size=len(xs),
                       description=f"deflection at the {len(xs)} grid nodes x = {xs[0]:g} … {xs[-1]:g} m "
                                   "(boundary nodes included)")

    # ----------------------------------------------------------- FMI calls
    def enter_initialization_mode(self) -> None:
        pass

    def exit_initialization_mode(self) -> None:
        self._exit_initialization()

    def do_step(self, current_time: float, step_size: float) -> Fmi3StepResult:
        if self._advance(step_size):
            self._reals[self._time_at] = current_time + step_size
            return _STEPPED
        return _REFUSED

    def terminate(self) -> None:
        pass

    def get_float64(self, vrs: Sequence[int]) -> list[float]:
        return self._read("GetFloat64", vrs, elements=True)

    def set_float64(self, vrs: Sequence[int], values: Sequence[float]) -> None:
        self._write("SetFloat64", vrs, values)

    def get_int32(self, vrs: Sequence[int]) -> list[int]:
        try:
            return super().get_int32(vrs)
        except Exception as exc:
            self._error("GetInt32", f"{type(exc).__name__}: {exc}")
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

    def set_int32(self, vrs: Sequence[int], values: Sequence[int]) -> None:
        self._refuse("SetInt32", vrs)

    def set_boolean(self, vrs: Sequence[int], values: Sequence[bool]) -> None:
        self._refuse("SetBoolean", vrs)

    def set_string(self, vrs: Sequence[int], values: Sequence[str]) -> None:
        self._refuse("SetString", vrs)
