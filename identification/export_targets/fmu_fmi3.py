"""Export target ``fmu_fmi3``: the pythonfmu co-simulation FMU of the model in FMI 3.0 (``<stem>_fmi3.fmu``; the
deflection field as one array, the identified values as start values: :func:`fmu_build.build_fmu` with
``fmi=3``)."""
from __future__ import annotations

from pathlib import Path

from . import ExportItem
from . import fmu

__all__ = ["carries", "write"]


def carries(item: ExportItem) -> str:
    """What the file carries."""
    return fmu.carries(item).replace("FMU of the beam", "FMU of the beam in FMI 3.0", 1)


def write(item: ExportItem, out_dir: Path) -> list[Path]:
    """Write ``<stem>_fmi3.fmu`` into ``out_dir``; return it."""
    from fmu_build import build_fmu

    return [build_fmu(item.config.with_parameters(**item.params), out_dir / f"{item.stem}_fmi3.fmu",
                      system=item.beam, fmi=3)]
