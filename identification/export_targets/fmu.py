"""Export target ``fmu``: the pythonfmu co-simulation FMU of the model (``<stem>.fmu``), the identified values as
start values (:func:`fmu_build.build_fmu`)."""
from __future__ import annotations

from pathlib import Path

from . import ExportItem

__all__ = ["carries", "write"]


def carries(item: ExportItem) -> str:
    """What the file carries."""
    without = f" (without {item.parts}: a signal effect outside the FMU's model)" if item.parts else ""
    return "FMU of the beam" + item.acquisition + without


def write(item: ExportItem, out_dir: Path) -> list[Path]:
    """Write ``<stem>.fmu`` into ``out_dir``; return it."""
    from fmu_build import build_fmu

    return [build_fmu(item.config.with_parameters(**item.params), out_dir / f"{item.stem}.fmu",
                      system=item.beam)]
