"""``ebb modes`` and ``ebb simulate``: parse, then call :func:`ebb_model.reports.modes_report` /
:func:`ebb_model.io.signals_io.simulate_files`."""
from __future__ import annotations

import argparse
import json
import sys
from typing import Sequence

from .messages import Subcommands

__all__ = ["add_parsers", "parse_params"]


def parse_params(items: Sequence[str] | None) -> dict[str, float]:
    """``--param NAME=VALUE`` items as ``{name: value}``.

    Raises
    ------
    ConfigError
        An item without ``=`` or with a value that is not a number.
    """
    from ebb_model.errors import ConfigError

    out: dict[str, float] = {}
    for it in items or ():
        name, sep, value = it.partition("=")
        if not sep:
            raise ConfigError(f"--param {it!r}: expected NAME=VALUE")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ConfigError(f"--param {it!r}: {value!r} is not a number") from None
    return out


def _cmd_modes(args: argparse.Namespace) -> int:
    from ebb_model.reports import modes_report

    rep = modes_report(args.config, n_modes=args.n_modes, params=parse_params(args.param), band_hz=args.band,
                       progress=lambda line: print(f"ebb modes: {line}", file=sys.stderr, flush=True))
    if args.json:
        print(json.dumps(rep, indent=2))
        return 0
    errs = rep["grid"]["error_bandwidths"]
    print(f"{'mode':>4} {'frequency [Hz]':>16} {'damping ratio':>14} {'discrete [Hz]':>16} {'grid error [bw]':>16}")
    for i, (f, z, fd) in enumerate(zip(rep["frequencies_hz"], rep["damping_ratios"],
                                       rep["discrete_frequencies_hz"]), start=1):
        zs = "-" if z is None else f"{z:.3e}"
        es = f"{errs[i - 1]:.2g}" if i <= len(errs) else "-"
        print(f"{i:>4} {f:>16.6f} {zs:>14} {fd:>16.6f} {es:>16}")
    print(rep["grid"]["summary"])
    print(f"max growth factor (Bistritz, unbounded grid): {rep['max_growth_factor']:.15g}")
    print(f"spectral radius of Phi (finite beam):         {rep['spectral_radius']:.15g}")
    verdict = "stable" if rep["stable"] else "UNSTABLE"
    if rep["marginal"] and rep["stable"]:
        verdict += " (marginal: zeros on the unit circle, undamped)"
    print(f"verdict: {verdict}")
    for m in rep["messages"]:
        print(f"note: {m}")
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    from ebb_model.io.signals_io import simulate_files

    out = simulate_files(args.config, args.input, args.out, params=parse_params(args.param))
    print(f"wrote {out}")
    return 0


def add_parsers(sub: Subcommands) -> None:
    """Register ``modes`` and ``simulate`` on the ``ebb`` parser."""
    p = sub.add_parser("modes", help="natural frequencies, damping and stability of a config")
    p.add_argument("config", help="TOML config file")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument("--n-modes", type=int, default=10, help="number of modes to list (default 10)")
    p.add_argument("--band", type=float, metavar="HZ",
                   help="top frequency of the record: the grid advice covers the modes up to it "
                        "(default: the listed modes)")
    p.add_argument("--param", action="append", metavar="NAME=VALUE", help="override a parameter")
    p.set_defaults(func=_cmd_modes)
    p = sub.add_parser("simulate", help="simulate a config for inputs from a CSV file")
    p.add_argument("config", help="TOML config file")
    p.add_argument("--input", required=True, help="CSV with a 'time' column and one column per actuator")
    p.add_argument("--out", required=True, help="output CSV: 'time' and one column per sensor")
    p.add_argument("--param", action="append", metavar="NAME=VALUE", help="override a parameter")
    p.set_defaults(func=_cmd_simulate)
