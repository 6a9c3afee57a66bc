"""Export target ``standalone``: the standalone C FMU of the model (``<stem>_standalone.fmu``; no Python at run
time, :func:`fmu_build.standalone.build_standalone_fmu`)."""
from __future__ import annotations

from pathlib import Path

from ebb_model import BeamConfig

from . import ExportItem

__all__ = ["carries", "check", "write"]


def check(config: BeamConfig) -> None:
    """Refuse, before a run, a config the standalone FMU cannot carry
    (:func:`fmu_build.standalone.check_standalone`)."""
    from fmu_build.standalone import check_standalone

    check_standalone(config)


def carries(item: ExportItem) -> str:
    """What the file carries."""
    without = f" (without {item.parts}: a signal effect outside the FMU's model)" if item.parts else ""
    return "standalone C FMU of the beam (no Python at run time)" + item.acquisition + without


def write(item: ExportItem, out_dir: Path) -> list[Path]:
    """Write ``<stem>_standalone.fmu`` into ``out_dir``; return it."""
    from fmu_build.standalone import build_standalone_fmu

    return [build_standalone_fmu(item.config.with_parameters(**item.params), out_dir / f"{item.stem}_standalone.fmu",
                                 system=item.beam)]
