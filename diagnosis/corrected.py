"""The diagnosed model as a product: the baseline with the verdict's effect, refitted, as StateSpace and FMU.

``ebb diagnose`` writes ``DIR/corrected/`` next to ``gap.json`` when its verdict names an effect:

* ``corrected.toml`` — the config with the refitted values: baseline unknowns, and the effect where it is a
  config change (end spring, point mass, Kelvin–Voigt damping, rotary inertia, foundation);
* ``corrected.npz`` — a python-control StateSpace (:mod:`identification.export_statespace`) of the linear
  time-invariant corrected model: the beam, plus each signal part's states in series
  (:meth:`diagnosis.effects.Signal.in_series`, e.g. the first-order lag of ``actuator_lag`` / ``sensor_lag`` by the
  same exact discretisation the diagnosis simulates with), so that it reproduces the diagnosis' refit to round-off;
* ``corrected.fmu`` — the pythonfmu FMU of the corrected beam (config changes included; a lag is not part of
  the FMU's model: ``corrected.json`` says so);
* ``corrected.json`` — effect and baseline parameters with units, held-out gap before/after, and which file
  carries what.

A model that is not time-invariant (axial drift, geometric stiffening) has no ``corrected.npz``; its FMU carries the
refitted beam without the effect (``corrected.json`` says so).
"""
from __future__ import annotations

from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping, Sequence

from ebb_model import DiscreteStateSpace, assemble
from ebb_model.output import atomic_path, make_dir
from ebb_model.jsonio import write_json
from ebb_model.truncation import design_model
from identification.export_targets import DEFAULT_TARGETS

from .effects import AugmentedModel

__all__ = ["corrected_statespace", "export_corrected"]


def corrected_statespace(model: AugmentedModel, beam: DiscreteStateSpace | None = None
                         ) -> DiscreteStateSpace | None:
    """The corrected model as one discrete system, or ``None`` when it is not time-invariant (drift, stretching).

    The beam's system (``beam``, assembled from the model when not given) with each signal part in series
    (:meth:`diagnosis.effects.Signal.in_series`).

    Raises
    ------
    StabilityError
        The corrected beam is unstable.
    """
    if not model.time_invariant:
        return None
    sys = assemble(model.config, model.params) if beam is None else beam
    for part in model.signals:
        sys = part.in_series(sys)
    return sys


#: What each export target of :data:`identification.export_targets.TARGETS` writes of the corrected model, and what that
#: file carries (``{parts}``: the model's signal-level parts, ``{without}``: the FMU's note about them).
_CARRIES: Mapping[str, tuple[str, str]] = MappingProxyType({
    "statespace": ("corrected.npz", "StateSpace of the corrected model{parts}"),
    "fmu": ("corrected.fmu", "FMU of the corrected beam{without}"),
    "standalone": ("corrected_standalone.fmu", "standalone C FMU of the corrected beam (no Python at run time)"
                                               "{without}"),
})


def export_corrected(model: AugmentedModel, out_dir: str | Path, summary: Mapping[str, Any], *,
                     targets: Sequence[str] = DEFAULT_TARGETS) -> list[Path]:
    """Write the corrected model into ``out_dir`` (created); returns the written files (see the module docstring).

    The model files are written by the export targets named in ``targets``
    (:data:`identification.export_targets.TARGETS`: ``statespace`` — only when the corrected model is
    time-invariant —, ``fmu``, ``standalone``), from one assembly of the corrected beam.  ``summary`` (effect,
    parameters with units, held-out gap) is written to ``corrected.json`` with the list of files and what each
    one carries.

    Raises
    ------
    ConfigError
        An unknown target name (before anything is written).
    """
    from ebb_model.tomlio import dumps as toml_dumps
    from identification.export_targets import check_targets, export_target
    from identification.export_targets import ExportItem

    targets = check_targets(targets)
    out = Path(out_dir)
    make_dir(out, exist_ok=True, parents=True)
    cfg = model.config.with_parameters(**model.params)
    written = [out / "corrected.toml"]
    with atomic_path(written[0]) as tmp:
        tmp.write_text(toml_dumps(cfg.to_dict()))
    carries: dict[str, str] = {"corrected.toml": "config with the refitted values (structural effects included)"}
    beam = assemble(model.config, model.params)
    # the StateSpace for control design: the modes up to the Nyquist frequency, the rest as a static correction
    sys = corrected_statespace(model, design_model(model.config, model.params)) if model.time_invariant else None
    parts = "; ".join(dict.fromkeys(part.description for part in model.signals))
    words = {"parts": f" ({parts} as states in series)" if parts else "",
             "without": f" (without {parts}: a signal effect outside the FMU's model)" if parts else ""}
    item = ExportItem("corrected", "corrected", cfg, model.params, sys if sys is not None else beam,
                      beam_system=beam)
    for name in targets:
        if name == "statespace" and sys is None:
            continue
        written.extend(export_target(name)(item, out))
        if name in _CARRIES:
            file, what = _CARRIES[name]
            carries[file] = what.format(**words)
    if sys is None:
        carries["note"] = (f"{parts} not time-invariant: no StateSpace; the FMU carries the refitted beam "
                           "without it")
    written.append(write_json(out / "corrected.json", dict(summary) | {"files": carries}))
    return written
