"""Natural frequencies picked from a spectrum file (:mod:`identification.spectrum_modes`, ``--modes FILE``).

Truth: the maxima of a four-mode accelerance evaluated analytically (each located to 1e-6 Hz on a fine grid
around its mode — the neighbours shift them, so not f_n/√(1−2ζ²)), written to a file at three resolutions with
log-normal noise of 0, 0.9 and 2.6 dB per bin, as an FFT's magnitude is.
"""
from __future__ import annotations

import numpy as np
import pytest

from ebb_cli import main
from ebb_model.errors import DataError
from identification.spectrum_modes import spectrum_modes

from test_diagnose_cli import _toml
from test_diagnosis_blind import bench_config

FN = np.array([7.3, 45.1, 127.9, 250.2])
ZETA = np.array([0.01, 0.005, 0.004, 0.003])
AMP = np.array([1.0, 0.6, 0.5, 0.3])


def _accelerance(f: np.ndarray) -> np.ndarray:
    return np.abs((2 * np.pi * f) ** 2 * sum(a / (fn ** 2 - f ** 2 + 2j * z * fn * f)
                                           for fn, z, a in zip(FN, ZETA, AMP)))


def _true_peaks() -> np.ndarray:
    peaks = []
    for fn in FN:
        f = np.linspace(0.98 * fn, 1.02 * fn, 400_001)      # 1e-6 relative steps
        peaks.append(f[np.argmax(_accelerance(f))])
    return np.array(peaks)


def _write(tmp_path, df: float, noise: float):
    f = np.arange(0.0, 400.0, df)
    mag = _accelerance(f) * np.exp(noise * np.random.default_rng(0).standard_normal(f.size))
    path = tmp_path / f"s_{df}_{noise}.csv"
    np.savetxt(path, np.column_stack([f, mag]), delimiter=",", header="frequency,magnitude", comments="")
    return path


@pytest.mark.parametrize("noise", [0.0, 0.1, 0.3])
@pytest.mark.parametrize("df", [0.05, 0.25, 0.5])
def test_peaks_are_found_within_their_stated_uncertainty(tmp_path, df, noise):
    """Every mode found, each within 3 of its own standard uncertainties of the true maximum (model_error 0:
    the procedure's uncertainty alone); measured |z| ≤ 2.0 over these nine spectra."""
    m = spectrum_modes(_write(tmp_path, df, noise), model_error=0.0)
    assert m.count == 4
    z = (m.frequencies_hz - _true_peaks()) / m.std_hz
    assert np.all(np.abs(z) < 3.0), (m.frequencies_hz, z)
    # the uncertainty is the procedure's, not inflated: below a bin width
    assert np.all(m.std_hz < df + 3e-4 * FN + 0.15)


def test_count_band_and_model_error(tmp_path):
    path = _write(tmp_path, 0.25, 0.1)
    m = spectrum_modes(path, count=2, band_hz=(20.0, 300.0), model_error=0.01)
    np.testing.assert_allclose(m.frequencies_hz, _true_peaks()[1:3], rtol=2e-3)
    assert np.all(m.std_hz >= 0.01 * m.frequencies_hz)
    with pytest.raises(DataError, match="4 resonance peak"):
        spectrum_modes(path, count=5)
    with pytest.raises(ValueError, match="count"):
        spectrum_modes(path, count=0)


def test_the_cli_takes_a_spectrum_as_measured_modes(tmp_path, capsys):
    """``--modes FILE``: a table in the config as well is refused (stated once), a bad file named — one line,
    exit 2, nothing written."""
    cfg = bench_config()
    (tmp_path / "c.toml").write_text(_toml(cfg) + "[identification.modes]\nfrequencies_hz = [8.0]\nstd_hz = [0.1]\n")
    spec = _write(tmp_path, 0.25, 0.0)
    rec = tmp_path / "r.csv"
    np.savetxt(rec, np.zeros((10, 4)), delimiter=",", header="time,F1,y1,y2", comments="")
    assert main(["diagnose", str(tmp_path / "c.toml"), str(rec), "--modes", str(spec), "--out",
                 str(tmp_path / "o1"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "identification.modes" in err and "once" in err, err
    (tmp_path / "plain.toml").write_text(_toml(cfg))
    junk = tmp_path / "junk.csv"
    junk.write_bytes(b"\x00\x01\x02binary")
    assert main(["diagnose", str(tmp_path / "plain.toml"), str(rec), "--modes", str(junk), "--out",
                 str(tmp_path / "o2"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "junk.csv" in err, err
    assert not (tmp_path / "o1").exists() and not (tmp_path / "o2").exists()


# --- a cantilever's spectrum as an unfiltered acquisition shows it (issue 51) ---------------------------------------
BETA_L = np.array([1.875104, 4.694091, 7.854757, 10.995541] + [(2 * n - 1) * np.pi / 2 for n in range(5, 17)])


def _cantilever_shape(beta_l: float, xi: np.ndarray) -> np.ndarray:
    """Clamped–free mode shape at ``xi = x/L`` in the overflow-free form (exponentials of ``β(x − L) ≤ 0``)."""
    b = beta_l
    sig = (np.cosh(b) + np.cos(b)) / (np.sinh(b) + np.sin(b))
    one_minus = (np.sin(b) - np.cos(b) - np.exp(-b)) / (np.sinh(b) + np.sin(b))      # 1 − σ, exactly
    return (0.5 * one_minus * np.exp(b * xi) + 0.5 * (1 + sig) * np.exp(-b * xi)
            - np.cos(b * xi) + sig * np.sin(b * xi))


def _cantilever_file(tmp_path, fs: float, daq_filter: bool):
    """The analytic tip accelerance of a cantilever driven at 3/4 of its length (16 modes, f1 7.3 Hz, ζ 0.3 %),
    as an acquisition at ``fs`` records it: with ``daq_filter`` behind an 8-pole Butterworth anti-alias filter at
    0.4 fs (a DAQ's), else unfiltered; either way every image of the continuous response is folded into the band
    (the sampled response's spectrum is ``Σ_k H(f − k fs)``); 0.3 dB of scatter.  Returns the file and the modes."""
    f1 = 7.3
    fn = f1 * (BETA_L / BETA_L[0]) ** 2
    amp = _cantilever_shape(BETA_L[:, None], np.array([0.75, 1.0]))
    f = np.arange(0.5, fs / 2, 0.05)

    def h(g: np.ndarray) -> np.ndarray:
        w = 2 * np.pi * g
        resp = sum(-(w ** 2) * a0 * a1 / ((2 * np.pi * v) ** 2 - w ** 2 + 2j * 0.003 * (2 * np.pi * v) * w)
                   for v, (a0, a1) in zip(fn, amp))
        return resp / np.sqrt(1.0 + (g / (0.4 * fs)) ** 16) if daq_filter else resp

    mag = np.abs(sum(h(f - k * fs) for k in range(-3, 4)))
    mag *= np.exp(0.3 / 8.686 * np.random.default_rng(1).standard_normal(f.size))
    path = tmp_path / "cantilever.csv"
    np.savetxt(path, np.column_stack([f, mag]), delimiter=",", header="frequency,magnitude", comments="")
    return path, fn


@pytest.mark.parametrize("fs, daq_filter", [(1000.0, True), (2000.0, True), (5000.0, True), (2000.0, False)])
def test_a_cantilever_spectrum_read_as_its_lowest_modes(tmp_path, fs, daq_filter):
    """Each peak taken is the beam's next mode, in order, from mode 1: behind the DAQ's filter the lowest five at
    least; at 5 kHz the list stops below mode 10 (1849 Hz), whose peak is too weak at this sensor pair — before
    the rule the peak above it was taken as mode 10 —; unfiltered at 2 kHz mode 3 drowns among folded images and
    the list stops below it — before the rule mode 4 was taken as mode 3, and images at 519 and 711 Hz as modes."""
    path, fn = _cantilever_file(tmp_path, fs, daq_filter)
    picked = spectrum_modes(path, model_error=0.0).frequencies_hz
    assert picked.size >= (5 if daq_filter else 2), picked
    # within 0.5 %: the neighbours (and the images) shift a peak a little
    np.testing.assert_allclose(picked, fn[:picked.size], rtol=5e-3)
