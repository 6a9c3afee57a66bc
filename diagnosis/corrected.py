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
from typing import Any, Mapping

from ebb_model import DiscreteStateSpace, assemble
from ebb_model.output import atomic_path, make_dir
from ebb_model.jsonio import write_json

from .effects import AugmentedModel

__all__ = ["corrected_statespace", "export_corrected"]


def corrected_statespace(model: AugmentedModel) -> DiscreteStateSpace | None:
    """The corrected model as one discrete system, or ``None`` when it is not time-invariant (drift, stretching).

    The beam's system with each signal part in series (:meth:`diagnosis.effects.Signal.in_series`).

    Raises
    ------
    StabilityError
        The corrected beam is unstable.
    """
    if not model.time_invariant:
        return None
    sys = assemble(model.config, model.params)
    for part in model.signals:
        sys = part.in_series(sys)
    return sys


def export_corrected(model: AugmentedModel, out_dir: str | Path, summary: Mapping[str, Any], *,
                     fmu: bool = True, standalone: bool = False) -> list[Path]:
    """Write the corrected model into ``out_dir`` (created); returns the written files (see the module docstring).

    The model files are the export targets of identified models (:data:`identification.export.TARGETS`):
    ``statespace`` (when the corrected model is time-invariant), ``fmu`` and (``standalone``) the standalone C FMU
    (:mod:`fmu_build.standalone`, no Python at run time, ``corrected_standalone.fmu``).  ``summary`` (effect,
    parameters with units, held-out gap) is written to ``corrected.json`` with the list of files and what each
    one carries.
    """
    from ebb_model.tomlio import dumps as toml_dumps
    from identification.export import export_target
    from identification.export_targets import ExportItem

    out = Path(out_dir)
    make_dir(out, exist_ok=True, parents=True)
    cfg = model.config.with_parameters(**model.params)
    written = [out / "corrected.toml"]
    with atomic_path(written[0]) as tmp:
        tmp.write_text(toml_dumps(cfg.to_dict()))
    carries: dict[str, str] = {"corrected.toml": "config with the refitted values (structural effects included)"}
    sys = corrected_statespace(model)
    parts = "; ".join(dict.fromkeys(part.description for part in model.signals))
    without_lag = f" (without {parts}: a signal effect outside the FMU's model)" if parts else ""
    targets = {"statespace": ("corrected.npz", "StateSpace of the corrected model"
                              + (f" ({parts} as states in series)" if parts else "")) if sys is not None else None,
               "fmu": ("corrected.fmu", "FMU of the corrected beam" + without_lag) if fmu else None,
               "standalone": ("corrected_standalone.fmu", "standalone C FMU of the corrected beam (no Python at "
                              "run time)" + without_lag) if standalone else None}
    item = ExportItem("corrected", "corrected", cfg, model.params,
                      sys if sys is not None else assemble(model.config, model.params))
    for name, what in targets.items():
        if what is not None:
            written.extend(export_target(name)(item, out))
            carries[what[0]] = what[1]
    if sys is None:
        carries["note"] = (f"{parts} not time-invariant: no StateSpace; the FMU carries the refitted beam "
                           "without it")
    written.append(write_json(out / "corrected.json", dict(summary) | {"files": carries}))
    return written
