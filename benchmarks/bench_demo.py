"""Wall time of the main job, ``ebb demo`` with its defaults, as a user runs it (a fresh process, a new folder).

The README quotes this time.  The command runs as its own process (``python -m ebb_cli demo --out DIR``: the
interpreter's start, the imports and numba's cached kernels included, as a user waits for them); the outcome line
of its ``report.txt`` says whether the withheld effect was named.

Run as ``python benchmarks/bench_demo.py [--repeats R] [--json PATH]``.
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from figures import add_json_argument, write_figures  # benchmarks/figures.py

ROOT = Path(__file__).resolve().parents[1]


def run_demo(out: Path) -> tuple[float, str]:
    """Seconds ``ebb demo --out out`` took, and its outcome line."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "ebb_cli", "demo", "--out", str(out)], cwd=ROOT, check=True,
                   stdout=subprocess.DEVNULL)
    seconds = time.perf_counter() - t0
    outcome = next(line for line in (out / "report.txt").read_text().splitlines() if line.startswith("withheld"))
    return seconds, outcome


def main() -> None:
    """Run the demo ``--repeats`` times, print and write the median."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=1)
    add_json_argument(ap)
    args = ap.parse_args()
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):
            seconds, outcome = run_demo(Path(tmp) / f"demo{r}")
            runs.append({"seconds": seconds, "outcome": outcome, "right": outcome.endswith("RIGHT")})
            print(f"ebb demo: {seconds:.1f} s; {outcome}", flush=True)
    write_figures(args.json, {"seconds": statistics.median(r["seconds"] for r in runs),
                              "right": sum(r["right"] for r in runs), "repeats": args.repeats, "runs": runs})


if __name__ == "__main__":
    main()
