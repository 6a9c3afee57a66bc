"""Experiment data layer: loaders for CSV, NPZ, MAT, LVM and UFF58, units, offsets, resampling, bad input.

Independent truths: signals are synthesised analytically, written with each
format's own writer (numpy, scipy.io.savemat, pyuff, LabVIEW's text layout by
hand) and must come back unchanged; unit factors are the exact definitions
(1 lbf = 0.45359237 kg x 9.80665 m/s2, 1 g_n = 9.80665 m/s2); resampled
tones are compared with the analytic signal on the new grid; the real
ARTS-Lab record must show its documented 100/120/150 Hz excitation.
"""
from __future__ import annotations

import dataclasses
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from conftest import make_config
from ebb_model.errors import DataError, DataWarning
from identification.data import (
    LBF,
    STANDARD_GRAVITY,
    Experiment,
    load_experiment,
    load_experiments,
    resample_uniform,
    to_si_factor,
)

REPO = Path(__file__).resolve().parents[1]
FIXTURES = Path(__file__).resolve().parent / "fixtures"
ARTS_DIR = REPO / ".." / "shared" / "data" / "arts-lab-cantilever"
ARTS_LVM = ARTS_DIR / "test_1_3200Hz.lvm"

DT = 1e-4
N = 1000


def cfg(dt: float = DT):
    """F1 (force), y1 (displacement), a2 (acceleration)."""
    return make_config(nodes=20, dt=dt, actuators=[("F1", 0.3)],
                       sensors=[("y1", 0.5, "displacement"), ("a2", 0.71, "acceleration")])


def arts_cfg():
    return make_config("clamped", "free", length=0.759, nodes=20, dt=1 / 3200, EI=114.7, rhoA=2.044,
                       actuators=[("force", 0.70)], sensors=[("accel", 0.61, "acceleration")])


def signals(n: int = N, dt: float = DT) -> dict[str, np.ndarray]:
    t = np.arange(n) * dt
    return {"time": t,
            "F1": 2.0 * np.sin(2 * np.pi * 50 * t) + 0.3,
            "y1": 1e-3 * np.sin(2 * np.pi * 80 * t + 0.4),
            "a2": 5.0 * np.cos(2 * np.pi * 120 * t) - 0.1}


def assert_matches(exp: Experiment, sig: dict[str, np.ndarray], rtol: float = 1e-12, atol: float = 0.0):
    np.testing.assert_allclose(exp.time, sig["time"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(exp.signal("F1"), sig["F1"], rtol=rtol, atol=atol)
    np.testing.assert_allclose(exp.signal("y1"), sig["y1"], rtol=rtol, atol=atol * 1e-3)
    np.testing.assert_allclose(exp.signal("a2"), sig["a2"], rtol=rtol, atol=atol)


def write_csv(path: Path, sig: dict[str, np.ndarray], fmt: str = "%.17g") -> Path:
    names = list(sig)
    np.savetxt(path, np.column_stack([sig[k] for k in names]), delimiter=",", header=",".join(names),
               comments="", fmt=fmt)
    return path


def write_txt(path: Path, sig: dict[str, np.ndarray], units: dict[str, str] | None = None) -> Path:
    """A text table as DAQ software writes it: a preamble, the names, the units, a stray line, the rows (tabs)."""
    names = list(sig)
    head = ["C:\\DAQ\\run3.txt", "Sampling Frequency - 5000", "Tue, Jul 19, 2022 10:55 PM", "\t".join(names),
            "\t".join((units or {}).get(n, "-") for n in names), "0.0 0.0 0\t\t0.0 0.0 0", ""]
    rows = ["\t".join(f"{v:.10E}" for v in row) for row in np.column_stack([sig[k] for k in names])]
    path.write_text("\n".join(head + rows) + "\n", encoding="utf-8")
    return path


def write_lvm(path: Path, t: np.ndarray, cols: list[np.ndarray], names: list[str], units: list[str], *,
              decimal: str = ".", x_columns: str = "One", segments: int = 1, comment: bool = False) -> Path:
    """An .lvm file in LabVIEW's layout (Writer_Version 2): file header, segment header(s), headings, rows."""
    nl = "\r\n"

    def fmt(v: float) -> str:
        return f"{v:.6f}".replace(".", decimal)

    head = ["LabVIEW Measurement\t", "Writer_Version\t2", "Reader_Version\t2", "Separator\tTab",
            f"Decimal_Separator\t{decimal}", "Multi_Headings\tNo", f"X_Columns\t{x_columns}",
            "Time_Pref\tAbsolute", "Operator\ttest", "Date\t2024/01/01", "Time\t12:00:00.0",
            "***End_of_Header***\t", ""]
    lines = head[:]
    bounds = np.linspace(0, t.size, segments + 1).astype(int)
    nch = len(cols)
    for s in range(segments):
        lo, hi = bounds[s], bounds[s + 1]
        dx = t[1] - t[0]
        lines += [f"Channels\t{nch}\t" + "\t" * 0,
                  "Samples\t" + "\t".join([str(hi - lo)] * nch),
                  "Y_Unit_Label\t" + "\t".join(units),
                  "X_Dimension\t" + "\t".join(["Time"] * nch),
                  "X0\t" + "\t".join([f"{t[lo]:.16E}".replace(".", decimal)] * nch),
                  "Delta_X\t" + "\t".join([f"{dx:.6E}".replace(".", decimal)] * nch),
                  "***End_of_Header***\t\t\t"]
        heading = (["X_Value"] if x_columns == "One" else []) + names + (["Comment"] if comment else [])
        lines.append("\t".join(heading))
        for k in range(lo, hi):
            row = ([fmt(t[k])] if x_columns == "One" else []) + [fmt(c[k]) for c in cols]
            lines.append("\t".join(row) + ("\tnote" if comment and k == lo else ""))
    path.write_bytes((nl.join(lines) + nl).encode("ascii"))
    return path


def write_uff(path: Path, sig: dict[str, np.ndarray], units: dict[str, str] | None = None,
              names: dict[str, str] | None = None) -> Path:
    import pyuff
    units = units or {}
    names = names or {}
    kinds = {"F1": 13, "y1": 8, "a2": 12}     # excitation force, displacement, acceleration
    dsets = []
    for i, k in enumerate(("F1", "y1", "a2")):
        dsets.append(pyuff.prepare_58(
            binary=0, func_type=1, rsp_node=i + 1, rsp_dir=3, ref_node=1, ref_dir=3,
            data=np.asarray(sig[k], dtype=float), x=np.asarray(sig["time"], dtype=float),
            id1=names.get(k, k), abscissa_spacing=1, abscissa_spec_data_type=17,
            ordinate_spec_data_type=kinds[k], ordinate_axis_units_lab=units.get(k, "NONE"),
            orddenom_spec_data_type=0, z_axis_spec_data_type=0))
    pyuff.UFF(str(path)).write_sets(dsets, mode="overwrite")
    return path


# ----------------------------------------------------------------------------------------------- round trips
def test_csv_round_trip(tmp_path):
    sig = signals()
    exp = load_experiment(write_csv(tmp_path / "run.csv", sig), cfg())
    assert exp.name == "run" and exp.source.endswith("run.csv")
    assert exp.input_names == ("F1",) and exp.output_names == ("y1", "a2")
    assert exp.units == {"F1": "N", "y1": "m", "a2": "m/s2"}
    assert_matches(exp, sig)
    exp.check_against(cfg())


UNITS = {"time": "s", "F1": "N", "y1": "m", "a2": "m/s2"}
DROPBEAR_RUN = REPO / ".." / "shared" / "data" / "dropbear-roller" / "slow10_test0.txt"


def test_text_table_with_a_preamble_round_trip(tmp_path):
    """A text table as DAQ software writes it (a preamble, names, units, a stray line, tab-separated rows printed
    to 11 digits): the experiment equals the signals to the printed precision (5e-11 relative); the same table
    separated by blanks reads the same; a units line that is not there leaves the file's units unsaid."""
    sig = signals()
    exp = load_experiment(write_txt(tmp_path / "run.txt", sig, UNITS), cfg())
    assert exp.units == {"F1": "N", "y1": "m", "a2": "m/s2"}
    assert_matches(exp, sig, rtol=5e-11, atol=1e-13)
    blank = tmp_path / "blank.dat"
    blank.write_text((tmp_path / "run.txt").read_text().replace("\t\t", "  ").replace("\t", " "))
    assert_matches(load_experiment(blank, cfg()), sig, rtol=5e-11, atol=1e-13)
    bare = tmp_path / "bare.tsv"
    lines = (tmp_path / "run.txt").read_text().splitlines()
    bare.write_text("\n".join(lines[:4] + lines[5:]) + "\n")
    assert_matches(load_experiment(bare, cfg()), sig, rtol=5e-11, atol=1e-13)


def test_text_table_problems_are_one_line(tmp_path):
    """A row that is not numbers names its line; no names before the rows, or repeated names: one line each."""
    sig = signals(50)
    p = write_txt(tmp_path / "run.txt", sig, UNITS)
    lines = p.read_text().splitlines()
    lines[20] = "0.1\tgarbage\t0.3\t0.4"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match="line 21 is not 4 numbers"):
        load_experiment(p, cfg())
    q = tmp_path / "nohead.txt"
    q.write_text("\n".join(["header text", *["\t".join(["1", "2", "3", "4"])] * 5]) + "\n")
    with pytest.raises(DataError, match="no line of 4 channel names"):
        load_experiment(q, cfg())
    r = tmp_path / "twice.txt"
    r.write_text("\n".join(["time\tF1\tF1\ta2", *["\t".join(["1", "2", "3", "4"])] * 5]) + "\n")
    with pytest.raises(DataError, match="channel names repeat"):
        load_experiment(r, cfg())


@pytest.mark.skipif(not DROPBEAR_RUN.is_file(), reason="../shared/data/dropbear-roller is not available")
def test_dropbears_text_file_is_read_in_place():
    """DROPBEAR's run (CC BY-SA 4.0, read in place): 70,000 rows at 5 kHz of the four channels its README lists;
    its unscaled volts are refused as an acceleration unit, with how to say what they are."""
    dropbear = make_config("clamped", "free", length=0.501, nodes=20, dt=2e-4, actuators=[("F1", 0.45)],
                           sensors=[("lowg", 0.47, "acceleration")])
    with pytest.raises(DataError, match=r"Voltage \(unscaled\).*units = \{ lowg = \.\.\. \}"):
        load_experiment(DROPBEAR_RUN, replace(dropbear, actuators=()), mapping={"lowg": "Low G Accel"})
    exp = load_experiment(DROPBEAR_RUN, replace(dropbear, actuators=()), mapping={"lowg": "Low G Accel"},
                          units={"lowg": "m/s2"})
    assert exp.outputs.shape == (70000, 1) and exp.time[1] == pytest.approx(2e-4)


def test_csv_mapping_and_units(tmp_path):
    sig = signals()
    raw = {"t": sig["time"], "load_lbf": sig["F1"], "disp_mm": sig["y1"], "acc_g": sig["a2"], "extra": sig["F1"]}
    p = write_csv(tmp_path / "mapped.csv", raw)
    exp = load_experiment(p, cfg(), mapping={"time": "t", "F1": "load_lbf", "y1": "disp_mm", "a2": 3},
                          units={"F1": "lbf", "y1": "mm", "a2": "g"})
    np.testing.assert_allclose(exp.signal("F1"), sig["F1"] * 4.4482216152605, rtol=1e-15)
    np.testing.assert_allclose(exp.signal("y1"), sig["y1"] * 1e-3, rtol=1e-15)
    np.testing.assert_allclose(exp.signal("a2"), sig["a2"] * 9.80665, rtol=1e-15)


def test_gains_apply_after_units_and_before_offset_removal(tmp_path):
    """A load cell reading compression negative: gain -1 flips it; the offset is removed afterwards."""
    sig = signals()
    p = write_csv(tmp_path / "g.csv", sig)
    exp = load_experiment(p, cfg(), units={"F1": "lbf"}, gains={"F1": -1.0, "a2": 0.5}, remove_offset="mean")
    f = -sig["F1"] * 4.4482216152605
    np.testing.assert_allclose(exp.signal("F1"), f - f.mean(), rtol=1e-12, atol=1e-14)
    a = 0.5 * sig["a2"]
    np.testing.assert_allclose(exp.signal("a2"), a - a.mean(), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(exp.signal("y1"), sig["y1"] - sig["y1"].mean(), rtol=1e-12, atol=1e-18)
    for bad in (0.0, float("nan"), float("inf"), True, "x"):
        with pytest.raises(DataError, match=r"gains\['F1'\]: must be a finite, non-zero number"):
            load_experiment(p, cfg(), gains={"F1": bad})
    with pytest.raises(DataError, match=r"gains: 'F9' is not a signal of the config"):
        load_experiment(p, cfg(), gains={"F9": 2.0})
    # a value where a table belongs (``gains = 5`` under [identification.data]) was a TypeError traceback
    for key in ("mapping", "units", "gains"):
        with pytest.raises(DataError, match=rf"g\.csv: {key}: must be a table {{signal = \.\.\.}}, got 5"):
            load_experiment(p, cfg(), **{key: 5})
    # ``resample = "yes"`` was taken as true
    with pytest.raises(DataError, match=r"g\.csv: resample must be true or false, got 'yes'"):
        load_experiment(p, cfg(), resample="yes")


def test_band_keeps_in_band_tones_and_removes_the_rest(tmp_path):
    """Tones on exact FFT bins: inside the flat part of the band unchanged, outside gone, on every signal."""
    t = np.arange(N) * DT                      # 1000 samples at 10 kHz: 10 Hz bins
    inside = np.sin(2 * np.pi * 120 * t) + 0.5 * np.cos(2 * np.pi * 150 * t)
    outside = 0.7 * np.sin(2 * np.pi * 20 * t) + 0.3 * np.sin(2 * np.pi * 900 * t) + 0.2
    sig = {"time": t, "F1": inside + outside, "y1": 1e-3 * (inside + outside), "a2": 2.0 * inside + outside}
    exp = load_experiment(write_csv(tmp_path / "b.csv", sig), cfg(), band=[80.0, 200.0])
    np.testing.assert_allclose(exp.signal("F1"), inside, atol=1e-12)
    np.testing.assert_allclose(exp.signal("y1"), 1e-3 * inside, atol=1e-15)
    np.testing.assert_allclose(exp.signal("a2"), 2.0 * inside, atol=1e-12)
    for bad, msg in (([200.0, 80.0], r"band \[200, 80\] Hz must satisfy 0 <= f_lo < f_hi <= 5000"),
                     ([0.0, 6000.0], r"must satisfy 0 <= f_lo < f_hi <= 5000 \(the Nyquist frequency\)"),
                     ([float("nan"), 10.0], r"must satisfy"), ("wide", r"band must be two numbers"),
                     ([1.0], r"band must be two numbers")):
        with pytest.raises(DataError, match=msg):
            load_experiment(tmp_path / "b.csv", cfg(), band=bad)


def test_csv_time_printed_with_few_decimals_is_recognised_as_uniform(tmp_path):
    # 3200 Hz printed with 6 decimals: steps 0.000312 / 0.000313 s, 0.16 % off dt, yet uniform to print precision
    dt = 1 / 3200
    sig = signals(700, dt)
    p = write_csv(tmp_path / "coarse.csv", sig, fmt="%.6f")
    exp = load_experiment(p, cfg(dt))
    np.testing.assert_allclose(np.diff(exp.time), dt, rtol=1e-12)
    assert exp.time[0] == 0.0
    # a genuinely irregular time column is not "regularised" away
    sig2 = dict(sig)
    sig2["time"] = sig["time"].copy()
    sig2["time"][300:] += 2e-5
    with pytest.raises(DataError, match=r"jitter\.csv: time \(column .time.\): not uniformly sampled: "
                                        r"step 0\.000332 s at sample 300"):
        load_experiment(write_csv(tmp_path / "jitter.csv", sig2, fmt="%.6f"), cfg(dt))


def test_npz_round_trip_and_to_npz(tmp_path):
    sig = signals()
    p = tmp_path / "run.npz"
    np.savez(p, **sig)
    exp = load_experiment(p, cfg())
    assert_matches(exp, sig)
    # Experiment.to_npz -> load_experiment gives the same experiment back
    q = exp.to_npz(tmp_path / "again.npz")
    back = load_experiment(q, cfg())
    for a in ("time", "inputs", "outputs"):
        np.testing.assert_array_equal(getattr(back, a), getattr(exp, a))
    assert back.units == exp.units


@pytest.mark.parametrize("name", ["file", "allow_pickle"])
def test_to_npz_keeps_a_signal_named_like_an_argument_of_savez(name, tmp_path):
    """A sensor named ``file`` or ``allow_pickle``: ``np.savez`` took it for its own argument (a TypeError, or the
    signal left out of the file); ``to_npz`` writes every signal by its name."""
    c = make_config(nodes=20, dt=DT, actuators=[("F1", 0.3)], sensors=[(name, 0.5, "displacement")])
    sig = signals()
    sig = {"time": sig["time"], "F1": sig["F1"], name: sig["y1"]}
    exp = load_experiment(write_csv(tmp_path / "r.csv", sig), c)
    back = load_experiment(exp.to_npz(tmp_path / "r.npz"), c)
    np.testing.assert_array_equal(back.outputs, exp.outputs)
    np.testing.assert_array_equal(back.inputs, exp.inputs)


def test_to_npz_keeps_units_so_no_double_conversion(tmp_path):
    sig = signals()
    exp = load_experiment(write_csv(tmp_path / "r.csv", sig), cfg(), units={"F1": "kN"})
    back = load_experiment(exp.to_npz(tmp_path / "r.npz"), cfg())
    np.testing.assert_array_equal(back.inputs, exp.inputs)
    np.testing.assert_allclose(back.signal("F1"), 1e3 * sig["F1"], rtol=1e-15)


def test_mat_round_trip(tmp_path):
    sig = signals()
    p = tmp_path / "run.mat"
    scipy.io.savemat(p, sig)                      # vectors become 1 x n row matrices
    assert_matches(load_experiment(p, cfg()), sig)
    q = tmp_path / "named.mat"
    scipy.io.savemat(q, {"t": sig["time"][:, None], "Fload": sig["F1"][:, None], "y1": sig["y1"],
                         "acc": sig["a2"], "note": "a string"})
    exp = load_experiment(q, cfg(), mapping={"time": "t", "F1": "Fload", "a2": "acc"})
    assert_matches(exp, sig)


def test_uff58_round_trip(tmp_path):
    sig = signals(400)
    p = write_uff(tmp_path / "run.uff", sig)
    exp = load_experiment(p, cfg())
    assert_matches(exp, sig, rtol=1e-10, atol=1e-12)   # ASCII double precision: 12 significant digits
    exp.check_against(cfg())


def test_uff58_declared_units_and_mapping_by_index(tmp_path):
    sig = signals(400)
    p = write_uff(tmp_path / "units.unv", sig, units={"F1": "lbf", "a2": "g"},
                  names={"F1": "load cell", "y1": "laser", "a2": "accelerometer"})
    exp = load_experiment(p, cfg(), mapping={"F1": "load cell", "y1": 1, "a2": "accelerometer"})
    np.testing.assert_allclose(exp.signal("F1"), LBF * sig["F1"], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(exp.signal("a2"), STANDARD_GRAVITY * sig["a2"], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(exp.signal("y1"), sig["y1"], rtol=1e-10, atol=1e-15)


def test_lvm_round_trip_written_by_hand(tmp_path):
    sig = signals()
    p = write_lvm(tmp_path / "run.lvm", sig["time"], [sig["F1"], sig["y1"] * 1e3, sig["a2"]],
                  ["Force", "Disp", "Acceleratio"], ["Newtons", "mm", "m/s^2"], comment=True)
    exp = load_experiment(p, cfg(), mapping={"F1": "Force", "y1": 2, "a2": "Acceleratio"})
    assert_matches(exp, sig, rtol=0, atol=5e-7)    # 6 printed decimals
    exp.check_against(cfg())


@pytest.mark.parametrize("variant", [dict(segments=2), dict(decimal=","), dict(x_columns="No")])
def test_lvm_variants(tmp_path, variant):
    sig = signals(600)
    p = write_lvm(tmp_path / "v.lvm", sig["time"], [sig["F1"], 1e3 * sig["y1"], sig["a2"]],
                  ["F1", "y1", "a2"], ["N", "mm", "m/s2"], **variant)
    exp = load_experiment(p, cfg())
    assert exp.n_samples == 600
    assert_matches(exp, sig, rtol=0, atol=5e-7)


def test_lvm_excerpt_of_the_real_file():
    """The first 320 samples of the ARTS-Lab record, kept in tests/fixtures (CC BY-SA 4.0, see README)."""
    p = FIXTURES / "arts_lab_test1_excerpt.lvm"
    # an excerpt: shorter than the 1,050,000 samples its (original) header declares, and it says so
    with pytest.warns(DataWarning, match=r"excerpt\.lvm: segment 1 ends at 0\.099687 s"):
        exp = load_experiment(p, arts_cfg(), mapping={"force": 2, "accel": 3})
    assert exp.n_samples == 320
    np.testing.assert_allclose(np.diff(exp.time), 1 / 3200, rtol=1e-12)
    # header units "Pounds" and "g" are honoured: first row is 0.000000 -0.170586 -3.399325 -0.016694
    assert exp.inputs[0, 0] == pytest.approx(-3.399325 * LBF, rel=1e-15)
    assert exp.outputs[0, 0] == pytest.approx(-0.016694 * STANDARD_GRAVITY, rel=1e-15)
    # the same by column heading, with explicit units
    with pytest.warns(DataWarning):
        by_name = load_experiment(p, arts_cfg(), mapping={"force": "Force", "accel": "Acceleratio"},
                                  units={"force": "lbf", "accel": "g"})
    np.testing.assert_array_equal(by_name.inputs, exp.inputs)


@pytest.mark.skipif(not ARTS_LVM.is_file(), reason="../shared/data/arts-lab-cantilever is not available")
def test_real_arts_lab_record():
    # (reading speed: benchmarks/bench_data.py)
    with pytest.warns(DataWarning, match=r"ends at 19\.7 s, its header declares 1050000 samples"):
        raw = load_experiment(ARTS_LVM, arts_cfg(), mapping={"force": 2, "accel": 3}, units={"force": "lbf"})
    assert raw.n_samples == 63041
    assert raw.dt == pytest.approx(1 / 3200, rel=1e-12)
    raw.check_against(arts_cfg())
    assert -5.5 * LBF < raw.inputs.mean() < -4.5 * LBF              # static offset of about -5 lbf
    with pytest.warns(DataWarning):
        exp = load_experiment(ARTS_LVM, arts_cfg(), mapping={"force": 2, "accel": 3}, remove_offset="mean")
    assert abs(exp.inputs.mean()) < 1e-9
    np.testing.assert_allclose(exp.inputs - raw.inputs, -raw.inputs.mean(), atol=1e-9)
    f = exp.signal("force")
    spec = np.abs(np.fft.rfft(f * np.hanning(f.size)))
    freq = np.fft.rfftfreq(f.size, exp.dt)
    from scipy.signal import find_peaks
    peaks, _ = find_peaks(spec, distance=int(5.0 / freq[1]))      # peaks at least 5 Hz apart
    top = np.sort(freq[peaks[np.argsort(spec[peaks])[-3:]]])
    np.testing.assert_allclose(top, [100.0, 120.0, 150.0], atol=0.2)


# --------------------------------------------------------------------------------------------------- units
def test_unit_factors_are_the_exact_definitions():
    assert to_si_factor("lbf", "force") == 4.4482216152605 == 0.45359237 * 9.80665
    assert to_si_factor("g", "acceleration") == 9.80665
    assert to_si_factor("kN", "force") == 1e3
    assert to_si_factor("mm", "displacement") == 1e-3
    assert to_si_factor("um", "displacement") == 1e-6
    assert to_si_factor("mm/s", "velocity") == 1e-3
    assert to_si_factor("m/s^2", "acceleration") == 1.0
    assert to_si_factor("Pounds", "force") == LBF           # LabVIEW's Y_Unit_Label spelling


def test_unknown_or_wrong_unit(tmp_path):
    with pytest.raises(DataError, match=r"unknown unit 'furlong'; allowed: N, kN, lbf, m, mm"):
        to_si_factor("furlong", "displacement")
    p = write_csv(tmp_path / "u.csv", signals())
    with pytest.raises(DataError, match=r"u\.csv: column 'F1' \(actuator 'F1'\): unknown unit 'lbs/s'"):
        load_experiment(p, cfg(), units={"F1": "lbs/s"})
    with pytest.raises(DataError, match=r"column 'F1' .*unit 'g' is a unit of acceleration, but the signal is a "
                                        r"force; allowed: N, kN, lbf"):
        load_experiment(p, cfg(), units={"F1": "g"})
    with pytest.raises(DataError, match=r"units: 'F9' is not a signal of the config"):
        load_experiment(p, cfg(), units={"F9": "N"})


def test_unknown_unit_declared_by_the_file_suggests_units_keyword(tmp_path):
    sig = signals()
    p = write_lvm(tmp_path / "volts.lvm", sig["time"], [sig["F1"], 1e3 * sig["y1"], sig["a2"]],
                  ["F1", "y1", "a2"], ["Volts", "mm", "Furlongs"])
    with pytest.raises(DataError, match=r"volts\.lvm: column 'F1' \(actuator 'F1'\): unit 'Volts' is a unit of "
                                        r"voltage.*the file declares this unit; override it with "
                                        r"units = \{ F1 = \.\.\. \} under \[identification\.data\]"):
        load_experiment(p, cfg())
    with pytest.raises(DataError, match=r"column 'a2' \(sensor 'a2'\): unknown unit 'Furlongs'.*units = "):
        load_experiment(p, cfg(), units={"F1": "N"})
    exp = load_experiment(p, cfg(), units={"F1": "N", "a2": "m/s2"})      # explicit units override
    assert_matches(exp, sig, rtol=0, atol=5e-7)


# ------------------------------------------------------------------------------------------------- offsets
def test_offset_removal_mean_and_pre_trigger(tmp_path):
    sig = signals(2000)
    t = sig["time"]
    on = t >= 0.05                                         # excitation starts after 50 ms of quiet record
    sig["F1"] = np.where(on, np.sin(2 * np.pi * 50 * (t - 0.05)), 0.0) + 0.3
    sig["a2"] = np.where(on, 3.0, 0.0) - 0.1
    p = write_csv(tmp_path / "off.csv", sig)
    m = load_experiment(p, cfg(), remove_offset="mean")
    np.testing.assert_allclose(m.inputs.mean(axis=0), 0.0, atol=1e-12)
    np.testing.assert_allclose(m.outputs.mean(axis=0), 0.0, atol=1e-12)
    assert load_experiment(p, cfg(), remove_offset=True).inputs.mean() == pytest.approx(0.0, abs=1e-12)
    pre = load_experiment(p, cfg(), remove_offset="pre-trigger", pre_trigger=0.05)
    np.testing.assert_allclose(pre.signal("F1")[~on], 0.0, atol=1e-12)
    np.testing.assert_allclose(pre.signal("a2"), np.where(on, 3.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(pre.signal("F1")[on], np.sin(2 * np.pi * 50 * (t[on] - 0.05)), atol=1e-12)
    with pytest.raises(DataError, match=r"remove_offset='median'; allowed: False, 'mean'"):
        load_experiment(p, cfg(), remove_offset="median")
    with pytest.raises(DataError, match=r"needs pre_trigger > 0"):
        load_experiment(p, cfg(), remove_offset="pre-trigger")


# ---------------------------------------------------------------------------------------------- resampling
def tones(t: np.ndarray) -> np.ndarray:
    w = 2 * np.pi * t
    return 0.5 + np.sin(100 * w) + 0.7 * np.sin(120 * w + 1) + 0.5 * np.cos(150 * w)


def test_resample_3200_to_10k_is_accurate(tmp_path):
    fs = 3200.0
    t = np.arange(3200) / fs                                # 1 s
    x = tones(t)
    p = tmp_path / "slow.npz"
    np.savez(p, time=t, F1=x, y1=1e-3 * x, a2=10 * x)
    with pytest.raises(DataError, match=r"inconsistent with the config's dt.*resample=True"):
        load_experiment(p, cfg())
    exp = load_experiment(p, cfg(), resample=True)
    exp.check_against(cfg())
    assert exp.dt == pytest.approx(DT, rel=1e-12)
    assert exp.time[-1] <= t[-1] + 1e-12 and exp.n_samples == 9997
    inner = (exp.time > 0.02) & (exp.time < t[-1] - 0.02)
    err = np.max(np.abs(exp.signal("F1")[inner] - tones(exp.time[inner])))
    assert err < 1e-3, err                                  # relative to amplitude ~2.7
    _, _, method = resample_uniform(t, x[:, None], DT)
    assert method == "polyphase 25/8"


def test_resample_irrational_ratio_is_accurate():
    fs = 7777.7
    t = np.arange(6000) / fs
    x = np.column_stack([tones(t), np.sin(2 * np.pi * 3000 * t)])    # 3 kHz = 77 % of the Nyquist frequency
    t2, y, method = resample_uniform(t, x, DT)
    assert method == "polyphase 16/1 + spline"
    np.testing.assert_allclose(np.diff(t2), DT, rtol=1e-9)
    inner = (t2 > 0.02) & (t2 < t[-1] - 0.02)
    assert np.max(np.abs(y[inner, 0] - tones(t2[inner]))) < 1e-3
    assert np.max(np.abs(y[inner, 1] - np.sin(2 * np.pi * 3000 * t2[inner]))) < 1e-3


@pytest.mark.parametrize("fs", [20000.0, 13131.3])          # rational (1/2) and irrational ratios
def test_downsampling_is_anti_aliased(fs):
    t = np.arange(int(fs)) / fs                                # 1 s
    x = (np.sin(2 * np.pi * 300 * t) + np.sin(2 * np.pi * 7000 * t))[:, None]   # 7 kHz > new Nyquist 5 kHz
    t2, y, method = resample_uniform(t, x, DT)
    assert method in ("polyphase 1/2", "polyphase 16/1 + spline")
    inner = (t2 > 0.05) & (t2 < t[-1] - 0.05)
    err = np.max(np.abs(y[inner, 0] - np.sin(2 * np.pi * 300 * t2[inner])))
    assert err < 1e-3, (method, err)                          # the 7 kHz tone is gone, 300 Hz kept


def test_resample_rejects_non_uniform_data():
    t = np.cumsum(np.r_[0.0, np.full(99, 1e-4), np.full(100, 2e-4)])
    with pytest.raises(DataError, match=r"cannot resample data that are not uniformly sampled"):
        resample_uniform(t, np.zeros((t.size, 1)), DT)


# ----------------------------------------------------------------------------------------------- bad input
def test_nan_and_inf_name_file_column_and_sample(tmp_path):
    sig = signals()
    sig["y1"] = sig["y1"].copy()
    sig["y1"][17] = np.nan
    p = write_csv(tmp_path / "holes.csv", sig)
    with pytest.raises(DataError, match=r"holes\.csv: column 'y1' \(sensor 'y1'\): non-finite value nan at "
                                        r"sample 17 \(t = 0\.0017 s\)"):
        load_experiment(p, cfg())
    sig = signals()
    sig["F1"] = sig["F1"].copy()
    sig["F1"][[5, 9]] = np.inf
    q = tmp_path / "inf.npz"
    np.savez(q, **sig)
    with pytest.raises(DataError, match=r"inf\.npz: array 'F1' \(actuator 'F1'\): non-finite value inf at "
                                        r"sample 5 .*2 non-finite samples"):
        load_experiment(q, cfg())


def test_nan_in_time(tmp_path):
    sig = signals()
    sig["time"] = sig["time"].copy()
    sig["time"][3] = np.nan
    p = write_csv(tmp_path / "tnan.csv", sig)
    with pytest.raises(DataError, match=r"tnan\.csv: time \(column 'time'\): non-finite value at sample 3"):
        load_experiment(p, cfg())


def test_mismatched_lengths(tmp_path):
    sig = signals()
    sig["y1"] = sig["y1"][:-1]
    p = tmp_path / "short.npz"
    np.savez(p, **sig)
    with pytest.raises(DataError, match=r"short\.npz: array 'y1' \(sensor 'y1'\) has 999 samples but time has "
                                        r"1000 -- mismatched lengths"):
        load_experiment(p, cfg())
    q = write_csv(tmp_path / "ragged.csv", signals())
    lines = q.read_text().splitlines()
    lines[11] = ",".join(lines[11].split(",")[:3])            # sample 10 loses its last field
    q.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"ragged\.csv, line 12 \(sample 10\): 3 fields, expected 4 "
                                        r"\(time, F1, y1, a2\) -- mismatched lengths"):
        load_experiment(q, cfg())


def test_non_numeric_field(tmp_path):
    q = write_csv(tmp_path / "text.csv", signals())
    lines = q.read_text().splitlines()
    parts = lines[8].split(",")
    parts[2] = "n/a"
    lines[8] = ",".join(parts)
    q.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"text\.csv, line 9 \(sample 7\), column 'y1': not a number \('n/a'\)"):
        load_experiment(q, cfg())


def test_non_monotonic_time(tmp_path):
    sig = signals()
    sig["time"] = sig["time"].copy()
    sig["time"][[40, 41]] = sig["time"][[41, 40]]
    p = tmp_path / "swap.mat"
    scipy.io.savemat(p, sig)
    with pytest.raises(DataError, match=r"swap\.mat: time \(variable 'time'\): not strictly increasing at "
                                        r"sample 41"):
        load_experiment(p, cfg())


def test_missing_columns_are_all_listed(tmp_path):
    sig = signals()
    del sig["a2"], sig["y1"]
    p = write_csv(tmp_path / "few.csv", sig)
    with pytest.raises(DataError, match=r"few\.csv: missing column\(s\) 'y1', 'a2'; found time, F1"):
        load_experiment(p, cfg())
    with pytest.raises(DataError, match=r"missing column\(s\) 'acc' \(sensor a2\)"):
        load_experiment(p, cfg(), mapping={"y1": "F1", "a2": "acc"})
    with pytest.raises(DataError, match=r"nt\.csv: missing time column 'time'; found t, F1 "
                                        r"\(name it with mapping = \{ time = "):
        write_csv(tmp_path / "nt.csv", {"t": sig["time"], "F1": sig["F1"]})
        load_experiment(tmp_path / "nt.csv", cfg())


def test_sample_time_inconsistent_with_config(tmp_path):
    sig = signals(dt=2e-4)
    p = write_csv(tmp_path / "slow.csv", sig)
    with pytest.raises(DataError, match=r"slow\.csv: time: sample time 0\.0002 s at sample 1 is inconsistent "
                                        r"with the config's dt = 0\.0001 s \(to resample the record to the "
                                        r"config's dt: resample = true under \[identification\.data\]"):
        load_experiment(p, cfg())


def test_bad_options_and_formats(tmp_path):
    p = write_csv(tmp_path / "ok.csv", signals())
    with pytest.raises(DataError, match=r"mapping: 'F2' is not a signal of the config; allowed: time, F1, y1, a2"):
        load_experiment(p, cfg(), mapping={"F2": "F1"})
    with pytest.raises(DataError, match=r"unknown format 'xlsx'; allowed: csv, npz, mat, lvm, uff58"):
        load_experiment(p, cfg(), format="xlsx")
    q = tmp_path / "data.h5"
    q.write_bytes(b"")
    with pytest.raises(DataError, match=r"data\.h5: cannot tell the format from the extension '\.h5'"):
        load_experiment(q, cfg())
    with pytest.raises(DataError, match=r"missing\.csv: cannot read"):
        load_experiment(tmp_path / "missing.csv", cfg())
    with pytest.raises(DataError, match=r"used both as the time and as actuator 'F1'"):
        load_experiment(p, cfg(), mapping={"F1": "time"})
    r = tmp_path / "not.lvm"
    r.write_text("time,F1\n0,1\n")
    with pytest.raises(DataError, match=r"not\.lvm: not a LabVIEW measurement file"):
        load_experiment(r, cfg())
    m = tmp_path / "matrix.mat"
    scipy.io.savemat(m, {**signals(), "a2": np.zeros((N, 2))})
    with pytest.raises(DataError, match=r"variable 'a2' \(sensor 'a2'\) has shape \(1000, 2\); expected a vector"):
        load_experiment(m, cfg())


# ------------------------------------------------------------------------------------------------ the value
def test_experiment_is_an_immutable_checked_value():
    sig = signals(10)
    exp = Experiment("e", sig["time"], sig["F1"], np.column_stack([sig["y1"], sig["a2"]]), ("F1",), ("y1", "a2"))
    with pytest.raises(dataclasses.FrozenInstanceError):
        exp.name = "other"
    with pytest.raises(ValueError):
        exp.inputs[0, 0] = 1.0
    with pytest.raises(DataError, match=r"inputs has shape \(10, 2\), expected \(10, 1\)"):
        Experiment("e", sig["time"], np.zeros((10, 2)), np.zeros((10, 2)), ("F1",), ("y1", "a2"))
    with pytest.raises(DataError, match=r"output 'a2' has a non-finite value \(nan\) at sample 4"):
        y = np.zeros((10, 2))
        y[4, 1] = np.nan
        Experiment("e", sig["time"], np.zeros(10), y, ("F1",), ("y1", "a2"))


def test_check_against_reports_every_name_problem():
    sig = signals(10)
    exp = Experiment("e", sig["time"], np.zeros((10, 1)), np.zeros((10, 2)), ("F9",), ("y1", "zz"))
    with pytest.raises(DataError) as info:
        exp.check_against(cfg())
    msg = str(info.value)
    assert "3 problems" in msg and "without data: F1" in msg and "not actuators of the config: F9" in msg
    assert "not sensors of the config: zz" in msg


def test_select_and_split(tmp_path):
    sig = signals()
    exp = load_experiment(write_csv(tmp_path / "s.csv", sig), cfg())
    fit, hold = exp.split(0.8)
    assert (fit.name, hold.name) == ("s_fit", "s_holdout")
    assert fit.n_samples == 800 and hold.n_samples == 200
    np.testing.assert_array_equal(np.r_[fit.time, hold.time], exp.time)
    fit.check_against(cfg())
    hold.check_against(cfg())
    w = exp.select(0.01, 0.02)
    assert w.n_samples == 100 and w.time[0] == pytest.approx(0.01) and w.time[-1] < 0.02
    with pytest.raises(DataError, match=r"no sample in the window"):
        exp.select(5.0, 6.0)
    with pytest.raises(DataError, match=r"split fraction 1\.5 must lie in \(0, 1\)"):
        exp.split(1.5)


def test_load_several_experiments(tmp_path):
    a = write_csv(tmp_path / "a.csv", signals())
    (tmp_path / "b").mkdir()
    b = tmp_path / "b" / "b.npz"
    np.savez(b, **signals(500))
    exps = load_experiments([a, b], cfg(), remove_offset="mean")
    assert [e.name for e in exps] == ["a", "b"] and [e.n_samples for e in exps] == [1000, 500]
    c = write_csv(tmp_path / "b" / "a.csv", signals())
    with pytest.raises(DataError, match=r"experiment name\(s\) a used more than once; pass names="):
        load_experiments([a, c], cfg())
    assert [e.name for e in load_experiments([a, c], cfg(), names=["run1", "run2"])] == ["run1", "run2"]


def test_time_summed_in_floating_point_is_accepted(tmp_path):
    # full-precision times that are a running sum (not k * dt): off the exact grid by ~1e-16 s, still uniform
    sig = signals(5000)
    sig["time"] = np.cumsum(np.r_[0.0, np.full(4999, DT)]) + 0.1
    exp = load_experiment(write_csv(tmp_path / "cumsum.csv", sig), cfg())
    exp.check_against(cfg())
    assert exp.time[0] == pytest.approx(0.1)
