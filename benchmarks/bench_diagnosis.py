"""Wall time of the gap diagnosis on the blind family's records (``tests/test_diagnosis_blind.py``).

Each case's record is generated first (not timed: the independent FE truth is the test's, not the diagnosis'
cost), then :func:`diagnosis.run.diagnose` runs blind with its defaults (two worker processes) and its wall time
is printed with the verdict and the posterior probability the diagnosis gives the right answer (Laplace evidence
over the baseline and the refitted candidates, :mod:`diagnosis.evidence`; "-" when the right effect was not
refitted); the JSON (``--json``) also gives, for a named effect, the share of the held-out gap its refit closes
and its largest size error against the withheld values, and the family's time per stage of the diagnosis
(``stage_seconds`` of ``gap.json``, :mod:`diagnosis.stages`) with its share.  The median and the largest time
over the chosen cases close the table.

Run as ``python benchmarks/bench_diagnosis.py [CASE ...] [--json PATH]`` (default: every case; ``--list`` names them).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import test_diagnosis_blind as blind  # noqa: E402

from diagnosis.run import diagnose  # noqa: E402
from ebb_model.reference.withheld import WithheldEffect  # noqa: E402
from figures import add_json_argument, write_figures  # noqa: E402  benchmarks/figures.py


def cases() -> dict[str, tuple[str, float, object, set[str]]]:
    """``{name: (sensor kind, band top [Hz], withheld effect(s), right verdicts)}`` of the blind family."""
    out: dict[str, tuple[str, float, object, set[str]]] = {}
    for c in blind.CASES:
        label, effect = c.values if hasattr(c, "values") else c
        out[f"disp-{label}"] = ("displacement", 60.0, effect, {label})
    for label, effect in blind.ACCEL_CASES:
        out[f"accel-{label}"] = ("acceleration", 150.0, effect, {label})
    for label, effect in blind.WIDE_CASES:
        out[f"wide-{label}"] = ("displacement", 150.0, effect, {label})
    out["disp-none"] = ("displacement", 60.0, None, {"none"})
    out["accel-none"] = ("acceleration", 150.0, None, {"none"})
    for label, effect in blind.OUTSIDE_CASES:
        out[f"outside-{label}"] = ("displacement", 60.0, effect, {"unexplained"})
    for labels, effects in blind.PAIR_CASES:
        out["pair-" + "+".join(sorted(labels))] = ("displacement", 60.0, effects, {"+".join(sorted(labels))})
    return out


def _size(doc: dict, effect: object) -> tuple[float | None, float | None]:
    """The named effect's share of the held-out gap closed [%] and its largest size error [%] against the
    withheld values (a point mass's position as a share of the beam's length), when the verdict names it."""
    if not doc["effects"] or doc["effects"][0]["label"] != doc["verdict"] or doc["effects"][0]["refit"] is None:
        return None, None
    refit = doc["effects"][0]["refit"]
    effects = effect if isinstance(effect, (list, tuple)) else [effect]
    if not all(isinstance(e, WithheldEffect) for e in effects):
        return 100.0 * refit["closed"], None
    fitted, errors, length = refit["effect_parameters"], [], blind.bench_config().beam.length
    for e in effects:
        label = f"{e.name}[{e.sensor}]" if e.sensor else e.name
        for k, v in e.values.items():
            got = fitted.get(k if len(effects) == 1 else f"{label}.{k}")
            if got is None:
                return 100.0 * refit["closed"], None
            errors.append(abs(got - v) / (length if k == "x" else abs(v)))
    return 100.0 * refit["closed"], 100.0 * max(errors)


def main() -> None:
    """Time the chosen cases and print the table."""
    table = cases()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cases", nargs="*", help="case names (default: all)")
    ap.add_argument("--list", action="store_true", help="list the case names")
    add_json_argument(ap)
    args = ap.parse_args()
    if args.list:
        print("\n".join(table))
        return
    chosen = args.cases or list(table)
    unknown = [c for c in chosen if c not in table]
    if unknown:
        ap.error(f"unknown case(s) {unknown}; --list names them")
    seed = {"disp-none": 5}
    times = []
    rows = []
    print(f"{'case':<44}{'diagnosis [s]':>14}{'P(right)':>10}  verdict")
    for name in chosen:
        kind, f_max, effect, right = table[name]
        with tempfile.TemporaryDirectory() as tmp:
            cfg = blind.bench_config(kind)
            data = blind._write(Path(tmp), cfg, effect, seed=seed.get(name, 3), f_max=f_max)
            t0 = time.perf_counter()
            d = diagnose(cfg, [data], None, plots=False, export=False)
            dt = time.perf_counter() - t0
        verdict = "+".join(sorted(d.verdict.split("+")))
        times.append(dt)
        probs = {("+".join(sorted(k.split("+"))) if k != "none" else k): v for k, v in d.report.evidence.items()}
        p_right = max((v for k, v in probs.items() if k in right), default=None)
        shown = "-" if p_right is None else f"{p_right:.3g}"
        print(f"{name:<44}{dt:>14.1f}{shown:>10}  {d.verdict} ({'right' if verdict in right else 'WRONG'})",
              flush=True)
        closed, size_error = _size(d.document, effect)
        stages = d.document.get("stage_seconds", {})
        rows.append({"case": name, "seconds": dt, "p_right": p_right, "verdict": d.verdict,
                     "right": verdict in right, "closed_percent": closed, "size_error_percent": size_error,
                     "slowest_stage": max(stages, key=stages.get) if stages else None, "stages": stages})
    print(f"median {statistics.median(times):.1f} s, largest {max(times):.1f} s over {len(times)} case(s)")
    slowest = max(rows, key=lambda r: r["seconds"])
    # where the family's time goes: each stage's seconds over all cases (gap.json's stage_seconds)
    total: dict[str, float] = {}
    for r in rows:
        for stage, s in r["stages"].items():
            total[stage] = total.get(stage, 0.0) + s
    shares = [{"stage": k, "seconds": v, "share_percent": 100.0 * v / sum(times)}
              for k, v in sorted(total.items(), key=lambda kv: -kv[1])]
    shares.append({"stage": "outside the stages (reading, set-up, the report)",
                   "seconds": sum(times) - sum(total.values()),
                   "share_percent": 100.0 * (1.0 - sum(total.values()) / sum(times))})
    for s in shares:
        print(f"{s['stage']:<52}{s['seconds']:>8.1f} s{s['share_percent']:>7.1f} %")
    write_figures(args.json, {"cases": len(rows), "right": sum(r["right"] for r in rows),
                              "median_s": statistics.median(times), "largest_s": slowest["seconds"],
                              "slowest_case": slowest["case"], "total_s": sum(times), "stage_shares": shares,
                              "rows": rows})


if __name__ == "__main__":
    main()
