"""Command-line interface ``ebb``: parses arguments and calls the API, nothing more.

Each subcommand mirrors an API function (FMPy's ``cli.py`` habit); every flag
is the kebab-case form of an API keyword.  Errors raised on purpose
(:class:`~ebb_model.errors.EbbError`) print one clear message and exit with
code 2, leaving no partial output.  Subcommands of the higher layers
(``build-fmu``, ``identify``, …) are registered by their own packages.
"""
from __future__ import annotations

import argparse
import importlib
import json
import math
import sys
from pathlib import Path
from typing import Any, Sequence

__all__ = ["main"]

#: (module, function) pairs that add subcommands of the higher layers, if installed.
_PLUGINS: tuple[tuple[str, str], ...] = (
    ("fmu_build.cli", "add_parser"),
    ("identification.cli", "add_parser"),
    ("diagnosis.cli", "add_parser"),
)


def _parse_params(items: Sequence[str] | None) -> dict[str, float]:
    from .errors import ConfigError

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


def modes_report(config_path: str | Path, *, n_modes: int = 10,
                 params: dict[str, float] | None = None, band_hz: float | None = None) -> dict[str, Any]:
    """Everything ``ebb modes`` prints, as a dict (JSON-ready); ``band_hz``: the record's top frequency, for the
    grid advice (default: the listed modes)."""
    from . import analyse_stability, discrete_frequencies, fast_model, load_config, modes
    from .grid_advice import grid_advice

    cfg = load_config(config_path)
    ma = modes(cfg, params, n_modes=n_modes)
    grid = grid_advice(cfg, params, n_modes=n_modes, band_hz=band_hz)
    fm = fast_model(cfg, params)
    fd, zd = discrete_frequencies(cfg, params)
    rep = analyse_stability(cfg, params, spectral_radius=fm.spectral_radius())
    from .jsonio import jsonable

    return jsonable({
        "frequencies_hz": ma.frequencies_hz.tolist(),
        "damping_ratios": ma.damping_ratios.tolist(),
        "discrete_frequencies_hz": fd[:n_modes].tolist(),
        "discrete_damping_ratios": zd[:n_modes].tolist(),
        "max_growth_factor": rep.max_growth_factor,
        "spectral_radius": rep.spectral_radius,
        "stable": rep.stable,
        "grid_stable": rep.grid_stable,
        "marginal": rep.marginal,
        "analyses_agree": rep.agree,
        "bistritz_bounds": {k: list(v) for k, v in rep.bounds.items()},
        "dt_max": rep.dt_max,
        "messages": list(rep.messages),
        "proportional_damping": ma.proportional,
        "grid": grid.to_dict() | {"summary": grid.summary()},
    })


def _cmd_modes(args: argparse.Namespace) -> int:
    if args.band is not None and not (math.isfinite(args.band) and args.band > 0):
        from .errors import ConfigError

        raise ConfigError(f"--band must be a positive frequency in Hz, got {args.band:g}")
    rep = modes_report(args.config, n_modes=args.n_modes, params=_parse_params(args.param), band_hz=args.band)
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


def simulate_files(config_path: str | Path, input_csv: str | Path, out_csv: str | Path, *,
                   params: dict[str, float] | None = None) -> Path:
    """Read inputs from CSV, simulate on the fast path, write outputs to CSV (atomically).

    Nothing is written when anything fails.
    """
    from . import fast_model, load_config, simulate
    from .assemble import check_stable
    from .parameter_values import resolve_parameters
    from .errors import ConfigError
    from .signals_io import read_signal_csv
    from .simulate import SimulationResult

    cfg = load_config(config_path)
    out = Path(out_csv)
    if not out.parent.is_dir():
        raise ConfigError(f"--out {out}: directory {out.parent} does not exist")
    t, u = read_signal_csv(input_csv, cfg.input_names, dt=cfg.time.dt)
    p = resolve_parameters(cfg, params)
    model = fast_model(cfg, p)
    check_stable(cfg, p, model.spectral_radius())
    res = simulate(model, u)
    SimulationResult(t, res.outputs, res.output_names).to_csv(out)
    return out


def _cmd_simulate(args: argparse.Namespace) -> int:
    out = simulate_files(args.config, args.input, args.out, params=_parse_params(args.param))
    print(f"wrote {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``ebb`` argument parser with all available subcommands."""
    parser = argparse.ArgumentParser(prog="ebb", description="Euler-Bernoulli beam under axial load: "
                                     "model, FMU, identification and sim-to-real gap diagnosis.")
    sub = parser.add_subparsers(dest="command", required=True)
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
    for mod, fn in _PLUGINS:
        try:
            m = importlib.import_module(mod)
        except ModuleNotFoundError as exc:
            if exc.name and (exc.name == mod or mod.startswith(exc.name + ".")):
                continue
            raise
        getattr(m, fn)(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ebb`` console script; returns the exit code."""
    import warnings

    from threadpoolctl import threadpool_limits

    from .errors import DataWarning, EbbError, Interrupted

    parser = build_parser()
    args = parser.parse_args(argv)
    prog = f"ebb {args.command}"

    def one_line(message: Warning | str, category: type[Warning], *_a: Any, **_k: Any) -> None:
        print(f"{prog}: warning: {message}", file=sys.stderr)

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always", DataWarning)
            warnings.showwarning = one_line
            # the matrices are small: BLAS threads only add overhead (and thrash on 2 cores)
            with threadpool_limits(limits=1, user_api="blas"):
                return int(args.func(args) or 0)
    except Interrupted as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except EbbError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
