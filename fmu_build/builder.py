"""Build a co-simulation FMU of the beam running on Python: :func:`build_fmu` (FMI 2.0 or 3.0).

The FMU is a pythonfmu FMU (FMI 2.0: pythonfmu's export library and Python runtime, a slave class derived from
``pythonfmu.Fmi2Slave``; FMI 3.0: pythonfmu3's, ``pythonfmu3.Fmi3Slave``; both slaves are
:class:`fmu_build.slave_base.BeamModel`) with three additions:

* a C loader as the entry library (``binaries/<platform>/<id>.so``, see
  ``loader.c``, ``loader3.c``), so that non-Python masters can load it without
  ``LD_PRELOAD`` or environment variables;
* a completed ``modelDescription.xml`` (units, ModelStructure) that
  ``fmpy.validation.validate_fmu`` accepts without findings;
* a unique model identifier, slave module and class name, core package name
  and GUID per build, so several beam FMUs run side by side in one process.

The archive is written to a temporary file next to ``out`` and renamed into
place only when complete: a failed build leaves no partial ``.fmu``.
"""
from __future__ import annotations

import os
import re
import sys
import shutil
import tempfile
import uuid
import zipfile
from pathlib import Path
from typing import Sequence

import pythonfmu
import pythonfmu3

import ebb_model
from ebb_model import PARAMETER_NAMES, BeamConfig, DiscreteStateSpace, assemble, load_config
from ebb_model.assemble import assemble_modal
from ebb_model.acquisition.bandlimited import causal_config
from ebb_model.acquisition.delay_line import delay_line
from ebb_model.io.output import atomic_path, check_output_file
from ebb_model.errors import FmuError, OutputError

from . import slave_base, slave_template, slave_template_fmi3
from .bundle import core_sources, write_resources
from .kernels import KERNEL_SUFFIXES, carry_kernels, compile_bytecode, core_package_name
from .loader import compile_loader, find_python_runtime
from .model_description import FmuIdentity, feedthrough_from_D, finish_model_description
from .model_description_fmi3 import finish_model_description_fmi3

__all__ = ["build_fmu"]

#: Per FMI version: the binaries' platform folder and the pythonfmu package whose export library goes inside.
_PLATFORM = {2: ("linux64", pythonfmu), 3: ("x86_64-linux", pythonfmu3)}

#: Top-level variable names the FMU itself uses besides the parameters.
_RESERVED = {"beam", "time", "actuators", "sensors", "masses", "springs", "weak_segments", slave_base.FIELD_NAME}


def _identity(base: str, core_package: str = "") -> FmuIdentity:
    """Fresh names for one build, derived from ``base`` (e.g. the config file's stem); ``core_package`` the name of
    the bundled core, when the FMU bundles one (:func:`~fmu_build.kernels.core_package_name`)."""
    stem = re.sub(r"\W", "_", base, flags=re.ASCII).strip("_") or "beam"
    if not stem[0].isalpha():
        stem = "beam_" + stem
    stem = stem[:40]
    token = uuid.uuid4()
    tag = token.hex[:12]
    model_identifier = f"{stem}_{tag}"
    return FmuIdentity(
        model_identifier=model_identifier,
        class_name=f"BeamSlave_{tag}",
        core_package=core_package,
        guid=f"{{{token}}}",
        model_name=stem,
    )


def _check_names(config: BeamConfig) -> None:
    names = [a.name for a in config.actuators] + [s.name for s in config.sensors]
    reserved = _RESERVED | set(PARAMETER_NAMES)
    clashes = sorted(set(names) & reserved)
    if clashes:
        raise FmuError(
            f"actuator/sensor names {clashes} clash with names the FMU uses ({', '.join(sorted(reserved))})",
            function="build_fmu",
        )


def _description(config: BeamConfig, runtime_python: str, version: str, field: bool) -> str:
    b = config.beam
    text = (
        f"Axially loaded Euler-Bernoulli beam (ebb_model): length {b.length:g} m, {b.nodes} interior nodes, "
        f"{b.left.kind}-{b.right.kind}, dt {config.time.dt:g} s, theta {config.time.theta:g}; "
        f"{len(config.actuators)} force input(s), {len(config.sensors)} sensor output(s)"
        + (", deflection at every grid node" if field else "")
        + ". Communication steps must be integer multiples of dt (inputs held over the step). "
        f"Requires Python {version} with {', '.join(slave_base.REQUIRED_PACKAGES)} (built with "
        f"{runtime_python}); "
        "the FMU's loader starts that interpreter when the master is not Python itself. Linux x86-64 only."
    )
    return text


def _check_output(out: Path, inputs: Sequence[str | os.PathLike[str]] = ()) -> Path:
    """Refuse an output the builders cannot write (not a .fmu name, a directory, an unusable place, an input)."""
    if out.suffix.lower() != ".fmu":
        raise FmuError(f"{out}: the output file name must end in .fmu", function="build_fmu")
    if out.is_dir():
        raise FmuError(f"{out}: is a directory; give the path of the .fmu file to write", function="build_fmu")
    try:
        check_output_file(out, inputs=inputs)   # directory present, writable (a real probe), room left; no input
    except OutputError as exc:   # the builders' one error type for an unusable output
        raise FmuError(str(exc), function="build_fmu") from None
    return out.parent


def _arrays(feedthrough: dict[str, tuple[str, ...]]) -> dict[str, tuple[str, ...]]:
    """The feedthrough by FMI 3.0 variable: the field's outputs ``w[i]`` are the one array ``w`` (the inputs that
    reach any element)."""
    out: dict[str, tuple[str, ...]] = {}
    for name, inputs in feedthrough.items():
        key = name.split("[", 1)[0] if name.startswith(slave_base.FIELD_NAME + "[") else name
        out[key] = tuple(dict.fromkeys(out.get(key, ()) + inputs))
    return out


def build_fmu(config: BeamConfig | str | os.PathLike[str], out: str | os.PathLike[str], *,
              field: bool = False, system: DiscreteStateSpace | None = None, fmi: int = 2) -> Path:
    """Build the beam FMU (FMI 2.0 or 3.0 co-simulation, Linux x86-64).

    Parameters
    ----------
    config
        A :class:`~ebb_model.BeamConfig`, or the path of a TOML config file.
    out
        Path of the ``.fmu`` file to write (replaced if it exists).
    field
        Also output the deflection at every grid node (boundary nodes included), in addition to the sensors:
        the scalars ``w[i]`` in FMI 2.0, one array ``w`` in FMI 3.0.
    system
        The config's system at its nominal values (:func:`ebb_model.assemble`), when the caller has it already
        (an export hands one assembled model to every target); assembled here otherwise.
    fmi
        The FMI version: 2 (pythonfmu 0.7, ``binaries/linux64``) or 3 (pythonfmu3, ``binaries/x86_64-linux``).
        The same variables, units, physics and refusals; FMI 3.0 adds the independent variable ``time``.

    Returns
    -------
    pathlib.Path
        ``out``.

    Raises
    ------
    ConfigError
        The config file is missing or invalid.
    ParameterError, StabilityError
        The nominal parameters give no valid (stable) model.
    FmuError
        The output is unusable (not a .fmu name; its place not writable, read-only or full, checked before the
        build by :func:`ebb_model.io.output.check_output_file`), names clash, the interpreter has no shared
        libpython, no C compiler is available, ``fmi`` is neither 2 nor 3, or writing the archive fails (nothing
        half-written is left).

    Notes
    -----
    The FMU runs on the interpreter that builds it: its libpython, standard
    library and site-packages are recorded in the loader.  ``ebb_model``'s
    sources are bundled (renamed) in the FMU's resources.
    """
    if fmi not in _PLATFORM:
        raise FmuError(f"`fmi` {fmi!r}: the FMI version must be 2 or 3 (FMI 2.0 or 3.0)", function="build_fmu")
    if isinstance(config, BeamConfig):
        cfg, base = config, "beam"
    else:
        cfg, base = load_config(config), Path(config).stem
    # the config as written goes into the FMU (a fractional channel delay is valid only under the band-limited
    # force), the slave takes it as a host drives it: sample by sample, no band-limited reconstruction
    config_dict = {k: v for k, v in cfg.to_dict().items() if k not in cfg.extra}
    cfg = causal_config(cfg)
    out = Path(out)
    _check_output(out, () if isinstance(config, BeamConfig) else (config,))
    _check_names(cfg)
    if system is None:
        system = assemble(cfg)  # nominal parameters must give a valid, stable model
    lined = delay_line(system)  # the channels' delays as the slave iterates them: refused here when not causal
    runtime = find_python_runtime()
    sources = core_sources()
    identity = _identity(base, core_package_name(sources, Path(ebb_model.__file__).parent))
    description = _description(cfg, sys.executable, runtime.version, field)
    spec = {
        "format": 1,
        "config": config_dict,
        "field": bool(field),
        "dt": float(system.dt),
        "model_name": identity.model_name,
        "description": description,
        "build_python": sys.executable,
    }

    try:
        with tempfile.TemporaryDirectory(prefix="ebb_fmu_") as staging_dir, atomic_path(out) as tmp_path:
            staging = Path(staging_dir)
            resources = staging / "resources"
            write_resources(resources, identity=identity, spec=spec, sources=sources, fmi=fmi)
            # the model the FMU carries first: the build's slave below then reads it instead of assembling
            carry_kernels(resources / identity.core_package, config_dict, field=field)

            platform, package = _PLATFORM[fmi]
            binaries = staging / "binaries" / platform
            binaries.mkdir(parents=True)
            inner = f"{identity.model_identifier}_{package.__name__}.so"
            shutil.copy2(Path(str(package.__file__)).parent / "resources" / "binaries" / platform
                         / "libpythonfmu-export.so", binaries / inner)
            slave_class = slave_template.BeamSlave if fmi == 2 else slave_template_fmi3.BeamSlave3
            slave = slave_class(instance_name="build", resources=str(resources))
            compile_loader(binaries / f"{identity.model_identifier}.so", inner_library=inner,
                           runtime=runtime, guid=identity.guid, fmi=fmi, arrays=slave.array_sizes())
            # the feedthrough's zero pattern: the system's D (the slave's realisation has the same D), or with
            # field outputs what the slave iterates
            realised = assemble_modal(cfg, field=True) if field else lined
            feedthrough = feedthrough_from_D(realised.D, realised.output_names, realised.input_names)
            if fmi == 2:
                xml = finish_model_description(slave.to_xml(), identity=identity, description=description,
                                               units=slave.variable_units, feedthrough=feedthrough)
            else:
                xml = finish_model_description_fmi3(slave.to_xml(), identity=identity, description=description,
                                                    units=slave.variable_units, feedthrough=_arrays(feedthrough),
                                                    starts=dict(cfg.parameter_values()))
            (staging / "modelDescription.xml").write_bytes(xml)
            compile_bytecode(resources)

            with open(tmp_path, "xb") as fh, zipfile.ZipFile(fh, "w", compression=zipfile.ZIP_DEFLATED) as zf:
                for f in sorted(staging.rglob("*")):
                    if f.is_file() and (f.parent.name != "__pycache__" or f.suffix in (".pyc", *KERNEL_SUFFIXES)):
                        zf.write(f, f.relative_to(staging).as_posix())
    except OutputError as exc:   # writing the archive failed (full disk …): nothing half-written is left
        raise FmuError(str(exc), function="build_fmu") from None
    except OSError as exc:
        raise FmuError(f"{out}: cannot write the FMU ({exc.strerror or exc})", function="build_fmu") from None
    return out
