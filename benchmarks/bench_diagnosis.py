"""Wall time of the gap diagnosis on the blind family's records (``tests/test_diagnosis_blind.py``), with
``--family rig`` on the rig and specimen effects' (``tests/test_rig_effects.py``, ``tests/test_transducer_mass.py``:
other benches, excitations and sensors), or with ``--family broadband`` on what labs record most
(``tests/test_diagnosis_broadband.py``: the steel strip under random noise through one accelerometer, and the hint
family's records of the test suite, clamped–pinned beams whose baseline takes the effect up in another beam).

Each case's record is generated first (not timed: the independent FE truth is the test's, not the diagnosis'
cost), then :func:`diagnosis.run.diagnose` runs blind with its defaults (two worker processes) and its wall time
is printed with the verdict and the posterior probability the diagnosis gives the right answer (Laplace evidence
over the baseline and the refitted candidates, :mod:`diagnosis.problem.evidence`; "-" when the right effect was not
refitted); the JSON (``--json``) also gives, for a named effect, the share of the held-out gap its refit closes
and its largest size error against the withheld values, and the family's time per stage of the diagnosis
(``stage_seconds`` of ``gap.json``, :mod:`diagnosis.stages`) with its share.  The median and the largest time
over the chosen cases close the table.

With ``--family hint``: the hint family's correct and withheld-effect records as drawn now (every pair of ends with
every kind; blind, :func:`hint_cases`).  Each row says also whether the diagnosis printed its linear
time-invariant line (:data:`LTI_LINE`).

Run as ``python benchmarks/bench_diagnosis.py [CASE ...] [--family blind|rig|broadband|hint] [--json PATH]``
(default: every case of the blind family; ``--list`` names them).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import test_diagnosis_blind as blind  # noqa: E402
import test_diagnosis_broadband as broadband  # noqa: E402
import test_rig_effects as rig  # noqa: E402
import test_transducer_mass as transducer  # noqa: E402

from diagnosis.run import diagnose  # noqa: E402
from ebb_model.reference.excitation import band_limited_input  # noqa: E402
from ebb_model.reference.withheld import WithheldEffect  # noqa: E402
from figures import add_json_argument, write_figures  # noqa: E402  benchmarks/figures.py
from hint_family import first_draw, hint_bench, write_hint_case  # noqa: E402  tests/hint_family.py
from first_records import DECLARED, write_case  # noqa: E402  tests/first_records.py


#: The line a diagnosis prints when the measured modes' own oscillators leave the records far above the floor
#: (:mod:`diagnosis.search.modal_stage`, :mod:`diagnosis.search.rank`): every record of these families is linear
#: and time-invariant but the drifting ones, so the line's rate on them is counted (``lti_line``).
LTI_LINE = "linear time-invariant"


@dataclass(frozen=True)
class Case:
    """One record of a family: ``write(folder) -> (config, record path)`` (the independent generator's record),
    the withheld effect(s), the right verdicts, when the fitted variables are not the withheld ones (an
    armature, a crack's compliance, a transducer), the true values of the fitted variables, and the beam's length
    [m] (a place's error is a share of it)."""

    write: Callable[[Path], tuple[Any, Path]]
    effect: Any
    right: set[str]
    values: dict[str, float] | None = None
    length: float = 1.0


def _blind(kind: str, f_max: float, effect: Any, seed: int = 3) -> Callable[[Path], tuple[Any, Path]]:
    def write(folder: Path) -> tuple[Any, Path]:
        cfg = blind.bench_config(kind)
        return cfg, blind._write(folder, cfg, effect, seed=seed, f_max=f_max)
    return write


def cases() -> dict[str, Case]:
    """The blind family of ``tests/test_diagnosis_blind.py``."""
    out: dict[str, Case] = {}
    for c in blind.CASES:
        label, effect = c.values if hasattr(c, "values") else c
        out[f"disp-{label}"] = Case(_blind("displacement", 60.0, effect), effect, {label})
    for label, effect in blind.ACCEL_CASES:
        out[f"accel-{label}"] = Case(_blind("acceleration", 150.0, effect), effect, {label})
    for label, effect in blind.WIDE_CASES:
        out[f"wide-{label}"] = Case(_blind("displacement", 150.0, effect), effect, {label})
    out["disp-none"] = Case(_blind("displacement", 60.0, None, seed=5), None, {"none"})
    out["accel-none"] = Case(_blind("acceleration", 150.0, None), None, {"none"})
    for label, effect in blind.OUTSIDE_CASES:
        out[f"outside-{label}"] = Case(_blind("displacement", 60.0, effect), effect, {"unexplained"})
    for labels, effects in blind.PAIR_CASES:
        key = "+".join(sorted(labels))
        out["pair-" + key] = Case(_blind("displacement", 60.0, effects), effects, {key})
    return out


def rig_cases() -> dict[str, Case]:
    """The rig and specimen effects of ``tests/test_rig_effects.py`` and ``tests/test_transducer_mass.py``:
    other benches (pinned–pinned under compression with velocity sensors and a swept sine, a cantilever under a
    multisine or hammer hits, clamped–clamped with two forces, mixed sensors and pink noise), a spring to ground,
    a shaker's armature, a local stiffness loss, a transducer's mass, effects near the detection limit, a pair."""
    def swept(effect: Any) -> Callable[[Path], tuple[Any, Path]]:
        def write(folder: Path) -> tuple[Any, Path]:
            cfg = rig.pinned_bench()
            return cfg, rig._write_swept(folder, cfg, effect, seed=4)
        return write

    def cantilever(effect: Any, hits: bool = False) -> Callable[[Path], tuple[Any, Path]]:
        def write(folder: Path) -> tuple[Any, Path]:
            cfg = rig.cantilever_bench()
            u = rig.hammer(blind.N_SAMPLES) if hits else band_limited_input(blind.N_SAMPLES, blind.DT, 1.0, 60.0,
                                                                             seed=3)
            return cfg, rig._write_cantilever(folder, cfg, effect, u)
        return write

    def crack(values: dict[str, float]) -> dict[str, float]:   # what the records determine
        return _determined("stiffness_loss", values, 1.0)

    W = WithheldEffect
    spring, lag = W("grounded_spring", rig.SPRING), W("actuator_lag", rig.PAIR_LAG)
    pinned_crack, hammer_spring = rig.PINNED_CRACK, rig.HAMMER_SPRING
    out: dict[str, Case] = {
        "disp-grounded_spring": Case(_blind("displacement", 60.0, spring), spring, {"grounded_spring"}),
        "accel-grounded_spring": Case(_blind("acceleration", 150.0, spring), spring, {"grounded_spring"}),
        "pinned-none": Case(swept(None), None, {"none"}),
        "pinned-grounded_spring": Case(swept(W("grounded_spring", rig.PINNED_SPRING)),
                                       W("grounded_spring", rig.PINNED_SPRING), {"grounded_spring"}),
        "hammer-none": Case(cantilever(None, hits=True), None, {"none"}),
        "hammer-grounded_spring": Case(cantilever(W("grounded_spring", hammer_spring), hits=True),
                                       W("grounded_spring", hammer_spring), {"grounded_spring"}),
        "mixed-pink-none": Case(rig.write_mixed, None, {"none"}),
        "pair-actuator_lag+grounded_spring": Case(_blind("displacement", 60.0, [spring, lag]), [spring, lag],
                                                  {"actuator_lag+grounded_spring"}),
        "disp-stiffness_loss": Case(_blind("displacement", 60.0, W("stiffness_loss", rig.CRACK)), None,
                                    {"stiffness_loss"}, crack(rig.CRACK)),
        "accel-stiffness_loss": Case(_blind("acceleration", 150.0, W("stiffness_loss", rig.CRACK)), None,
                                     {"stiffness_loss"}, crack(rig.CRACK)),
        "pinned-stiffness_loss": Case(swept(W("stiffness_loss", pinned_crack)), None, {"stiffness_loss"},
                                      crack(pinned_crack)),
        "disp-armature": Case(_blind("displacement", 60.0, rig._armature(0.55, rig.ARMATURE)), None,
                              {"shaker_armature[F1]"}, rig.ARMATURE),
        "accel-armature": Case(_blind("acceleration", 150.0, rig._armature(0.55, rig.ARMATURE)), None,
                               {"shaker_armature[F1]"}, rig.ARMATURE),
        "pinned-armature": Case(swept(rig._armature(0.45, rig.PINNED_ARMATURE)), None,
                                {"shaker_armature[F1]"}, rig.PINNED_ARMATURE),
        "cantilever-armature": Case(cantilever(rig._armature(0.9, rig.CANTILEVER_ARMATURE)), None,
                                    {"shaker_armature[F1]"}, rig.CANTILEVER_ARMATURE),
        "disp-point_mass_at_drive": Case(_blind("displacement", 60.0, W("point_mass", rig.DRIVE_POINT_MASS)),
                                         W("point_mass", rig.DRIVE_POINT_MASS), {"point_mass"}),
    }
    for share in (0.01, 0.003):   # near the detection limit: 1 % and 0.3 % of the cantilever's mass
        mass = W("point_mass", {"mass": share, "x": 0.7})
        out[f"cantilever-point_mass-{100 * share:g}%"] = Case(cantilever(mass), mass, {"point_mass"})
    for prefix, kind, f_max in (("disp", "displacement", 60.0), ("accel", "acceleration", 150.0)):
        on_sensor = W("point_mass", {"mass": transducer.MASS, "x": 0.8})
        out[f"{prefix}-transducer_mass"] = Case(_blind(kind, f_max, on_sensor), None, {"transducer_mass[y2]"},
                                                {"mass": transducer.MASS})
    out["cantilever-transducer_mass_tip"] = Case(cantilever(W("point_mass", transducer.TIP_MASS)), None,
                                                 {"transducer_mass[y2]"}, {"mass": transducer.TIP_MASS["mass"]})
    return out


def broadband_cases() -> dict[str, Case]:
    """What labs record most (``tests/test_diagnosis_broadband.py``): the steel strip under random noise to fs/2.56
    through one tip accelerometer with nothing, a compliant clamp, a tip accelerometer's mass, a crack or a small
    mass mid-span withheld, and the hint family's records of the test suite (clamped–pinned beams under noise,
    a newcomer's config, a spring or a mass withheld; two correct records)."""
    def strip(effect: Any) -> Callable[[Path], tuple[Any, Path]]:
        return lambda folder: broadband._bench(folder, effect)

    def hint(i: int) -> Callable[[Path], tuple[Any, Path]]:
        return lambda folder: write_hint_case(first_draw(i, elements=128), folder)

    length = broadband.STRIP.length
    out = {"strip-none": Case(strip(None), None, {"none"}, length=length)}
    for effect, verdict, found in broadband.CASES:
        values = {k: truth for k, (truth, _) in found.items()}
        out[f"strip-{verdict}"] = Case(strip(effect), None, {verdict}, values, length)
    for i in (5, 9, 13, 45, 49, 53, 44, 48):
        case = first_draw(i, elements=128)
        right = {case.effect.name} if case.effect is not None else {"none"}
        out[f"hint{i}-{case.effect.name if case.effect is not None else 'none'}"] = Case(
            hint(i), case.effect, right, length=case.bench.length)
    return out


def hint_cases() -> dict[str, Case]:
    """The hint family's correct and withheld-effect quarters as drawn now (``tests/hint_family.py``: every pair of
    ends with every kind, axial load or none, one to three sensors of random kinds, noise to fs/2.56, to 0.2 fs or
    white, a newcomer's config; 32 records) — blind: the suite's broadband tests name records of the family's first
    draw, none of these but the clamped–pinned ones (5, 21, 37, 53) were looked at when the diagnosis was changed."""
    def hint(i: int) -> Callable[[Path], tuple[Any, Path]]:
        return lambda folder: write_hint_case(hint_bench(i, elements=128), folder)

    out = {}
    for i in range(64):
        case = hint_bench(i, elements=128)
        if case.kind in ("correct", "withheld effect"):
            name = case.effect.name if case.effect is not None else "none"
            out[f"h{i}-{case.bench.left}-{case.bench.right}-{name}"] = Case(hint(i), case.effect, {name},
                                                                           length=case.bench.length)
    return out


def declared_cases() -> dict[str, Case]:
    """Benches whose config declares parts (``tests/first_records.py``'s ``DECLARED``: the strip with its tip
    accelerometer's 45 g, a beam on a 300 N/m spring with a 30 g sensor), each with a mass at 0.3 m in the truth
    that the config does not declare (10 g, 1.3 % of the strip's; 20 g) — where a common scale of the unknowns
    moves the modes, so the start and the modal pattern must find the level too; a newcomer's config."""
    def bench(i: int, mass: float) -> Callable[[Path], tuple[Any, Path]]:
        return lambda folder: write_case(DECLARED[i], folder, WithheldEffect("point_mass", {"mass": mass, "x": 0.3}))

    return {f"{DECLARED[i].name}+{1000 * mass:g}g": Case(bench(i, mass), WithheldEffect(
        "point_mass", {"mass": mass, "x": 0.3}), {"point_mass"}, length=DECLARED[i].length)
        for i, mass in ((0, 0.010), (1, 0.020))}


FAMILIES = {"blind": cases, "rig": rig_cases, "broadband": broadband_cases, "hint": hint_cases,
            "declared": declared_cases}


def _determined(name: str, values: dict[str, float], length: float) -> dict[str, float]:
    """The withheld values of effect ``name`` that records determine: a soft segment's compliance
    ``(1/f − 1) ℓ/L`` and place, not its length and factor apart (``diagnosis.effects.local_stiffness``: on the
    hint family's record 57, the χ² with the length held and the rest refitted on 323 nodes lies within 1396–1413
    from 0.005 to 0.04 m for the truth's 0.031 m and is 1459 at 0.05 m, the compliance 4 % below to 2.5 % above the
    truth's along it); every other effect's values as withheld.  ``length``: the beam's (L of ``ℓ/L``)."""
    if name != "stiffness_loss":
        return values
    return {"x": values["x"], "compliance": (1.0 / values["factor"] - 1.0) * values["length"] / length}


def _size(doc: dict, case: Case) -> tuple[float | None, float | None]:
    """The named effect's share of the held-out gap closed [%] and its largest size error [%] against the
    withheld values the records determine (:func:`_determined`; a position as a share of the beam's length), when
    the verdict names it."""
    row = next((e for e in doc["effects"] if e["label"] == doc["verdict"]), None)   # (a transducer's row follows
    if row is None or row["refit"] is None:                                            # the point mass it nests in)
        return None, None
    refit = row["refit"]
    fitted, length = refit["effect_parameters"], case.length
    if case.values is not None:
        truth = case.values
    else:
        effects = case.effect if isinstance(case.effect, (list, tuple)) else [case.effect]
        if not all(isinstance(e, WithheldEffect) for e in effects):
            return 100.0 * refit["closed"], None
        truth = {}
        for e in effects:
            label = f"{e.name}[{e.sensor}]" if e.sensor else e.name
            truth |= {(k if len(effects) == 1 else f"{label}.{k}"): v
                      for k, v in _determined(e.name, dict(e.values), length).items()}
    errors = []
    for k, v in truth.items():
        got = fitted.get(k)
        if got is None:
            return 100.0 * refit["closed"], None
        errors.append(abs(got - v) / (length if k == "x" or k.endswith(".x") else abs(v)))
    return 100.0 * refit["closed"], 100.0 * max(errors)


def main() -> None:
    """Time the chosen cases and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cases", nargs="*", help="case names (default: all)")
    ap.add_argument("--family", choices=sorted(FAMILIES), default="blind",
                    help="the blind family (default), the rig and specimen effects, broadband records, the hint "
                         "family or the benches with declared parts")
    ap.add_argument("--list", action="store_true", help="list the case names")
    add_json_argument(ap)
    args = ap.parse_args()
    table = FAMILIES[args.family]()
    if args.list:
        print("\n".join(table))
        return
    chosen = args.cases or list(table)
    unknown = [c for c in chosen if c not in table]
    if unknown:
        ap.error(f"unknown case(s) {unknown}; --list names them")
    times = []
    rows = []
    print(f"{'case':<44}{'diagnosis [s]':>14}{'P(right)':>10}  verdict")
    for name in chosen:
        case = table[name]
        right = case.right
        with tempfile.TemporaryDirectory() as tmp:
            cfg, data = case.write(Path(tmp))
            t0 = time.perf_counter()
            said: list[str] = []
            d = diagnose(cfg, [data], None, plots=False, export=False, progress=said.append)
            dt = time.perf_counter() - t0
        verdict = "+".join(sorted(d.verdict.split("+")))
        times.append(dt)
        probs = {("+".join(sorted(k.split("+"))) if k != "none" else k): v for k, v in d.report.evidence.items()}
        p_right = max((v for k, v in probs.items() if k in right), default=None)
        shown = "-" if p_right is None else f"{p_right:.3g}"
        print(f"{name:<44}{dt:>14.1f}{shown:>10}  {d.verdict} ({'right' if verdict in right else 'WRONG'})",
              flush=True)
        closed, size_error = _size(d.document, case)
        stages = d.document.get("stage_seconds", {})
        rows.append({"case": name, "seconds": dt, "p_right": p_right, "verdict": d.verdict,
                     "right": verdict in right, "closed_percent": closed, "size_error_percent": size_error,
                     "slowest_stage": max(stages, key=stages.get) if stages else None, "stages": stages,
                     "lti_line": any(LTI_LINE in line for line in said)})
    print(f"median {statistics.median(times):.1f} s, largest {max(times):.1f} s over {len(times)} case(s); "
          f"the linear time-invariant line on {sum(r['lti_line'] for r in rows)}")
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
                              "lti_lines": sum(r["lti_line"] for r in rows),
                              "median_s": statistics.median(times), "largest_s": slowest["seconds"],
                              "slowest_case": slowest["case"], "total_s": sum(times), "stage_shares": shares,
                              "rows": rows})


if __name__ == "__main__":
    main()
