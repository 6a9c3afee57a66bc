"""Benchmark: the identified beam against a black box — held-out prediction of default ``identify`` and of N4SID.

On correctly modelled records from the independent truth (``tests/first_records.py``: the demo beam under a white
force read by two displacement sensors, a cantilever's tip accelerometer under a random force, a compressed pinned
beam read by a velocity sensor and an accelerometer under random noise to 0.2 fs), the first 70 % of each record
is the training record and the rest is held out.  The beam is identified with the defaults from the newcomer's
config on the training part alone and simulated over the whole record; N4SID (:mod:`benchmarks.n4sid`, the
textbook algorithm) is fitted to the same training part at every even order from 2 to 40 (block rows
``max(order, 20)``), at the record's rate and after a decimation by 4 (scipy's FIR decimator on inputs and outputs;
the beam's prediction is decimated the same way there), and simulated from the state its regression estimated.

The score is the held-out NRMSE (RMS of prediction minus measurement over the measurement's RMS, averaged over the
sensors); the records' noise sets its floor (1–2 % of the clean RMS).  Target: the identified model at or below
the best N4SID order on every record.  At the records' own rate N4SID's horizon (at most 40 block rows) is short
against the slow modes' periods and its models are poor; the decimated fit is the rival that counts.

Usage: ``python benchmarks/bench_black_box.py [--json PATH]``.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import signal

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from first_records import BROADBAND, CASES, FirstRecord, write_case  # noqa: E402  (tests/first_records.py)
from n4sid import n4sid, simulate as simulate_black_box  # noqa: E402  (benchmarks/n4sid.py)
from figures import add_json_argument, write_figures  # noqa: E402  (benchmarks/figures.py)
from ebb_model.simulate import simulate_config  # noqa: E402
from identification.run import identify  # noqa: E402

#: The records (names in ``tests/first_records.py``).
RECORDS = ("demo-beam-white-displacement", "cantilever-accel-random", "pinned-compression-velocity-accel-band20")
#: Share of each record the models are fitted to; the rest is held out.
TRAINING = 0.7
ORDERS = tuple(range(2, 41, 2))
DECIMATION = 4


def nrmse(pred: np.ndarray, meas: np.ndarray) -> float:
    """Mean over the sensors of RMS(prediction − measurement) / RMS(measurement)."""
    return float(np.mean(np.sqrt(np.mean((pred - meas) ** 2, axis=0)) / np.sqrt(np.mean(meas ** 2, axis=0))))


def best_black_box(u: np.ndarray, y: np.ndarray, cut: int) -> tuple[float, int]:
    """The best held-out NRMSE of N4SID over :data:`ORDERS` fitted to the samples before ``cut``, and its order."""
    best = (np.inf, 0)
    for order in ORDERS:
        try:
            model = n4sid(u[:cut], y[:cut], order, max(order, 20))
            pred = simulate_black_box(model, u)
        except np.linalg.LinAlgError:
            continue
        score = nrmse(pred[cut:], y[cut:]) if np.all(np.isfinite(pred[cut:])) else np.inf
        best = min(best, (score, order))
    return best


def run(case: FirstRecord, work: Path) -> dict:
    """One record: the beam identified on the training part, N4SID at every order; the held-out scores."""
    cfg_path, rec_path = write_case(case, work / case.name)
    data = np.loadtxt(rec_path, delimiter=",", skiprows=1)
    header = rec_path.read_text(encoding="utf-8").splitlines()[0]
    cut = int(TRAINING * len(data))
    train = work / case.name / "training.csv"
    np.savetxt(train, data[:cut], delimiter=",", header=header, comments="", fmt="%.12g")
    u, y = data[:, 1:2], data[:, 2:]
    res = identify(cfg_path, [train], work / case.name / "run", progress=False, export=False)
    beam = simulate_config(res.config, u, res.best).outputs
    row = {"record": case.name, "samples": len(data), "beam": nrmse(beam[cut:], y[cut:])}
    row["n4sid"], row["n4sid_order"] = best_black_box(u, y, cut)
    ud, yd, bd = (signal.decimate(a, DECIMATION, axis=0, ftype="fir") for a in (u, y, beam))
    cd = cut // DECIMATION
    row["beam_decimated"] = nrmse(bd[cd:], yd[cd:])
    row["n4sid_decimated"], row["n4sid_decimated_order"] = best_black_box(ud, yd, cd)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_json_argument(ap)
    args = ap.parse_args()
    cases = {c.name: c for c in CASES + BROADBAND}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in RECORDS:
            r = run(cases[name], Path(tmp))
            rows.append(r)
            print(f"{name}: held-out NRMSE beam {r['beam']:.4f}, best N4SID {r['n4sid']:.4f} (order "
                  f"{r['n4sid_order']}); decimated by {DECIMATION}: beam {r['beam_decimated']:.4f}, N4SID "
                  f"{r['n4sid_decimated']:.4f} (order {r['n4sid_decimated_order']})", flush=True)
    wins = sum(r["beam"] <= r["n4sid"] and r["beam_decimated"] <= r["n4sid_decimated"] for r in rows)
    print(f"the beam predicts at least as well as every N4SID order on {wins} of {len(rows)} records")
    write_figures(args.json, {"records": len(rows), "beam_wins": wins, "rows": rows})

if __name__ == "__main__":
    main()
