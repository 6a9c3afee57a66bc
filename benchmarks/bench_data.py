"""Benchmark of the data layer: reading the real ARTS-Lab LabVIEW record (63,041 rows, 4 columns).

Printed (medians over repeats, measured in this one run):

* ``load_experiment`` on the ``.lvm`` file (parse, units, time-base checks, offset removal);
* ``numpy.loadtxt`` of the same numbers alone (the C parser the reader uses) and the ratio of the two —
  the reader's own overhead on top of parsing.

Target: reading the record well under 2 s on the 2-core CI machine (it used to be a timed unit test).

Run: ``python benchmarks/bench_data.py [--repeats R]`` (needs ``../shared`` beside the repository).
"""
from __future__ import annotations

import argparse
import io
import sys
import warnings
from pathlib import Path

import numpy as np

import ebb_model as em
from ebb_model.errors import DataWarning
from identification.data import load_experiment

from figures import add_json_argument, write_figures  # benchmarks/figures.py
from timing import median_time  # benchmarks/timing.py

ROOT = Path(__file__).resolve().parents[1]
ARTS_LVM = ROOT / ".." / "shared" / "data" / "arts-lab-cantilever" / "test_1_3200Hz.lvm"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    add_json_argument(ap)
    args = ap.parse_args()
    if not ARTS_LVM.is_file():
        sys.exit(f"{ARTS_LVM}: not found (the shared data folder must sit beside the repository)")
    cfg = em.load_config(ROOT / "examples" / "arts_cantilever.toml", extra_sections=("identification",))
    names = [a.name for a in cfg.actuators] + [s.name for s in cfg.sensors]
    mapping = {names[0]: 2, names[1]: 3}
    text = ARTS_LVM.read_text(encoding="latin-1")
    body = text[text.rindex("***End_of_Header***"):].split("\n", 2)[2]

    def read() -> None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DataWarning)  # the record is shorter than its header declares
            load_experiment(ARTS_LVM, cfg, mapping=mapping, units={names[0]: "lbf"}, remove_offset="mean")

    t_read = median_time(read, args.repeats)
    t_parse = median_time(lambda: np.loadtxt(io.StringIO(body), delimiter="\t", usecols=range(4)), args.repeats)
    print(f"ARTS-Lab record, 63,041 rows x 4 columns (medians of {args.repeats})")
    print(f"  load_experiment (.lvm -> checked Experiment): {t_read * 1e3:8.1f} ms   (target < 2000 ms)")
    print(f"  numpy.loadtxt of the numbers alone:            {t_parse * 1e3:8.1f} ms")
    print(f"  ratio reader / parsing alone:                  {t_read / t_parse:8.2f} x")
    write_figures(args.json, {"read_ms": t_read * 1e3, "loadtxt_ms": t_parse * 1e3, "ratio": t_read / t_parse})


if __name__ == "__main__":
    main()
