"""The ``ebb build-fmu`` sub-command: parses arguments and calls :func:`build_fmu`.

Wiring into the main CLI::

    from fmu_build import add_parser
    add_parser(subparsers)          # registers "build-fmu"
    args = parser.parse_args(argv)
    return args.func(args)          # run_build_fmu; typed errors propagate (exit code 2)
"""
from __future__ import annotations

import argparse

from .builder import build_fmu

__all__ = ["add_parser", "run_build_fmu"]


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``build-fmu CONFIG --out FILE [--field] [--standalone]`` on ``subparsers``.

    Parameters
    ----------
    subparsers
        The object returned by ``ArgumentParser.add_subparsers()``.

    Returns
    -------
    argparse.ArgumentParser
        The sub-command's parser; its default ``func`` is :func:`run_build_fmu`.
    """
    p = subparsers.add_parser(
        "build-fmu",
        help="package the beam as an FMI 2.0 co-simulation FMU",
        description="Build an FMI 2.0 co-simulation FMU (Linux x86-64) of the beam described by CONFIG. "
                    "The FMU runs on this Python interpreter (numpy, scipy and numba required). With "
                    "--standalone: an FMU in C (co-simulation and model exchange) that needs no Python.",
    )
    p.add_argument("config", metavar="CONFIG", help="TOML config file")
    p.add_argument("--out", required=True, metavar="FILE", help="the .fmu file to write")
    p.add_argument("--field", action="store_true",
                   help="also output the deflection w[i] at every grid node")
    p.add_argument("--standalone", action="store_true",
                   help="build the standalone C FMU instead (model exchange and co-simulation, no Python at run "
                        "time; the model's C source is inside, compiled with gcc for linux64)")
    p.set_defaults(func=run_build_fmu)
    return p


def run_build_fmu(args: argparse.Namespace) -> int:
    """Handler of ``build-fmu``: build (the pythonfmu FMU, or with ``--standalone`` the C one), print the path,
    return 0.

    Raises
    ------
    ConfigError, ParameterError, StabilityError, FmuError
        Left to the caller, which maps them to exit code 2.
    """
    if args.standalone:
        from .standalone import build_standalone_fmu

        path = build_standalone_fmu(args.config, args.out, field=args.field)
    else:
        path = build_fmu(args.config, args.out, field=args.field)
    print(path)
    return 0
