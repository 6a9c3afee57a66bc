"""``ebb identify`` and ``ebb export``: parse, then call :func:`identification.run.identify` /
:func:`identification.export.export_points`."""
from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from .messages import Subcommands, add_target_argument
from .modes import add_modes_arguments, config_with_spectrum_modes

if TYPE_CHECKING:
    from identification.fisher import FisherReport

__all__ = ["add_parsers"]


def _cmd_identify(args: argparse.Namespace) -> int:
    from ebb_model.errors import Interrupted
    from identification.optimise import CHECKPOINT
    from identification.report import identified_lines
    from identification.run import identify
    from identification.uncertainty import FOLDER

    if not args.data:
        return _identify_from_modes(args)
    try:
        res = identify(config_with_spectrum_modes(args), args.data, args.out, backend=args.backend,
                       workers=args.workers, dask=args.dask, pop=args.pop, generations=args.generations, seed=args.seed,
                       resume=args.resume, force=args.force, algorithm=args.algorithm,
                       progress=not args.no_progress, export=not args.no_export, fmu=args.fmu,
                       fmu_parameters=args.fmu_parameters, fmu_inputs=args.fmu_inputs,
                       fmu_outputs=args.fmu_outputs, polish=args.polish, targets=args.target)
    except KeyboardInterrupt:
        if (Path(args.out) / CHECKPOINT).exists():
            raise Interrupted(f"interrupted; resume with --resume (checkpoint kept in {args.out})") from None
        raise Interrupted("interrupted before the first generation; nothing was written") from None
    f = cast("FisherReport", res.fisher_nominal)     # identify computes it (None only in a result read back)
    print(f"Fisher information at the nominal point: rank {f.rank}/{len(f.names)}, "
          f"condition number {f.condition_number:.3g}")
    for m in f.messages:
        print(f"  {m}")
    ds = res.data_start
    if ds:
        modes = ds["modes_hz"]
        seen = (f"{len(modes)} stable mode(s), {modes[0]:.4g}–{modes[-1]:.4g} Hz" if modes
                else "no stable mode")
        print(f"the records: {seen}; start " + json.dumps({k: float(f"{v:.6g}") for k, v in ds["parameters"].items()})
              + f" ({ds['n_evaluations']} evaluations)")
    p = res.pareto
    print(f"{len(p.X)} Pareto points after {p.generations} generations, {p.n_evaluations} evaluations")
    print("knee of the GA front (not polished): " + json.dumps({k: round(v, 6) for k, v in res.knee.items()}))
    for j, q in enumerate(res.polished[1:], start=1):
        values = {k: round(float(v), 6) for k, v in zip(p.parameter_names, q.x)}
        origin = "the records' start" if q.from_index < 0 else f"point {q.from_index}"
        print(f"polished {j} (from {origin}, {q.n_evaluations} evaluations): " + json.dumps(values))
    if res.polished:
        print(f"total evaluations (GA + polish): {res.n_evaluations}")
    for line in identified_lines(res):
        print(line)
    bound = res.out_dir / FOLDER / "bound.json"
    if bound.is_file():
        doc = json.loads(bound.read_text())
        if doc.get("band_hz"):
            lo, hi = doc["band_hz"]
            parts = [f"{s} median {v['median']:.3g}, max {v['max']:.3g}"
                     for s, v in doc["multiplicative_bound_in_band"].items()]
            print(f"uncertainty: multiplicative bound in the band {lo:.3g}–{hi:.3g} Hz: " + "; ".join(parts)
                  + f" ({doc['samples']} sampled models in {bound.parent})")
            if doc.get("samples_note"):
                print(f"  {doc['samples_note']}")
    for event in res.events:
        print(f"note: {event}")
    print(f"wrote {res.out_dir / 'pareto.json'}")
    return 0


def _identify_from_modes(args: argparse.Namespace) -> int:
    """``ebb identify CONFIG --out DIR`` without records: the measured natural frequencies alone
    (:func:`identification.modes_only.identify_from_modes`)."""
    from identification.modes_only import identify_from_modes

    res = identify_from_modes(config_with_spectrum_modes(args), args.out)
    print("no record: identified from the measured natural frequencies and the config's priors alone")
    for line in res.lines():
        print(line)
    print(f"wrote {Path(args.out) / 'identified.json'}")
    return 0


#: A tracked unknown's slope against the declared channel is a trend when it exceeds this many of its σ.
TREND_DEVIATIONS = 3.0


def _cmd_track(args: argparse.Namespace) -> int:
    """``ebb track CONFIG RECORD --channel NAME --decay|--ambient --out DIR`` (:func:`identification.tracking.track`):
    the table printed, ``tracked.json`` and ``tracked.png`` written at once into ``--out``."""
    import numpy as np

    from ebb_model.errors import ConfigError
    from ebb_model.io.jsonio import write_json
    from ebb_model.io.output import staged_dir
    from identification.config_file import load_identification_config
    from identification.output_record import declared_channel, sensor_record
    from identification.parameters import parameter_space
    from identification.plots import tracking_figure
    from identification.tracking import linear_in_channel, track

    out = Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(f"{out}: the output directory must not exist or be empty")
    cfg = load_identification_config(args.config)
    space = parameter_space(cfg)
    unknown = [v for v in (args.varies or ()) if v not in space.names]
    if unknown:
        raise ConfigError(f"--varies {', '.join(unknown)}: not among the config's unknowns ({', '.join(space.names)})")
    outputs = sensor_record(cfg, args.record)
    channel = declared_channel(args.record, args.channel)
    kind = "ambient" if args.ambient else "decay"
    rows = track(cfg, outputs, channel, kind=kind)
    judged: list[Any] = [None] * len(rows)
    if not args.no_diagnosis:
        from diagnosis.from_modes import diagnose_segments, segment_verdict

        judged = [segment_verdict(d) for d in diagnose_segments(cfg, rows)]
    fitted_rows = [r.identified for r in rows if r.identified is not None]
    names = list(fitted_rows[0].parameters) if fitted_rows else []
    bounds = dict(zip(space.names, zip(space.lower, space.upper)))

    def on_bound(name: str, value: float) -> str:
        lo, hi = bounds.get(name, (-np.inf, np.inf))
        return " (on its bound)" if min(abs(value - lo), abs(value - hi)) <= 1e-6 * (hi - lo) else ""
    lines = []
    for i, (r, d) in enumerate(zip(rows, judged)):
        head = (f"segment {i + 1}: {r.start_s:.3f}–{r.stop_s:.3f} s, {args.channel} {r.segment.level:.5g} ± "
                f"{r.segment.level_std:.2g}, {r.modes.frequencies_hz.size} mode(s)")
        if r.identified is None:
            lines.append(f"{head}: {r.why}")
        else:
            fitted = ", ".join(f"{n} {r.identified.parameters[n]:.5g} ± {r.identified.std[n]:.2g}"
                               + on_bound(n, r.identified.parameters[n]) for n in names if n not in r.identified.held)
            agree = "" if r.identified.agreement["agrees"] else " (the model does not reproduce the modes)"
            left = ("" if not r.left_out_hz else " (left out: " + ", ".join(f"{f:.4g}" for f in r.left_out_hz)
                    + " Hz, heavily damped beside a better-shown mode: the model matches the rest better without it)")
            lines.append(f"{head}: {fitted}{agree}{left}")
        if d is not None and d["verdict"]:
            lines.append(f"  diagnosis: {d['verdict']} — {d['reason']}")
    lines_fit = {n: linear_in_channel(rows, n) for n in names}
    for n, fit in lines_fit.items():
        if fit is None:
            continue
        if abs(fit["slope"]) <= TREND_DEVIATIONS * fit["slope_std"]:      # no line to speak of: say so, no R²
            lines.append(f"{n}: no trend with {args.channel} beyond {TREND_DEVIATIONS:g} σ (slope {fit['slope']:.3g} ± "
                         f"{fit['slope_std']:.2g})")
            continue
        lines.append(f"{n} against {args.channel}: slope {fit['slope']:.5g} ± {fit['slope_std']:.2g}, intercept "
                     f"{fit['intercept']:.5g} ± {fit['intercept_std']:.2g}, R² {fit['r2']:.4f}, χ²/dof "
                     f"{fit['chi2_per_dof']:.3g} over {int(fit['segments'])} segments (the segments' σ share the "
                     "priors' part; the line takes them as independent)")
    together: dict[str, Any] | None = None
    if args.varies:
        from identification.tracking import together_lines

        together, more = together_lines(cfg, rows, list(args.varies), args.channel)
        lines += more
    t = np.arange(channel.size) * cfg.time.dt
    with staged_dir(out) as tmp:
        write_json(tmp / "tracked.json", {"record": str(args.record), "channel": args.channel, "kind": kind,
                                          "segments": [r.to_dict() | {"diagnosis": d}
                                                       for r, d in zip(rows, judged)],
                                          "against_channel": lines_fit, "together": together})
        tracking_figure(t, channel, rows, args.channel, tmp / "tracked.png", together)
    for line in lines:
        print(line)
    print(f"wrote {out / 'tracked.json'} and {out / 'tracked.png'}")
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from identification.export import export_points
    from identification.result import IdentificationResult

    # a flag without indices means all of its kind ("--polished": every polished point)
    points = "all" if args.points == [] else args.points
    polished = "all" if args.polished == [] else args.polished
    result = IdentificationResult.read(args.dir)
    if args.ssp:
        from identification.export_ssp import check_ssp

        check_ssp(result)                                # before any file is written
    files = export_points(result, points, polished=polished, targets=args.target,
                          reduce_order=args.reduce_order, modes_up_to=args.modes_up_to)
    if args.ssp:
        from identification.export_ssp import export_ssp

        files.append(export_ssp(result, points, polished=polished, fmi=args.ssp_fmi))
    for f in files:
        print(f"wrote {f}")
    return 0


def add_parsers(sub: Subcommands) -> None:
    """Register ``identify`` and ``export`` on the ``ebb`` parser."""
    p = sub.add_parser("identify", help="multi-objective identification of the config's unknowns from data")
    p.add_argument("config", help="TOML config with identify = true parameters")
    p.add_argument("data", nargs="*", help="data files (.csv, .npz, .mat, .lvm, .uff, .txt); none: identify from the "
                                           "measured natural frequencies alone (--modes FILE, --decay "
                                           "FILE, --ambient FILE or [identification.modes])")
    p.add_argument("--out", required=True, help="result directory (checkpoint, pareto.json, plots, exports)")
    p.add_argument("--backend", default="auto", help="auto | native | fmu (default auto: the native model)")
    p.add_argument("--fmu", default=None, help="FMU to evaluate with --backend fmu (default: one built from CONFIG)")
    p.add_argument("--fmu-parameters", nargs="+", default=None,
                   help="FMU parameter names, one per unknown (default: the unknowns' names)")
    p.add_argument("--fmu-inputs", nargs="+", default=None,
                   help="FMU input names, one per actuator (default: the actuators' names)")
    p.add_argument("--fmu-outputs", nargs="+", default=None,
                   help="FMU output names, one per sensor (default: the sensors' names)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--workers", type=int, default=1, help="local worker processes (default 1)")
    g.add_argument("--dask", default=None, metavar="ADDRESS",
                   help="Dask scheduler address, or local:K for a local cluster of K worker processes set up "
                        "for model evaluations (profiler off, slower health checks; default: none, --workers)")
    add_modes_arguments(p)
    p.add_argument("--pop", type=int, default=None,
                   help="population size, at least 4 (default 40; with --resume the checkpoint's)")
    p.add_argument("--generations", type=int, default=None,
                   help="generations, at least 1 (default 30; with --resume the checkpoint's)")
    p.add_argument("--seed", type=int, default=None, help="random seed (default 1; with --resume the checkpoint's)")
    p.add_argument("--algorithm", default=None,
                   help="nsga2 | nsga3 (default nsga2; with --resume the checkpoint's)")
    p.add_argument("--polish", type=int, default=1, metavar="K",
                   help="after the GA, refine the K Pareto points nearest the knee (knee first) by bounded least "
                        "squares (default 1: the polished knee is the identified model; 0: the GA's knee, reported "
                        "as not polished)")
    p.add_argument("--resume", action="store_true",
                   help="continue from the checkpoint in --out (refused when the config, the data or an option "
                        "given differs from what it was made with)")
    p.add_argument("--force", action="store_true", help="run even if the Fisher matrix is singular")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-export", action="store_true", help="skip the exports at the end")
    add_target_argument(p, "export targets of every Pareto and polished point")
    p.set_defaults(func=_cmd_identify)
    p = sub.add_parser("track", help="a record without a force that changes during acquisition: per still segment "
                                     "of a declared channel, its modes and the unknowns they fix, as a time series")
    p.add_argument("config", help="TOML config with identify = true parameters and their priors")
    p.add_argument("record", help="the record: the config's sensors' columns and the declared channel")
    p.add_argument("--channel", required=True, help="the record's column that says when the set-up changed (a "
                                                     "position sensor, a load cell), by name or index")
    kind = p.add_mutually_exclusive_group(required=True)
    kind.add_argument("--decay", action="store_true", help="each segment rings down from the change before it")
    kind.add_argument("--ambient", action="store_true", help="each segment is stationary under an unmeasured force")
    p.add_argument("--no-diagnosis", action="store_true",
                   help="skip the diagnosis of each segment's modes (the effects weighed against them)")
    p.add_argument("--varies", nargs="+", default=None, metavar="NAME",
                   help="also fit every segment together: one beam, only these unknowns (a support's place "
                        "x_NAME, an axial load N) one value per segment")
    p.add_argument("--out", required=True, help="result directory (tracked.json, tracked.png)")
    p.set_defaults(func=_cmd_track)
    p = sub.add_parser("export", help="export Pareto points of a result directory (StateSpace, FMU)")
    p.add_argument("dir", help="result directory of 'ebb identify'")
    p.add_argument("--points", type=int, nargs="*", default=None,
                   help="Pareto point indices; the flag alone: all (default: all, unless --polished is given)")
    p.add_argument("--polished", type=int, nargs="*", default=None,
                   help="polished point indices; the flag alone: all (default: all, unless --points is given)")
    add_target_argument(p, "export targets")
    p.add_argument("--reduce-order", type=int, default=None,
                   help="also a balanced truncation of this order (default: none)")
    p.add_argument("--modes-up-to", type=float, default=None, metavar="HZ",
                   help="the StateSpace keeps the modes up to HZ, the others as a static correction (default: the "
                        "Nyquist frequency, no aliased modes; inf: every mode); the FMUs carry the whole beam")
    p.add_argument("--ssp", action="store_true",
                   help="also an SSP package: one standalone FMU and one parameter set per chosen point "
                        "(<config>.ssp; its SystemStructure.ssd bound to the identified model)")
    p.add_argument("--ssp-fmi", type=int, choices=(2, 3), default=2,
                   help="the FMI version of the SSP package's FMU (default 2)")
    p.set_defaults(func=_cmd_export)
