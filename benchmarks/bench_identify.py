"""Identification benchmark: evaluations and wall time until all four parameters are within 1 % of truth.

Case: the synthetic 4-parameter case of ``tests/test_recovery.py`` — data from
the cubic-Hermite FE beam + Newmark (a different discretisation), clamped–
clamped, one force (a continuous 0.67–110 Hz multisine covering modes 1–4,
sampled at 1 kHz, 1.5 s), two displacement sensors, 1 % noise; unknowns EI,
rhoA, c, N; the FD model with 199 interior nodes and 20 sub-steps.

Every run is the real workflow, :func:`identification.run.identify` (NSGA-II,
then the least-squares polish of the knee), watched through its
``on_progress`` hook: after every GA generation the knee of the current front,
after the polish the polished knee, is compared with the truth.  Reported per
run: the model evaluations (GA + polish residuals + polish Jacobian columns +
the final objective evaluation of the polished point, plus the ``2 × 4``
simulations of the Fisher check at the nominal point before the GA) and the
wall time from the call until the first check with all four parameters within
1 % — and the total search time (GA + polish; the Cramér–Rao bounds, plots and
files written afterwards are not timed).

Configurations:

(a) native backend, 2 local worker processes (target ≤ 3000 evaluations, ≤ 30 s);
(b) FMU backend (fmpy, the FMU built from the config once, outside the timing),
    2 local worker processes;
(c) FMU backend on Dask with 1 and with 2 single-threaded worker processes —
    the same seeded run, so the same candidates — and the speed-up of the
    search time (target ≥ 1.7×), on two kinds of cluster (``--cluster``):
    a ``LocalCluster`` with Dask's default settings, and the tool's own local
    cluster (``--dask local:K``, :func:`identification.cluster.local_cluster`:
    worker profiler off, slower health checks).  The clusters are started
    before timing and reused across repeats.

Medians over ``--repeats`` runs.  BLAS is limited to one thread.  The machine
load (1-minute load average) is printed before and after: on a shared 2-core
machine, other processes take cores from the workers.

Usage::

    python benchmarks/bench_identify.py [--repeats 3] [--pop 24] [--generations 10]
        [--fmu-repeats 1] [--parts abc] [--cluster both|defaults|local] [--json out.json]
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for p in (ROOT, ROOT / "tests"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

from identification.run import Progress, identify  # noqa: E402
from test_recovery import TRUTH, fd_config, recovery_case  # noqa: E402
from figures import write_figures  # noqa: E402  benchmarks/figures.py

TOL = 0.01


@dataclass
class RunRecord:
    """One identification run."""

    label: str
    evaluations_to_target: int | None
    seconds_to_target: float | None
    stage_at_target: str | None
    search_evaluations: int
    search_seconds: float
    ga_seconds: float
    first_generation_seconds: float
    errors_percent: dict[str, float]
    worker_cpu_share: float | None = None


def _within(x: np.ndarray, names: tuple[str, ...]) -> bool:
    return all(abs(v / TRUTH[n] - 1.0) <= TOL for n, v in zip(names, x))


def _cpu_seconds() -> float:
    """CPU time of the calling process (user + system)."""
    t = os.times()
    return t.user + t.system


def run_once(label: str, data: Path, work: Path, names: tuple[str, ...], *, noise_std: np.ndarray,
             client: Any = None, **kw: Any) -> RunRecord:
    """One ``identify`` run, watched generation by generation.

    With a Dask ``client``, the run goes to its cluster and the workers' CPU time is measured: its
    share of ``wall time × workers`` shows how much of their cores the workers actually got.
    """
    if client is not None:
        kw["dask"] = client.scheduler.address
        cpu0 = client.run(_cpu_seconds)
    out = Path(tempfile.mkdtemp(dir=work)) / "out"
    n_fisher = 2 * len(names)  # simulations of the nominal Fisher check, before the GA
    hit: dict[str, Any] = {}
    last: dict[str, Any] = {}
    t0 = time.perf_counter()

    def watch(p: Progress) -> None:
        t = time.perf_counter() - t0
        last.update(t=t, n=p.n_evaluations + n_fisher, x=p.X[p.knee])
        if p.stage == "generation":
            last["t_ga"] = t
            last.setdefault("t_first", t)
        if not hit and _within(p.X[p.knee], names):
            hit.update(n=p.n_evaluations + n_fisher, t=t, stage=f"{p.stage} {p.step}")

    cfg = fd_config()
    identify(cfg, [data], out, progress=False, export=False, noise_std=noise_std, on_progress=watch, **kw)
    share = None
    if client is not None:
        wall = time.perf_counter() - t0
        cpu1 = client.run(_cpu_seconds)
        share = sum(cpu1[w] - cpu0[w] for w in cpu1) / (wall * len(cpu1))
    shutil.rmtree(out.parent, ignore_errors=True)
    errs = {n: 100.0 * (float(v) / TRUTH[n] - 1.0) for n, v in zip(names, last["x"])}
    return RunRecord(label, hit.get("n"), hit.get("t"), hit.get("stage"), int(last["n"]), float(last["t"]),
                     float(last["t_ga"]), float(last["t_first"]), errs, share)


def _median(values: list[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return statistics.median(vals) if len(vals) == len(values) and vals else None


def _speedup(by_workers: dict[int, list[RunRecord]], seconds: Any) -> float | None:
    """Median ``seconds(run)`` on 1 worker over the median on 2 workers."""
    t1 = _median([seconds(r) for r in by_workers[1]])
    t2 = _median([seconds(r) for r in by_workers[2]])
    return t1 / t2 if t1 and t2 else None


def _fmt(v: float | None, spec: str) -> str:
    return "—" if v is None else format(v, spec)


def _load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


#: The clusters of configuration (c).
CLUSTERS = {"defaults": "LocalCluster with Dask's default settings",
            "local": "the tool's local cluster (--dask local:K: profiler off, slower health checks)"}


def _dask_runs(setup: str, data: Path, work: Path, names: tuple[str, ...], fmu: Path, repeats: int,
               common: dict[str, Any]) -> dict[int, list[RunRecord]]:
    """Alternating runs (1, 2, 1, 2, ...) on a 1-worker and a 2-worker cluster of ``setup``, both started first."""
    import distributed

    from identification.cluster import local_cluster

    def start(n: int) -> Any:
        directory = str(work / f"dask-{setup}-{n}")
        if setup == "local":
            return local_cluster(n, local_directory=directory)
        return distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                        local_directory=directory)

    by_workers: dict[int, list[RunRecord]] = {1: [], 2: []}
    clusters: dict[int, Any] = {}
    try:
        for n in (1, 2):
            clusters[n] = start(n)
        clients = {n: distributed.Client(c.scheduler_address) for n, c in clusters.items()}
        try:
            # both clusters up before timing; alternating runs see the same (changing) machine load
            for _ in range(repeats):
                for n_workers in (1, 2):
                    by_workers[n_workers].append(run_once(
                        f"fmu, dask {n_workers}, {setup}", data, work, names, client=clients[n_workers],
                        backend="fmu", fmu=fmu, **common))
        finally:
            for c in clients.values():
                c.close()
    finally:
        for c in clusters.values():
            c.close()
    return by_workers


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="repeats of (a) and of each Dask run in (c)")
    ap.add_argument("--fmu-repeats", type=int, default=1, help="repeats of (b)")
    ap.add_argument("--pop", type=int, default=24)
    ap.add_argument("--generations", type=int, default=10)
    ap.add_argument("--polish", type=int, default=1)
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--parts", default="abc", help="which configurations to run, e.g. 'a' or 'ac' (default abc)")
    ap.add_argument("--cluster", default="both", choices=("defaults", "local", "both"),
                    help="Dask clusters of (c): a LocalCluster with Dask's defaults, the tool's own local cluster "
                         "(--dask local:K), or both (default)")
    ap.add_argument("--json", default=None, help="also write the records here")
    args = ap.parse_args(argv)

    from threadpoolctl import threadpool_limits

    threadpool_limits(1, "blas")
    work = Path(tempfile.mkdtemp(prefix="bench-identify-"))
    try:
        case = recovery_case()
        data = case.write_csv(work / "fe_record.csv")
        names = ("EI", "rhoA", "c", "N")
        common: dict[str, Any] = {"pop": args.pop, "generations": args.generations, "seed": args.seed,
                                  "polish": args.polish, "noise_std": case.noise_std}
        print(f"case: FE data, 1500 samples, 1 % noise; FD model 199 nodes; pop {args.pop}, "
              f"{args.generations} generations, polish {args.polish}, seed {args.seed}")
        print(f"load average before: {_load()}  (cores: {os.cpu_count()})")
        records: list[RunRecord] = []
        rows: list[tuple[str, list[RunRecord]]] = []

        if "a" in args.parts:
            recs = [run_once("native, 2 workers", data, work, names, workers=2, backend="native", **common)
                    for _ in range(args.repeats)]
            rows.append(("(a) native, 2 processes", recs))
            records += recs
        speedups: dict[str, tuple[float | None, float | None, float | None]] = {}
        if "b" in args.parts or "c" in args.parts:
            from fmu_build import build_fmu

            threadpool_limits(1, "blas")
            fmu = build_fmu(fd_config(), work / "beam.fmu")
            threadpool_limits(1, "blas")
            if "b" in args.parts:
                recs = [run_once("fmu, 2 workers", data, work, names, workers=2, backend="fmu", fmu=fmu, **common)
                        for _ in range(args.fmu_repeats)]
                rows.append(("(b) FMU, 2 processes", recs))
                records += recs
            if "c" in args.parts:
                for setup in (["defaults", "local"] if args.cluster == "both" else [args.cluster]):
                    by_workers = _dask_runs(setup, data, work, names, fmu, args.repeats, common)
                    for n_workers in (1, 2):
                        recs = by_workers[n_workers]
                        rows.append((f"(c) FMU, Dask {n_workers} worker{'s' if n_workers > 1 else ''}, {setup}", recs))
                        records += recs
                    speedups[setup] = tuple(_speedup(by_workers, phase) for phase in (
                        lambda r: r.search_seconds, lambda r: r.ga_seconds, lambda r: r.search_seconds - r.ga_seconds))
        print(f"load average after: {_load()}")
        print()
        head = (f"{'configuration':38s} {'runs':>4s} {'evals to 1 %':>12s} {'s to 1 %':>9s} {'reached at':>12s} "
                f"{'search evals':>12s} {'search s':>9s}  final errors % (EI, rhoA, c, N)")
        print(head)
        print("-" * len(head))
        base = None
        for label, recs in rows:
            ev = _median([r.evaluations_to_target for r in recs])
            ts = _median([r.seconds_to_target for r in recs])
            ss = _median([r.search_seconds for r in recs])
            se = _median([r.search_evaluations for r in recs])
            if base is None:
                base = ss
            errs = ", ".join(f"{recs[-1].errors_percent[n]:+.3f}" for n in names)
            print(f"{label:38s} {len(recs):4d} {_fmt(ev, '12.0f')} {_fmt(ts, '9.2f')} "
                  f"{(recs[-1].stage_at_target or 'never'):>12s} {_fmt(se, '12.0f')} {_fmt(ss, '9.2f')}  {errs}")
        print()
        for label, recs in rows:
            print(f"{label}: per run [first generation (incl. start-up) / GA done / polish done] s: "
                  + "; ".join(f"{r.first_generation_seconds:.2f} / {r.ga_seconds:.2f} / {r.search_seconds:.2f}"
                              + ("" if r.worker_cpu_share is None else
                                 f" (workers' CPU {100 * r.worker_cpu_share:.0f} % of their cores)")
                              for r in recs))
        for setup, (speedup, ga, pol) in speedups.items():
            print(f"Dask speed-up, FMU backend, 2 workers vs 1 (median search time), {CLUSTERS[setup]}: "
                  f"{_fmt(speedup, '.2f')}x (target >= 1.7x); GA phase (start-up included) {_fmt(ga, '.2f')}x, "
                  f"polish phase {_fmt(pol, '.2f')}x (forward-difference polish of 4 unknowns: 1 + 4 evaluations "
                  "per iteration, at best 5/3 = 1.67x on 2 workers)")
        if "a" in args.parts:
            a = rows[0][1]
            ev_a, t_a = _median([r.evaluations_to_target for r in a]), _median([r.seconds_to_target for r in a])
            ok = ev_a is not None and t_a is not None and ev_a <= 3000 and t_a <= 30.0
            print(f"(a) target <= 3000 evaluations and <= 30 s: {'met' if ok else 'NOT met'}")
        table = [{"configuration": label, "runs": len(recs),
                  "evaluations_to_target": _median([r.evaluations_to_target for r in recs]),
                  "seconds_to_target": _median([r.seconds_to_target for r in recs]),
                  "search_evaluations": _median([r.search_evaluations for r in recs]),
                  "search_seconds": _median([r.search_seconds for r in recs])} for label, recs in rows]
        write_figures(Path(args.json) if args.json else None, {
            "records": [asdict(r) for r in records], "rows": table, "load_after": _load(),
            "dask_speedup": {k: v[0] for k, v in speedups.items()},
            "dask_speedup_ga": {k: v[1] for k, v in speedups.items()},
            "dask_speedup_polish": {k: v[2] for k, v in speedups.items()}})
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
