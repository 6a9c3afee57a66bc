"""One FMU, many parameter sets: the identified models as an SSP package (System Structure & Parameterization 1.0).

``export_ssp(result, …)`` writes ``<out_dir>/export/<config>.ssp``, a zip holding

* ``resources/beam.fmu`` — the standalone C FMU of the result's set-up (no Python at run time; parameters
  ``EI, rhoA, c, eta, N, rhoI, kf`` tunable), FMI 2.0 or, with ``fmi=3``, FMI 3.0 (the systems and parameter sets
  are the same: they name the component's variables, which both versions share);
* ``resources/<stem>.ssv`` — one parameter set (``ssv:ParameterSet``) per chosen Pareto / polished point, every
  physical parameter with its unit;
* ``SystemStructure.ssd`` — the system (one component ``beam`` with its inputs, outputs and parameters as
  connectors) bound to the default set: the identified model (the polished knee, else the knee);
* ``<stem>.ssd`` — the same system bound to each other set (SSP's variants), for a host to load instead.

Each system carries what masters need to run it without extra arguments: a default experiment (start 0, stop ten
periods of the lowest mode) with the base step ``dt`` in the annotations libcosim and OMSimulator read.

A point whose positions were identified has its own grid of forces and sensors, which one FMU cannot take as a
parameter: such results are refused (export FMUs per point instead).
"""
from __future__ import annotations

import math
import tempfile
import zipfile
from pathlib import Path
from typing import Sequence
from xml.sax.saxutils import quoteattr

from ebb_model.beam import PARAMETER_NAMES, PARAMETER_UNITS
from ebb_model.config import BeamConfig
from ebb_model.errors import ConfigError
from ebb_model.io.output import atomic_path, check_writable_dir, make_dir

from .export import chosen
from .result import IdentificationResult

__all__ = ["export_ssp", "check_ssp", "DEFAULT_SET"]

_NS = ('xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
       'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
       'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
       'xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations" '
       'xmlns:oms="https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd"')
#: The component's name in every system of the package.
COMPONENT = "beam"
#: The package's default system (bound to the identified model's parameter set).
DEFAULT_SET = "SystemStructure.ssd"


def _ssv(name: str, params: dict[str, float]) -> str:
    rows = "\n".join(f'      <ssv:Parameter name={quoteattr(k)}><ssv:Real value="{params[k]!r}" '
                     f'unit={quoteattr(PARAMETER_UNITS[k])}/></ssv:Parameter>' for k in PARAMETER_NAMES)
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet {_NS} version="1.0" name={quoteattr(name)}>\n'
            f"  <ssv:Parameters>\n{rows}\n  </ssv:Parameters>\n</ssv:ParameterSet>\n")


def _ssd(name: str, config: BeamConfig, bound: str, dt: float, stop: float) -> str:
    """The system: the component with its outputs and parameters as connectors, bound to the parameter set
    ``bound``; the default experiment with its stop time and the base step in the annotations libcosim
    (``osp:FixedStepAlgorithm``) and OMSimulator (``oms:FixedStepMaster``) read.  The inputs are not connectors:
    SSP 1.0 masters differ on unconnected ones (fmpy's ``simulate_ssp`` stops on an input no connection feeds;
    libcosim refuses a connection to the system's own connector) — a master sets them by the FMU's value
    references (libcosim's manipulators), the FMU's modelDescription declares them."""
    conns = [("output", n) for n in config.output_names] + [("parameter", k) for k in PARAMETER_NAMES]
    rows = "\n".join(f'          <ssd:Connector name={quoteattr(n)} kind="{kind}"><ssc:Real/></ssd:Connector>'
                     for kind, n in conns)
    step = repr(float(dt))
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription {_NS} version="1.0" '
            f'name={quoteattr(name)}>\n  <ssd:System name={quoteattr(name)}>\n    <ssd:Elements>\n'
            f'      <ssd:Component name="{COMPONENT}" source="resources/beam.fmu" '
            f'type="application/x-fmu-sharedlibrary">\n        <ssd:Connectors>\n{rows}\n        </ssd:Connectors>\n'
            f'        <ssd:ParameterBindings>\n          <ssd:ParameterBinding source="resources/{bound}.ssv"/>\n'
            f"        </ssd:ParameterBindings>\n      </ssd:Component>\n    </ssd:Elements>\n"
            f'    <ssd:Annotations>\n      <ssc:Annotation type="org.openmodelica">\n        <oms:Annotations>\n'
            f'          <oms:SimulationInformation>\n            <oms:FixedStepMaster description="oms-ma" '
            f'stepSize="{step}"/>\n          </oms:SimulationInformation>\n        </oms:Annotations>\n'
            f"      </ssc:Annotation>\n    </ssd:Annotations>\n  </ssd:System>\n"
            f'  <ssd:DefaultExperiment startTime="0.0" stopTime="{stop!r}">\n    <ssd:Annotations>\n'
            f'      <ssc:Annotation type="com.opensimulationplatform">\n        <osp:Algorithm>\n'
            f'          <osp:FixedStepAlgorithm baseStepSize="{step}"/>\n        </osp:Algorithm>\n'
            f"      </ssc:Annotation>\n    </ssd:Annotations>\n  </ssd:DefaultExperiment>\n"
            f"</ssd:SystemStructureDescription>\n"
            f"<!-- inputs (set by value reference): {', '.join(config.input_names)}; communication step: multiples "
            f"of dt = {step} s -->\n")


def stop_time(config: BeamConfig, params: dict[str, float]) -> float:
    """The default experiment's duration: ten periods of the model's lowest mode, a whole number of steps ``dt``
    (at least one)."""
    from ebb_model.modal.modal import discrete_frequencies

    dt = config.time.dt
    freqs, _ = discrete_frequencies(config, params)
    lowest = float(freqs[0]) if len(freqs) and freqs[0] > 0 else 1.0 / dt
    return max(1, math.ceil(10.0 / lowest / dt)) * dt


def check_ssp(result: IdentificationResult) -> None:
    """Refuse a result one FMU cannot carry: its positions or a point's size were identified (each point has its
    own grid; a point's size is no FMU parameter).

    Raises
    ------
    ConfigError
        Naming the identified positions and sizes.
    """
    space = result.space
    parts = [f"the {what} of {', '.join(n[2:] for n in space.names if test(n))}"
             for what, test in (("positions", space.is_position), ("sizes", space.is_size))
             if any(test(n) for n in space.names)]
    if parts:
        raise ConfigError(f"`export_ssp`: {' and '.join(parts)} were identified; one FMU cannot take them as "
                          "parameters (export an FMU per point)")


def export_ssp(result: IdentificationResult, points: Sequence[int] | str | None = None, *,
               polished: Sequence[int] | str | None = None, fmi: int = 2) -> Path:
    """Write ``<out_dir>/export/<config>.ssp`` (module docstring) and return its path.

    Parameters
    ----------
    result
        The identification's result.
    points, polished
        Index lists or ``"all"``; with neither given, every Pareto and polished point.
    fmi
        The FMI version of the package's FMU, 2 (the default) or 3.

    Raises
    ------
    ConfigError
        Indices out of range, a result whose positions were identified (no single FMU carries them) — before
        anything is written.
    OutputError
        The export directory cannot take the file (nothing half-written is left).
    """
    from fmu_build.standalone import build_standalone_fmu

    check_ssp(result)
    if fmi not in (2, 3):
        raise ConfigError(f"`fmi` = {fmi!r}: the SSP's FMU is FMI 2 or 3")
    d = result.out_dir
    check_writable_dir(d / "export" if (d / "export").is_dir() else d)
    models = result.models(*chosen(result, points, polished))
    if not models:
        raise ConfigError("`export_ssp`: no point chosen")
    default = "polished_0" if result.polished else f"point_{result.pareto.knee}"
    stems = [stem for stem, _, _ in models]
    bound = default if default in stems else stems[0]
    config = result.config
    stop = stop_time(config, next(p for stem, _, p in models if stem == bound))
    out = make_dir(d / "export", exist_ok=True) / f"{result.config_name}.ssp"
    with tempfile.TemporaryDirectory() as tmp, atomic_path(out, suffix=".ssp") as part:
        fmu = build_standalone_fmu(config, Path(tmp) / "beam.fmu", fmi=fmi)
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            z.write(fmu, "resources/beam.fmu")
            for stem, _, params in models:
                z.writestr(f"resources/{stem}.ssv", _ssv(stem, params))
                if stem != bound:
                    z.writestr(f"{stem}.ssd", _ssd(f"{result.config_name}_{stem}", config, stem, config.time.dt,
                                                      stop))
            z.writestr(DEFAULT_SET, _ssd(f"{result.config_name}_{bound}", config, bound, config.time.dt, stop))
    return out
