"""Export targets of identified models: one module per target, registered in :data:`TARGETS`.

A target module provides ``write(item: ExportItem, out_dir: Path) -> list[Path]``, which writes the files of one
identified model into ``out_dir`` (named after ``item.stem``) and returns them, and may provide
``carries(item: ExportItem) -> str``, what those files carry in words (``corrected.json``'s file map and the
console say it; without it: "written by the export target NAME"). Adding a target is one module here and one
line in the registry.

``statespace`` — python-control StateSpace (``.npz``, and a balanced truncation on request); ``fmu`` — the
pythonfmu FMU; ``fmu_fmi3`` — the same in FMI 3.0; ``standalone`` — the standalone C FMU (no Python at run time);
``standalone_fmi3`` — the same in FMI 3.0.
"""
from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from ebb_model import BeamConfig, DiscreteStateSpace
from ebb_model.errors import ConfigError

__all__ = ["DEFAULT_TARGETS", "ExportItem", "TARGETS", "check_targets", "export_target", "target_carries"]

#: Export targets: name → module of :mod:`identification.export_targets` providing ``write(item, out_dir)``.
TARGETS: Mapping[str, str] = MappingProxyType({
    "statespace": "identification.export_targets.statespace",   # python-control StateSpace (.npz)
    "fmu": "identification.export_targets.fmu",                 # pythonfmu FMU
    "fmu_fmi3": "identification.export_targets.fmu_fmi3",       # the same in FMI 3.0
    "standalone": "identification.export_targets.standalone",   # standalone C FMU
    "standalone_fmi3": "identification.export_targets.standalone_fmi3",   # the same in FMI 3.0
})
#: What ``identify``, ``export`` and the corrected model write when no target is named.
DEFAULT_TARGETS: tuple[str, ...] = ("statespace", "fmu")


def export_target(name: str) -> Callable[[ExportItem, Path], list[Path]]:
    """The ``write`` function of export target ``name``.

    Raises
    ------
    ConfigError
        ``name`` is not in :data:`TARGETS` (the message lists them).
    """
    return importlib.import_module(TARGETS[check_targets([name])[0]]).write


def target_carries(name: str, item: ExportItem) -> str:
    """What the files export target ``name`` writes of ``item`` carry, in words (its module's ``carries``)."""
    module = importlib.import_module(TARGETS[check_targets([name])[0]])
    carries = getattr(module, "carries", None)
    return carries(item) if carries is not None else f"written by the export target {name!r}"


def check_targets(targets: Sequence[str], config: BeamConfig | None = None) -> tuple[str, ...]:
    """``targets`` as a tuple of known export target names (before anything is written); with ``config``, each
    target whose module has ``check(config)`` also checks that it can carry the config's model.

    Raises
    ------
    ConfigError
        A name not in :data:`TARGETS` (the message lists them), a string instead of a list of names, or a target
        that cannot carry ``config`` (e.g. the standalone FMU and an anti-alias filter).
    """
    if isinstance(targets, str):
        raise ConfigError(f"`targets`: expected a list of target names, got the string {targets!r}")
    unknown = [t for t in targets if t not in TARGETS]
    if unknown:
        raise ConfigError(f"`targets`: unknown export target {unknown[0]!r}; allowed: {', '.join(TARGETS)}")
    for t in targets if config is not None else ():
        check = getattr(importlib.import_module(TARGETS[t]), "check", None)
        if check is not None:
            check(config)
    return tuple(targets)


@dataclass(frozen=True, eq=False)
class ExportItem:
    """One identified model to export.

    Attributes
    ----------
    stem
        File name stem (``point_3``, ``polished_0``).
    title
        Model name written into the files (``<run>_<stem>``).
    config
        Set-up of the model (positions moved for identified positions).
    params
        Identified physical parameter values.
    system
        The model for control design (what a StateSpace export writes): the beam at ``params`` with its modes in
        the band (:func:`ebb_model.modal.truncation.design_model`), with a corrected model's signal-level parts in
        series when it has them; ``None`` when the model has no such form (a corrected model whose effect is not
        time-invariant, or a constant force: ``no_system`` says why) — a target that writes ``system`` then writes
        nothing and says so, never the beam without the effect.
    options
        Target options (``reduce_order`` for ``statespace``).
    beam_system
        The whole beam alone (what an FMU carries: every mode, no signal parts); ``None``: ``system``.
    parts
        The signal-level parts ``system`` has in series and ``beam`` has not, in words ("" for none: a corrected
        model's lags and gains, :mod:`diagnosis.corrected.export`).
    modes
        Which modes ``system`` keeps, each with its frequency error estimate against a converged grid
        (:meth:`ebb_model.modal.truncation.ModeResolution.to_dict`); ``None`` when it did not choose them so.
    no_system
        Why ``system`` is ``None`` ("" when it is not).
    """

    stem: str
    title: str
    config: BeamConfig
    params: Mapping[str, float]
    system: DiscreteStateSpace | None
    options: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    beam_system: DiscreteStateSpace | None = None
    parts: str = ""
    modes: Mapping[str, Any] | None = None
    no_system: str = ""

    def __post_init__(self) -> None:
        if self.system is None and self.beam_system is None:
            raise ValueError("an export item needs the model's system or the beam's")

    @property
    def beam(self) -> DiscreteStateSpace:
        """The beam's own system at ``params`` (what the FMU targets build from)."""
        beam = self.system if self.beam_system is None else self.beam_system
        assert beam is not None                  # __post_init__
        return beam

    @property
    def acquisition(self) -> str:
        """What of the records' acquisition the files carry besides the beam, in words ("" for nothing said): the
        channels' converter delays as delay-line states (:mod:`ebb_model.acquisition.delay_line`)."""
        from ebb_model.acquisition.channel_delay import effective_delays

        return ", the channels' converter delays as delay-line states" if effective_delays(self.config) else ""
