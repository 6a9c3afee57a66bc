"""Export targets of identified models: one module per target, registered in :data:`identification.export.TARGETS`.

A target module provides ``write(item: ExportItem, out_dir: Path) -> list[Path]``, which writes the files of one
identified model into ``out_dir`` (named after ``item.stem``) and returns them. Adding a target is one module
here and one line in the registry.

``statespace`` — python-control StateSpace (``.npz``, and a balanced truncation on request); ``fmu`` — the
pythonfmu FMU; ``standalone`` — the standalone C FMU (no Python at run time).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from ebb_model import BeamConfig, DiscreteStateSpace

__all__ = ["ExportItem"]


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
        The assembled state-space system at ``params``.
    options
        Target options (``reduce_order`` for ``statespace``).
    """

    stem: str
    title: str
    config: BeamConfig
    params: Mapping[str, float]
    system: DiscreteStateSpace
    options: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
