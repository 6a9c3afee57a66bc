"""Build the standalone C FMU of the beam: :func:`build_standalone_fmu`.

The FMU needs no Python at run time.  It carries the C source of the same model as ``ebb_model``:
finite-difference assembly from the physical parameters, then for the default scheme ``exact`` Richardson
modes on two grids, each mode integrated exactly over a sample under the input polynomial, or the seed's
θ-scheme on the nodal unknowns (``[time] scheme = "theta"``; see ``csrc/ebb_theta.c``), so ``EI``,
``rhoA``, ``c``, ``eta``, ``N``, ``rhoI``, ``kf`` stay tunable parameters; only the structure (grid, ends,
positions, point masses, ``dt``, input reconstruction) is generated into ``sources/ebb_config.h``.

The channels' converter delays (``delay`` of a ``[[sensors]]`` table, after the force's channel) are carried as
delay lines (:mod:`ebb_model.acquisition.delay_line`): each delayed sensor's undelayed output of the last samples
kept in the instance, its output their weighted sum (``csrc/ebb_delay.c``).  Past samples are no continuous-time
state, so such an FMU offers co-simulation only; a delay no causal delay line realises (a sensor ahead of the
force's channel, a fraction of a sample shorter than
:data:`~ebb_model.acquisition.delay_line.MIN_FRACTIONAL`) is refused with one line.

Archive layout::

    modelDescription.xml           ModelExchange (not with channel delays) and CoSimulation, one modelIdentifier
    binaries/linux64/<id>.so       gcc -std=c99 -O2 -shared -fPIC -fvisibility=hidden ... -lm
                                   (FMI 3.0: binaries/x86_64-linux/<id>.so)
    sources/*.c, *.h               ebb_linalg.c, ebb_fd.c, ebb_model.c, ebb_theta.c, ebb_instance.c,
                                   ebb_derivatives.c, ebb_state.c, ebb_delay.c, ebb_fmi2.c (FMI 3.0: ebb_fmi3.c),
                                   ebb_beam.h, ebb_instance.h (FMI 3.0: also ebb_fmi3.h), ebb_config.h
    sources/buildDescription.xml   the same file list (FMI 2.0.4 / 3.0 layout), for other platforms

FMI 3.0 (``fmi=3``) is the same instance behind the FMI 3.0 C API: the deflection field as one array variable
``w``, ``time`` as the independent variable, adjoint derivatives besides directional ones
(:mod:`~fmu_build.standalone.description_fmi3`).

Decisions: the binary is compiled at build time, so gcc is needed to build, nothing to run.  The archive is
written to a temporary file next to ``out`` and renamed into place when complete: a failed build leaves no
partial ``.fmu``.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path

from ebb_model import BeamConfig, DiscreteStateSpace, assemble, load_config
from ebb_model.assemble import field_config
from ebb_model.acquisition.bandlimited import causal_config
from ebb_model.acquisition.delay_line import line_problems
from ebb_model.config.types import MAX_NODES
from ebb_model.io.output import atomic_path
from ebb_model.errors import ConfigError, FmuError, OutputError

from ..builder import _check_names, _check_output, _identity
from .description import (C_HEADERS, C_SOURCES, build_description_xml, config_header, delay_lines, fmu_variables,
                          model_description_xml, n_modes)
from .description_fmi3 import model_description_xml3

__all__ = ["build_standalone_fmu", "compile_binary", "SOURCE_DIR"]

#: Where the C sources live (copied verbatim into the FMU's ``sources/``).
SOURCE_DIR = Path(__file__).resolve().parent / "csrc"
#: The binaries' folder by FMI version (FMI 3.0 names platforms as architecture-os).
_PLATFORM = {2: "linux64", 3: "x86_64-linux"}
#: The FMI versions the standalone FMU is built for.
FMI_VERSIONS = (2, 3)
#: The largest grid, :data:`ebb_model.config.types.MAX_NODES` (1000), is also the C model's: its solvers are dense
#: (Jacobi sweeps, O(n³) each): initialisation takes 0.2 s at 200 nodes and 1.6 s at 400 (exact scheme), about
#: 25 s at 1000.
#: Compiler flags of the binary (plain C99, hidden symbols except the fmi2 or fmi3 functions).
CFLAGS = ("-std=c99", "-O2", "-shared", "-fPIC", "-fvisibility=hidden", "-Wall")


def _description(config: BeamConfig, field: bool, fmi: int = 2) -> str:
    b, t = config.beam, config.time
    scheme = "exact" if t.scheme == "exact" else f"theta {t.theta:g} with {t.substeps} sub-step(s)"
    states = ("the modal coordinates and velocities of the Richardson modes" if t.scheme == "exact"
              else "deflection and velocity of the grid's unknowns")
    delayed = [config.sensors[i].name for i, _, _ in delay_lines(config)]
    exchange = (f"Model exchange: {2 * n_modes(config)} states, {states}." if not delayed else
                f"No model exchange: the channels' converter delays (sensor(s) {', '.join(delayed)}) are delay lines "
                "of past output samples, not continuous-time states.")
    return (f"Axially loaded Euler-Bernoulli beam (ebb_model, scheme {scheme}, input {t.input_hold}): length "
            f"{b.length:g} m, {b.nodes} interior nodes, {b.left.kind}-{b.right.kind}, dt {t.dt:g} s; "
            f"{len(config.actuators)} force input(s), {len(config.sensors)} sensor output(s)"
            + ((", deflection at every grid node" + (" (array w)" if fmi == 3 else "")) if field else "")
            + ". Standalone C (no Python at run time): the model is assembled from the parameters at "
              "initialisation. Co-simulation: communication steps must be integer multiples of dt (inputs held "
              f"over the step). {exchange} Binary for "
              f"{_PLATFORM[fmi]}; sources/ compile elsewhere (C99 + libm).")


def compile_binary(sources: Path, target: Path, *, compiler: str = "gcc", fmi: int = 2) -> None:
    """Compile the FMU's ``sources`` (those of FMI version ``fmi``) into the shared library ``target``.

    Raises
    ------
    FmuError
        No compiler, or the compilation fails (its message included).
    """
    cc = shutil.which(compiler)
    if cc is None:
        raise FmuError(f"no C compiler ({compiler}) found: the standalone FMU's binary is compiled at build time",
                       function="build_standalone_fmu")
    target.parent.mkdir(parents=True, exist_ok=True)
    cmd = [cc, *CFLAGS, "-o", os.path.relpath(target, sources), *C_SOURCES[fmi], "-lm"]
    proc = subprocess.run(cmd, cwd=sources, capture_output=True, text=True)
    if proc.returncode != 0:
        raise FmuError(f"compiling the standalone FMU failed: {proc.stderr.strip()[-2000:]}",
                       function="build_standalone_fmu")


def check_standalone(config: BeamConfig) -> None:
    """Whether the standalone FMU can carry ``config`` (before anything is built or run).

    Raises
    ------
    ConfigError
        The grid exceeds :data:`MAX_NODES`.
    """
    if config.beam.nodes > MAX_NODES:
        raise ConfigError(f"beam.nodes = {config.beam.nodes}: the standalone FMU's dense C solvers take at most "
                          f"{MAX_NODES} nodes (initialisation time grows as nodes³)")


def build_standalone_fmu(config: BeamConfig | str | os.PathLike[str], out: str | os.PathLike[str], *,
                         field: bool = False, system: DiscreteStateSpace | None = None, fmi: int = 2) -> Path:
    """Build the standalone FMU (FMI 2.0 or 3.0, model exchange and co-simulation; C, no Python at run time).

    The config's channel delays are carried as delay lines (module docstring): then co-simulation only.

    Parameters
    ----------
    config
        A :class:`~ebb_model.BeamConfig`, or the path of a TOML config file.  Its nominal parameter values
        become the parameters' start values.
    out
        Path of the ``.fmu`` file to write (replaced if it exists).
    field
        Also output the deflection ``w[i]`` at every grid node (displacement outputs at the nodes).
    system
        The config's system at its nominal values, when the caller has it already (it is the check that the
        nominal values give a valid, stable model; assembled here otherwise).
    fmi
        The FMI version, 2 (the default) or 3: FMI 3.0 carries the deflection field as one array ``w``.

    Returns
    -------
    pathlib.Path
        ``out``.

    Raises
    ------
    ConfigError
        The config file is missing or invalid, its grid exceeds :data:`MAX_NODES`, or a channel's delay has no
        causal delay line (ahead of the force's channel, or a fraction of a sample too short): one line naming the
        sensor(s).
    ParameterError, StabilityError
        The nominal parameters give no valid (stable) model.
    FmuError
        The output is unusable (checked before the build: not a .fmu name, not writable, read-only or full),
        names clash, no C compiler, or writing the archive fails (nothing half-written is left).
        Also when ``fmi`` is neither 2 nor 3.
    """
    if fmi not in FMI_VERSIONS:
        raise FmuError(f"`fmi` = {fmi!r}: the standalone FMU is built for FMI 2 or 3", function="build_standalone_fmu")
    if isinstance(config, BeamConfig):
        cfg, base = config, "beam"
    else:
        cfg, base = load_config(config), Path(config).stem
    problems = line_problems(cfg)       # the host has only the past: no sensor ahead of the force, no short fraction
    if problems:
        raise ConfigError("; ".join(problems))
    cfg = causal_config(cfg)            # a host feeds the force sample by sample: no band-limited reconstruction
    out = Path(out)
    _check_output(out, () if isinstance(config, BeamConfig) else (config,))
    _check_names(cfg)
    taken = {a.name for a in cfg.actuators} | {x.name for x in cfg.sensors}
    clashes = sorted(taken & ({"modes", "nodes"} | ({"w", "time"} if fmi == 3 else set())))
    if clashes:
        raise FmuError(f"actuator/sensor names {clashes} clash with the standalone FMU's own names (modes.q[i], "
                       "nodes.q[i]; FMI 3.0: w, time)", function="build_standalone_fmu")
    check_standalone(cfg)
    if system is None:
        assemble(cfg)                                   # the nominal parameters must give a valid, stable model
    field_sensors = tuple(field_config(cfg).sensors[len(cfg.sensors):]) if field else ()
    identity = _identity(base)
    variables = fmu_variables(cfg, field_sensors, fmi=fmi)
    sources = C_SOURCES[fmi]
    describe = model_description_xml if fmi == 2 else model_description_xml3
    xml = describe(variables, identity=identity, description=_description(cfg, field, fmi), dt=cfg.time.dt,
                   sources=sources, exchange=not delay_lines(cfg))

    try:
        with tempfile.TemporaryDirectory(prefix="ebb_cfmu_") as staging_dir, atomic_path(out) as tmp_path:
            staging = Path(staging_dir)
            src = staging / "sources"
            src.mkdir()
            for name in sources + C_HEADERS[fmi]:
                shutil.copyfile(SOURCE_DIR / name, src / name)
            (src / "ebb_config.h").write_text(config_header(cfg, variables, identity, field_sensors),
                                              encoding="utf-8")
            (src / "buildDescription.xml").write_bytes(build_description_xml(identity, sources, fmi))
            (staging / "modelDescription.xml").write_bytes(xml)
            compile_binary(src, staging / "binaries" / _PLATFORM[fmi] / f"{identity.model_identifier}.so", fmi=fmi)
            with open(tmp_path, "xb") as fh, zipfile.ZipFile(fh, "w", compression=zipfile.ZIP_DEFLATED) as zf:
                for f in sorted(staging.rglob("*")):
                    if f.is_file():
                        zf.write(f, f.relative_to(staging).as_posix())
    except OutputError as exc:   # writing the archive failed (full disk …): nothing half-written is left
        raise FmuError(str(exc), function="build_standalone_fmu") from None
    except OSError as exc:
        raise FmuError(f"{out}: cannot write the FMU ({exc.strerror or exc})",
                       function="build_standalone_fmu") from None
    return out
