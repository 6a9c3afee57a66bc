"""``ebb demo``: the whole workflow on an embedded example, in about a minute on 2 cores.

1. *Truth*: a clamped–pinned test bench simulated by the independent
   reference (cubic-Hermite finite elements integrated exactly in time, not
   the identifying finite-difference model) with an effect the model does not
   have — a compliant clamp — and 1 % measurement noise.
2. *Identify* EI, ρA, c and N with the multi-objective GA and the
   least-squares polish of the knee (:mod:`identification`, defaults).
3. *Export* the identified model (the polished knee) as an FMU and a
   python-control StateSpace.
4. *Diagnose* the remaining gap blind (:func:`diagnosis.run.diagnose`),
   export the corrected model, and show identified, corrected and true values
   side by side.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ebb_model.io.output import atomic_path, check_new_output_dir, make_dir

if TYPE_CHECKING:
    from .report.result import GapReport

__all__ = ["DEMO_CONFIG", "run_demo"]

#: The embedded default set-up (TOML).
DEMO_CONFIG = """\
# ebb demo: clamped-pinned test bench, one shaker force, two displacement sensors.
[beam]
length = 1.0
nodes = 60
left = "clamped"
right = "pinned"

[time]
dt = 5e-4
theta = 0.25
substeps = 4

[parameters]
EI   = { value = 12.0, bounds = [5.0, 20.0], identify = true }
rhoA = { value = 1.2,  bounds = [0.5, 2.0],  identify = true }
c    = { value = 1.0,  bounds = [0.2, 8.0],  identify = true }
eta  = { value = 0.0 }
N    = { value = 30.0, bounds = [0.0, 60.0], identify = true }

[[actuators]]
name = "F1"
x = 0.55

[[sensors]]
name = "y1"
x = 0.35
kind = "displacement"

[[sensors]]
name = "y2"
x = 0.8
kind = "displacement"
"""

#: Parameters of the truth (the config's values above are only the starting guess).
TRUTH = {"EI": 10.0, "rhoA": 1.0, "c": 2.0, "N": 20.0}
WITHHELD = ("boundary_rotational_left", {"kr": 300.0})


def run_demo(out: str | Path = "demo-out", *, quick: bool = False, progress: bool = True) -> dict:
    """Run the demo into ``out`` (must not exist or be empty); print and return a short report."""
    from ebb_model.reference.excitation import band_limited_input
    from ebb_model.reference.synthetic import synthesize
    from ebb_model.reference.withheld import WithheldEffect
    from identification.export import export_points
    from identification.run import identify
    from identification.config_file import load_identification_config

    from .report.html import text_report
    from .run import diagnose

    out = make_dir(check_new_output_dir(out), exist_ok=True)
    say = print if progress else (lambda *_a, **_k: None)
    t0 = time.perf_counter()
    cfg_path = out / "config.toml"
    with atomic_path(cfg_path) as tmp:
        tmp.write_text(DEMO_CONFIG)
    cfg = load_identification_config(cfg_path)

    say("1/4 truth: Hermite FE, exact in time, with a withheld effect, 1 % noise")
    n = 4000 if quick else 6000
    u = band_limited_input(n, cfg.time.dt, 2.0, 60.0, seed=11)
    rec = synthesize(cfg, u, params=TRUTH, effect=WithheldEffect(WITHHELD[0], WITHHELD[1]), noise=0.01, seed=12)
    data = out / "measured.csv"
    table = np.column_stack([rec.time, rec.inputs, rec.outputs])
    with atomic_path(data) as tmp:
        np.savetxt(tmp, table, delimiter=",", header="time,F1,y1,y2", comments="", fmt="%.10g")

    say("2/4 identify EI, rhoA, c, N (NSGA-II + least-squares polish of the knee)")
    res = identify(cfg_path, [data], out / "identify", pop=16 if quick else 24, generations=4 if quick else 12,
                   seed=1, progress=progress, export=False)
    identified = res.best

    say("3/4 export the identified model (polished knee): FMU + python-control StateSpace")
    files = export_points(res, polished=[0])

    say("4/4 diagnose the remaining gap (blind); export the corrected model")
    d = diagnose(cfg_path, [data], out / "diagnosis", result=res,
                 progress=(lambda m: print(f"    {m}")) if progress else None)
    report = text_report(d.report)
    truth_label = WITHHELD[0]
    title = "ebb demo: identify a beam from synthetic data with a withheld effect, export it, diagnose the gap"
    comparison = comparison_table(identified, d.report, TRUTH, WITHHELD)
    outcome = f"withheld effect: {truth_label} -> diagnosis {'RIGHT' if d.verdict == truth_label else 'WRONG'}"
    elapsed = f"elapsed: {time.perf_counter() - t0:.0f} s; results in {out}"
    lines = [title, "=" * len(title), "", *comparison,
             "exports:  " + ", ".join(str(f) for f in files),
             *([f"corrected model: {out / 'diagnosis' / 'corrected'}"] if d.report.corrected_files else []),
             "", report, "",
             outcome, elapsed]
    text = "\n".join(lines)
    with atomic_path(out / "report.txt") as tmp:
        tmp.write_text(text + "\n")
    from dataclasses import replace

    from ebb_model.io.htmlio import PAGE, Section, write_page
    from identification.report import html_sections as identify_sections

    from .report.html import html_sections

    summary = Section("Result", lead=outcome, preformatted="\n".join(comparison),
                      paragraphs=(elapsed, "exports: " + ", ".join(str(f) for f in files)))
    write_page(out / PAGE, title, [summary, *(replace(s, title=f"Identification — {s.title}")
                                              for s in identify_sections(res)),
                                   *(replace(s, title=f"Diagnosis — {s.title}")
                                     for s in html_sections(d.report, out / "diagnosis"))])
    print(text)
    return {"verdict": d.verdict, "truth": truth_label, "identified": identified,
            "exports": [str(f) for f in files], "document": d.document}


def comparison_table(identified: dict[str, float], report: GapReport, truth: dict[str, float],
                     withheld: tuple[str, dict[str, float]]) -> list[str]:
    """Identified, corrected (diagnosis' refit with its effect) and true values side by side, with units, and
    the held-out gap before/after."""
    from ebb_model.beam import PARAMETER_UNITS
    from ebb_model.reference.withheld import EFFECT_CATALOGUE

    row = report.row(report.verdict)
    refit = row.refit if row is not None else None
    corrected = refit.baseline_parameters if refit is not None else {}
    lines = [f"{'':<28}{'unit':<10}{'identified':>12}{'corrected':>12}{'truth':>12}"]
    for k, v in identified.items():
        c = f"{corrected[k]:.4g}" if k in corrected else "-"
        lines.append(f"{k:<28}{PARAMETER_UNITS.get(k, ''):<10}{v:>12.4g}{c:>12}{truth.get(k, float('nan')):>12.4g}")
    name, values = withheld
    spec = EFFECT_CATALOGUE[name]
    found = refit.effect_parameters if refit is not None and row is not None and row.effect == name else {}
    for p, unit in zip(spec.parameters, spec.units):
        c = f"{found[p]:.4g}" if p in found else "-"
        lines.append(f"{name + '.' + p:<28}{unit:<10}{'-':>12}{c:>12}{values[p]:>12.4g}")
    if refit is not None:
        before = ", ".join(f"{k} {v:.3g}" for k, v in refit.heldout_gap_ratio_before.items())
        after = ", ".join(f"{k} {v:.3g}" for k, v in refit.heldout_gap_ratio_after.items())
        lines.append(f"held-out gap ratio (1 = noise floor): {before} -> corrected {after}")
    return lines
