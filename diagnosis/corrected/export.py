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

A part that adds a constant to a reading (a sensor offset) keeps the model time-invariant but makes it affine: the
StateSpace carries the linear part, ``corrected.json``'s ``output_offsets`` the constants (the parts' own
``outputs`` applied to zero readings — nothing to declare beyond the part itself).  A model that is not
time-invariant (axial drift, geometric stiffening), a part that declares no StateSpace form, a constant force on
the beam, or a declared form that does not reproduce the part's simulation (checked on a probe, every export) has
no ``corrected.npz``; ``corrected.json`` says which, and its FMU carries the refitted beam without the effect.
What each file carries is the export target's own words (``carries`` of its module).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ebb_model import DiscreteStateSpace, assemble, simulate
from ebb_model.acquisition.delay_line import exported_config, realised_line
from ebb_model.io.output import atomic_path, make_dir
from ebb_model.io.jsonio import write_json
from ebb_model.modal.truncation import design_model, design_resolution
from identification.export_targets import DEFAULT_TARGETS

from ..effects import AugmentedModel

__all__ = ["StateSpaceForm", "corrected_statespace", "export_corrected", "statespace_form"]

#: The StateSpace form must reproduce the diagnosis' simulation of the model to this share of the output's
#: largest value on a probe (the exact series connection agrees to ~1e-11: tests/test_corrected.py).
FORM_TOLERANCE = 1e-8
#: Samples of the probe input the form is checked on.
PROBE_SAMPLES = 400


@dataclass(frozen=True)
class StateSpaceForm:
    """The corrected model as a discrete system and constant offsets of its readings, or why there is none.

    Attributes
    ----------
    system
        The beam with each signal part in series (:meth:`diagnosis.effects.Signal.in_series`); ``None`` when
        the model has no such form (``reason`` says why).
    output_offsets
        Per sensor, the constant a part adds to its reading (a sensor offset: the model is time-invariant and
        affine, ``y = system's output + offset``); empty when none.
    reason
        Why there is no ``system``: not time-invariant, a part declaring no StateSpace, an input offset, or a form
        that does not reproduce the diagnosis' simulation.
    """

    system: DiscreteStateSpace | None
    output_offsets: Mapping[str, float]
    reason: str | None = None


def _parts(model: AugmentedModel, beam: DiscreteStateSpace | None = None, *, delays: bool = True) -> str:
    """The signal parts' descriptions, joined; with ``beam``, only those that put states or terms in series with
    it (a part whose ``in_series`` leaves the system as it is — a constant offset — is not in the StateSpace), and
    without ``delays`` none that only delays its outputs (a delay the exported StateSpace leaves out)."""
    def carried(part: Any) -> bool:
        if beam is None:
            return True
        joined = part.in_series(beam)
        if joined is beam:
            return False
        return delays or joined is None or not (joined.nstates == beam.nstates and np.array_equal(joined.A, beam.A)
                                                and np.array_equal(joined.C, beam.C)
                                                and np.array_equal(joined.D, beam.D))

    return "; ".join(dict.fromkeys(part.description for part in model.signals if carried(part)))


def _constant_terms(model: AugmentedModel) -> tuple[np.ndarray, np.ndarray]:
    """What the parts make of a zero force and of zero readings, held (steady): the affine terms."""
    cfg, dt = model.config, model.config.time.dt
    u = np.zeros((2, len(cfg.actuators)))
    y = np.zeros((2, len(cfg.sensors)))
    for part in model.signals:
        u = part.inputs(u, dt)
    for part in model.signals:
        y = part.outputs(y, dt, cfg.output_names)
    return np.asarray(u[-1], dtype=float), np.asarray(y[-1], dtype=float)


def _in_series(model: AugmentedModel, beam: DiscreteStateSpace) -> DiscreteStateSpace | None:
    sys = beam
    for part in model.signals:
        joined = part.in_series(sys)
        if joined is None:
            return None
        sys = joined
    return sys


def statespace_form(model: AugmentedModel, beam: DiscreteStateSpace | None = None, *,
                    full: DiscreteStateSpace | None = None) -> StateSpaceForm:
    """The corrected model as one discrete system plus constant reading offsets (:class:`StateSpaceForm`).

    The beam's system (``beam``, e.g. a design model; default the whole beam assembled from the model) with each
    signal part in series; the affine terms are what the parts make of zero signals.  The form is checked
    against the diagnosis' own simulation (:func:`diagnosis.problem.augmented.simulate_effects`) of the whole beam on a
    probe input: a part whose declared StateSpace (``in_series``) does not reproduce what it does to the signals
    gives no system rather than a wrong one.  ``full``: the whole beam when the caller has assembled it already.

    Raises
    ------
    StabilityError
        The corrected beam is unstable.
    """
    from ..problem.augmented import simulate_effects

    parts = _parts(model)
    if not model.time_invariant:
        return StateSpaceForm(None, {}, f"{parts}: not time-invariant")
    cfg = model.config
    full = assemble(cfg, model.params) if full is None else full
    whole = _in_series(model, full)
    if whole is None:
        missing = [p.description for p in model.signals if p.in_series(full) is None]
        return StateSpaceForm(None, {}, f"{missing[0] if missing else parts}: declares no StateSpace form "
                                        "(Signal.in_series)")
    force, readings = _constant_terms(model)
    if np.any(force != 0.0):
        return StateSpaceForm(None, {}, f"{parts}: a constant force on the beam (an input offset) has no "
                                        "StateSpace form")
    # the check: the form against the simulation, on a smooth probe started away from zero
    rng = np.random.default_rng(0)
    u = np.cumsum(rng.standard_normal((PROBE_SAMPLES, len(cfg.actuators))), axis=0)
    y_sim = simulate_effects(cfg, model.params, u, model.signals)
    y_form = simulate(whole, u).outputs + readings
    scale = float(np.max(np.abs(y_sim))) or 1.0
    off = float(np.max(np.abs(y_form - y_sim))) / scale
    if not off <= FORM_TOLERANCE:
        return StateSpaceForm(None, {}, f"{parts}: its StateSpace form (Signal.in_series) does not reproduce its "
                                        f"simulation (off by {off:.2g} of the largest output on a probe)")
    sys = whole if beam is None else _in_series(model, beam)
    offsets = {name: float(v) for name, v in zip(cfg.output_names, readings) if v != 0.0}
    return StateSpaceForm(sys, offsets)


def corrected_statespace(model: AugmentedModel, beam: DiscreteStateSpace | None = None
                         ) -> DiscreteStateSpace | None:
    """The system of :func:`statespace_form` (``None`` when the model has none)."""
    return statespace_form(model, beam).system


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
    from ebb_model.io.tomlio import dumps as toml_dumps
    from identification.export_targets import ExportItem, check_targets, export_target, target_carries

    targets = check_targets(targets, model.config)
    config = model.config
    exported, left_out = exported_config(config)     # the delays as delay-line states where causal
    model = replace(model, config=exported)
    out = Path(out_dir)
    make_dir(out, exist_ok=True, parents=True)
    cfg = config.with_parameters(**model.params)     # the config, its channel delays kept
    written = [out / "corrected.toml"]
    with atomic_path(written[0]) as tmp:
        tmp.write_text(toml_dumps(cfg.to_dict()))
    carries: dict[str, Any] = {"corrected.toml": "config with the refitted values (structural effects included)"}
    beam = assemble(model.config, model.params)
    # the StateSpace for control design: the modes up to the Nyquist frequency that the grid resolves, the rest as
    # a static correction
    resolution = design_resolution(model.config, model.params)
    form = statespace_form(model, design_model(model.config, model.params, resolution=resolution), full=beam)
    system, line_left_out = (None, "") if form.system is None else realised_line(form.system)
    item = ExportItem("corrected", "corrected", exported.with_parameters(**model.params), model.params, system,
                      beam_system=beam,
                      parts=_parts(model, beam, delays=not line_left_out),
                      modes=None if resolution is None else resolution.to_dict(),
                      no_system=form.reason or "")
    for name in targets:
        files = export_target(name)(item, out)
        written.extend(files)
        for f in files:
            carries[f.name] = target_carries(name, item)
        if not files:                                 # a target that cannot carry this model says why
            carries[f"{name} (nothing written)"] = target_carries(name, item)
    extra: dict[str, Any] = {}
    if form.output_offsets:
        units = {s.name: s.unit for s in model.config.sensors}
        extra["output_offsets"] = {k: {"value": v, "unit": units.get(k, "")} for k, v in form.output_offsets.items()}
        carries["note"] = ("a sensor reads the model's output plus a constant (output_offsets, in neither the "
                           "StateSpace nor the FMU): the model is time-invariant and affine")
    if left_out or line_left_out:
        carries["channel delays"] = "; ".join(m for m in (left_out, line_left_out) if m)
    written.append(write_json(out / "corrected.json", dict(summary) | extra | {"files": carries}))
    return written
