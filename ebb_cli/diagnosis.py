"""``ebb diagnose`` and ``ebb demo``: parse, then call :func:`diagnosis.run.diagnose` /
:func:`diagnosis.demo.run_demo`."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Callable, cast

from .messages import Subcommands, add_target_argument
from .modes import add_modes_arguments, config_with_spectrum_modes

__all__ = ["add_parsers"]


def _cmd_diagnose(args: argparse.Namespace) -> int:
    from diagnosis.run import diagnose

    def say(msg: str) -> None:
        if not args.quiet:
            print(msg, file=sys.stderr)

    if not args.data:
        return _from_modes(args)
    if args.each:
        return _each(args, say)
    if args.resume:
        from ebb_model.errors import ConfigError

        raise ConfigError("--resume continues a batch (--each) whose Dask scheduler went away")
    d = diagnose(config_with_spectrum_modes(args), args.data, args.out, holdout=args.holdout or (), result=args.result,
                 holdout_fraction=args.holdout_fraction, shortlist=args.shortlist, plots=not args.no_plots,
                 export=not args.no_export, targets=args.target, workers=args.workers, dask=args.dask,
                 earlier=args.earlier, progress=say)
    from diagnosis.report.html import text_report

    print(text_report(d.report))
    out_dir = cast(Path, d.out_dir)     # --out is required: the diagnosis was written there
    print(f"wrote {out_dir / 'gap.json'}")
    if d.report.corrected_files:
        _say_corrected(out_dir / "corrected")
    return 0


def _from_modes(args: argparse.Namespace) -> int:
    """``ebb diagnose CONFIG --out DIR`` without records (:func:`diagnosis.from_modes.diagnose_from_modes`)."""
    from diagnosis.from_modes import diagnose_from_modes
    from ebb_model.errors import ConfigError

    if args.each or args.resume or args.holdout or args.result or args.earlier:
        raise ConfigError("without records: --each, --resume, --holdout, --result and --earlier do not apply")
    d = diagnose_from_modes(config_with_spectrum_modes(args), args.out)
    print("no record: the effects weighed against the measured natural frequencies alone")
    for line in d.lines():
        print(line)
    print(f"wrote {Path(args.out) / 'gap.json'}")
    return 0


def _say_corrected(folder: Path) -> None:
    """What the corrected model's folder holds, in the words of its ``corrected.json`` (the export targets')."""
    import json

    files = json.loads((folder / "corrected.json").read_text(encoding="utf-8"))["files"]
    print(f"wrote the corrected model to {folder}:")
    for name, what in files.items():
        print(f"  {name}: {what}" if name != "note" else f"  note: {what}")


def _each(args: argparse.Namespace, say: Callable[[str], None]) -> int:
    """``--each``: one diagnosis per record, side by side (:func:`diagnosis.batch.diagnose_each`)."""
    from diagnosis.batch import diagnose_each
    from ebb_model.errors import ConfigError

    if args.holdout or args.result or args.earlier:
        raise ConfigError("--each: each record holds out its own tail; --holdout, --result and --earlier do not "
                          "apply")
    docs = diagnose_each(config_with_spectrum_modes(args), args.data, args.out, workers=args.workers,
                         dask=args.dask, progress=say, holdout_fraction=args.holdout_fraction,
                         shortlist=args.shortlist, plots=not args.no_plots, export=not args.no_export,
                         targets=args.target, resume=args.resume)
    for path, doc in zip(args.data, docs):
        print(f"{path}: verdict {doc['verdict']} ({Path(args.out) / Path(path).stem / 'gap.json'})")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from diagnosis.demo import run_demo

    run_demo(args.out, quick=args.quick, progress=not args.quiet)
    return 0


def add_parsers(sub: Subcommands) -> None:
    """Register ``diagnose`` and ``demo`` on the ``ebb`` parser."""
    p = sub.add_parser("diagnose", help="where model and data disagree, which effect explains it, how far it closes")
    p.add_argument("config", help="TOML config (the baseline model; identify = true unknowns with bounds)")
    p.add_argument("data", nargs="*", help="measured records to fit (.csv, .npz, .mat, .lvm, .uff, .txt); none: "
                                           "weigh the effects against the measured natural frequencies alone "
                                           "(--modes FILE, --decay FILE, --ambient FILE or [identification.modes])")
    p.add_argument("--holdout", nargs="+", default=None, metavar="FILE",
                   help="records held out entirely (default: hold out the tail of each record)")
    p.add_argument("--holdout-fraction", type=float, default=0.3,
                   help="fraction of each record held out when --holdout is not given (default 0.3)")
    p.add_argument("--result", default=None, metavar="DIR", help="an `ebb identify` result to start from")
    p.add_argument("--out", required=True, help="output directory (gap.json, plots); must not exist or be empty")
    p.add_argument("--earlier", default=None, metavar="GAP_JSON",
                   help="an earlier diagnosis of the same bench (its gap.json or directory): the models' odds "
                        "start from its posterior (the record its next experiment asked for, weighed with the "
                        "records that asked for it)")
    add_modes_arguments(p)
    p.add_argument("--shortlist", type=int, default=None,
                   help="effects refitted after the score test (default: [diagnosis] shortlist, else 4)")
    p.add_argument("--workers", type=int, default=2, metavar="K",
                   help="processes refitting the shortlisted effects (with --each: diagnosing the records) side "
                        "by side (default 2)")
    p.add_argument("--dask", default=None, metavar="ADDRESS",
                   help="run them on a Dask cluster instead: a scheduler address or local:K")
    p.add_argument("--each", action="store_true",
                   help="diagnose each record on its own, as independent tasks (OUT/<record stem>/ per record)")
    p.add_argument("--resume", action="store_true",
                   help="with --each: continue a batch whose Dask scheduler went away (OUT holds its checkpoint)")
    p.add_argument("--no-plots", action="store_true", help="skip the report plots")
    p.add_argument("--no-export", action="store_true",
                   help="do not write the corrected model (config and the export targets' files) when an "
                        "effect is named")
    add_target_argument(p, "export targets of the corrected model")
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=_cmd_diagnose)

    p = sub.add_parser("demo", help="the whole workflow on an embedded example (synthetic data with a withheld "
                                    "effect → identify → export → diagnose), about a minute on 2 cores")
    p.add_argument("--out", default="demo-out", help="output directory (default demo-out; must not exist or be empty)")
    p.add_argument("--quick", action="store_true", help="smaller run (for tests)")
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=_cmd_demo)
