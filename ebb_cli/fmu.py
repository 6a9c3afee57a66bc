"""``ebb build-fmu``: parse, then call :func:`fmu_build.build_fmu` (or, with ``--standalone``,
:func:`fmu_build.build_standalone_fmu`)."""
from __future__ import annotations

import argparse

from .messages import Subcommands

__all__ = ["add_parsers"]


def _cmd_build_fmu(args: argparse.Namespace) -> int:
    if args.standalone:
        from fmu_build.standalone import build_standalone_fmu

        path = build_standalone_fmu(args.config, args.out, field=args.field, fmi=args.fmi)
    else:
        from fmu_build import build_fmu

        path = build_fmu(args.config, args.out, field=args.field, fmi=args.fmi)
    print(path)
    return 0


def add_parsers(sub: Subcommands) -> None:
    """Register ``build-fmu CONFIG --out FILE [--field] [--standalone] [--fmi {2,3}]`` on the ``ebb`` parser."""
    p = sub.add_parser(
        "build-fmu",
        help="package the beam as an FMI 2.0 or 3.0 co-simulation FMU",
        description="Build an FMI 2.0 (or, with --fmi 3, FMI 3.0) co-simulation FMU (Linux x86-64) of the beam "
                    "described by CONFIG. The FMU runs on this Python interpreter (numpy, scipy and numba "
                    "required); in FMI 3.0 the deflection field is one array w. With "
                    "--standalone: an FMU in C (co-simulation and model exchange) that needs no Python, in FMI 2.0 "
                    "or, with --fmi 3, FMI 3.0 (the deflection field as one array w, adjoint derivatives). The "
                    "channels' converter delays (delay in CONFIG) are carried as delay lines of past output samples "
                    "(the standalone FMU then offers co-simulation only).",
    )
    p.add_argument("config", metavar="CONFIG", help="TOML config file")
    p.add_argument("--out", required=True, metavar="FILE", help="the .fmu file to write")
    p.add_argument("--field", action="store_true",
                   help="also output the deflection w[i] at every grid node")
    p.add_argument("--standalone", action="store_true",
                   help="build the standalone C FMU instead (model exchange and co-simulation, no Python at run "
                        "time; the model's C source is inside, compiled with gcc for linux64)")
    p.add_argument("--fmi", type=int, choices=(2, 3), default=2,
                   help="the FMI version: 2 (default) or 3 (binaries/x86_64-linux; the Python FMU through "
                        "pythonfmu3, the standalone one in C)")
    p.set_defaults(func=_cmd_build_fmu)
