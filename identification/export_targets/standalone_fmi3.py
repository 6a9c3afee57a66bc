"""Export target ``standalone_fmi3``: the standalone C FMU of the model in FMI 3.0 (``<stem>_standalone_fmi3.fmu``;
no Python at run time, the deflection field as one array, adjoint derivatives:
:func:`fmu_build.standalone.build_standalone_fmu` with ``fmi=3``)."""
from __future__ import annotations

from pathlib import Path

from . import ExportItem
from .standalone import check

__all__ = ["carries", "check", "write"]


def carries(item: ExportItem) -> str:
    """What the file carries."""
    without = f" (without {item.parts}: a signal effect outside the FMU's model)" if item.parts else ""
    return "standalone C FMU of the beam in FMI 3.0 (no Python at run time)" + item.acquisition + without


def write(item: ExportItem, out_dir: Path) -> list[Path]:
    """Write ``<stem>_standalone_fmi3.fmu`` into ``out_dir``; return it."""
    from fmu_build.standalone import build_standalone_fmu

    return [build_standalone_fmu(item.config.with_parameters(**item.params),
                                 out_dir / f"{item.stem}_standalone_fmi3.fmu", system=item.beam, fmi=3)]
