"""The identified model's uncertainty (:mod:`identification.uncertainty`): the residual's frequency response and its
standard error are calibrated, and the bound ``identify`` writes covers held-out data it did not see.

Truth: the repository's independent generator (cubic-Hermite finite elements integrated exactly in time under a
cubic-spline force, :func:`ebb_model.reference.synthetic.synthesize`), on the blind family's clamped–pinned bench.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from ebb_model.reference.excitation import band_limited_input
from ebb_model.reference.synthetic import synthesize
from ebb_model.reference.withheld import WithheldEffect
from identification.export_statespace import load_statespace
from identification.native import NativeEvaluator, experiments_from_arrays
from identification.noise import welch_nperseg
from identification.run import identify
from identification.uncertainty import FOLDER, load_bound, residual_response, uncertainty_model, write_uncertainty

from test_diagnose_cli import _toml
from test_diagnosis_blind import DT, TRUTH, bench_config

N = 6000


def test_the_residual_response_and_its_standard_error_are_calibrated():
    """Two white inputs through two known filters plus white noise: ``residual_response`` returns the filters'
    responses, with standard errors that are the errors' actual size — ``|error| / σ`` of a complex Gaussian
    error has median √(ln 2) = 0.83 and exceeds 2 with probability e⁻⁴ = 1.8 % (the
    fraction above 2 of 3 × 127 bins × 2 inputs is within 0.6–3.5 % with about 99.9 % probability, were the bins
    independent; measured 0.858 and 2.4 %)."""
    rng = np.random.default_rng(5)
    n, dt, nperseg = 40000, 1e-3, 256
    b = [signal.butter(2, 0.2), signal.butter(3, [0.1, 0.4], btype="band")]
    z_all = []
    for seed in range(3):
        u = rng.standard_normal((n, 2))
        y = sum(signal.lfilter(*bk, u[:, k]) for k, bk in enumerate(b)) + 0.3 * rng.standard_normal(n)
        f, E, sigma = residual_response([u], [y[:, None]], dt, nperseg)
        truth = np.stack([signal.freqz(*bk, worN=f, fs=1.0 / dt)[1] for bk in b], axis=-1)
        z_all.append((np.abs(E[:, 0, :] - truth) / sigma[:, 0, :])[1:-1])
    z = np.concatenate(z_all).ravel()
    print(f"\n|error|/sigma: median {np.median(z):.3f} (0.833), above 2: {np.mean(z > 2):.4f} (0.018)")
    assert 0.75 <= np.median(z) <= 0.92
    assert 0.006 <= np.mean(z > 2) <= 0.035


def _records(tmp_path, effect):
    """A fit record and a held-out record (different multisines and noise) of the bench at its truth."""
    cfg = bench_config()
    (tmp_path / "bench.toml").write_text(_toml(cfg))
    files, recs = [], []
    for seed in (5, 6):
        u = band_limited_input(N, DT, 2.0, 60.0, seed=seed)
        rec = synthesize(cfg, u, params=TRUTH, effect=effect, noise=0.01, seed=seed + 100)
        files.append(tmp_path / f"r{seed}.npz")
        np.savez(files[-1], time=rec.time, F1=rec.inputs[:, 0], y1=rec.outputs[:, 0], y2=rec.outputs[:, 1])
        recs.append(rec)
    return files, recs


@pytest.mark.parametrize("effect, param_cover", [
    (None, (0.95, 1.0)),
    (WithheldEffect("point_mass", {"mass": 0.06, "x": 0.7}), (0.0, 0.7)),
])
def test_the_bound_covers_held_out_data(tmp_path, effect, param_cover):
    """``identify`` (defaults but a tiny GA: the polish does the work) on one record writes the uncertainty; on a
    held-out record the model's residual — its frequency response :math:`\\hat E_B` against the held-out force,
    the difference between the truth and the identified model — lies within the written additive bound plus the
    held-out estimate's own two standard errors at every frequency of the band (and so within the multiplicative
    bound: one input).

    Without an effect the parameters' share alone covers it (measured 100 %); with a point mass of 6 % of the
    beam withheld the identified model is biased (EI, ρA, N moved to absorb it; measured: its multiplicative bound
    0.31 median in the band) and the parameters' share covers only 41–45 % of the band — the residual's share is
    what makes the bound true (measured: 100 % with it)."""
    files, recs = _records(tmp_path, effect)
    res = identify(tmp_path / "bench.toml", [files[0]], tmp_path / "out", pop=8, generations=2, progress=False,
                   export=False)
    bound = load_bound(tmp_path / "out" / FOLDER / "bound.npz")
    x = res.polished[0].x
    held = recs[1]
    ev = NativeEvaluator(res.config, res.space, experiments_from_arrays([("held", held.inputs, held.outputs)]))
    r = held.outputs - ev.simulate(x).outputs[0]
    f, E, sigma = residual_response([held.inputs], [r], DT, welch_nperseg(N))
    assert np.allclose(f, bound["f_hz"])
    m = bound["measured"]
    assert m.sum() >= 20                                   # the band 2–60 Hz at 2.7 Hz resolution
    gap = np.abs(E[m]) - 2.0 * sigma[m]
    covered = gap <= bound["additive"][m]
    covered_mult = np.max(gap / np.abs(bound["nominal"][m]), axis=2) <= bound["multiplicative"][m]
    param_only = np.mean(gap <= bound["parametric"][m], axis=0).ravel()
    print(f"\ncovered {covered.mean(axis=0).ravel()}, by the parameters' share alone {param_only}; "
          f"multiplicative bound median {np.median(bound['multiplicative'][m], axis=0)}")
    assert covered.all() and covered_mult.all()
    assert np.all((param_only >= param_cover[0]) & (param_only <= param_cover[1]))
    # the sampled models are StateSpace exports: their parameters scatter as the written covariance says
    samples, cov = bound["samples"], bound["covariance"]
    assert samples.shape == (32, 4)
    z = (samples - x) / np.sqrt(np.diag(cov))
    assert np.all(np.abs(z) < 5.0) and 0.5 < np.std(z) < 1.5      # 128 standard-normal draws
    sys0 = load_statespace(tmp_path / "out" / FOLDER / "sample_0.npz")
    assert sys0.dt == DT and sys0.ninputs == 1 and sys0.noutputs == 2
    from ebb_model.modal.truncation import design_model
    again = design_model(*res.space.apply(res.config, samples[0]))
    assert np.array_equal(sys0.A, again.A) and np.array_equal(sys0.D, again.D)   # the export's own design model
    if effect is None:
        # written again with fewer samples (a resumed run), no earlier sample is left behind
        fit = NativeEvaluator(res.config, res.space, experiments_from_arrays([("fit", recs[0].inputs,
                                                                                recs[0].outputs)]))
        write_uncertainty(uncertainty_model(fit, x, res.noise, n_samples=5), fit, tmp_path / "out", "again")
        assert sorted(p.name for p in (tmp_path / "out" / FOLDER).glob("sample_*.npz")) == [
            f"sample_{j}.npz" for j in range(5)]


def test_inputs_driven_by_one_signal_do_not_break_the_residual_response():
    """Two forces from one signal (a rig's two shakers in parallel): S_uu is singular at every frequency; the
    response is the minimum-norm one, finite, and the two inputs share the filter's response equally."""
    rng = np.random.default_rng(2)
    u1 = rng.standard_normal(8000)
    b, a = signal.butter(2, 0.2)
    y = signal.lfilter(b, a, u1) + 0.1 * rng.standard_normal(8000)
    f, E, sigma = residual_response([np.column_stack([u1, u1])], [y[:, None]], 1e-3, 256)
    assert np.all(np.isfinite(E)) and np.all(np.isfinite(sigma))
    truth = signal.freqz(b, a, worN=f, fs=1e3)[1]
    assert np.allclose(E[:, 0, 0], E[:, 0, 1])
    assert np.median(np.abs(2 * E[:, 0, 0] - truth)) < 0.05 * np.max(np.abs(truth))


@pytest.mark.parametrize("covariance, why", [(np.full((2, 2), np.inf), "not finite"), (np.eye(2), "outside")])
def test_no_sampled_model_says_why(covariance, why):
    """A bound with no sampled model names the reason: a singular Fisher information (the covariance is not
    finite) or draws that all left the bounds; with samples there is no note."""
    from identification.uncertainty import UncertaintyModel

    nf = 4
    one = np.ones((nf, 1, 1))
    args = (("EI", "rhoA"), np.ones(2), covariance)
    rest = (np.linspace(1.0, 4.0, nf), np.ones(nf, bool), one, 0.1 * one, 0.1 * one, ("F1",), ("y1",))
    empty = UncertaintyModel(*args, np.empty((0, 2)), *rest).summary()
    assert empty["samples"] == 0 and why in empty["samples_note"]
    assert UncertaintyModel(*args, np.ones((3, 2)), *rest).summary()["samples_note"] is None


def _blow(n: int, at: int, seed: int) -> np.ndarray:
    """A 10 ms sin² blow of 50 N at sample ``at`` (a hammer), with a load cell's noise of 0.01 N."""
    u = np.zeros((n, 1))
    w = int(round(0.01 / DT))
    u[at:at + w, 0] = 50.0 * np.sin(np.pi * np.arange(w) / w) ** 2
    return u + 0.01 * np.random.default_rng(seed).standard_normal((n, 1))


def test_a_hammer_record_gets_its_uncertainty(tmp_path):
    """A blow near the record's start (as a hammer test records it): the excited band is the blow's wherever it
    falls in the record (it was read as 0–0.5 Hz from Welch's Hann segments, which all but hide a blow at the
    start), so the uncertainty has a band and a bound; a held-out blow's residual lies within the additive bound
    plus its own two standard errors on every bin of the band (measured: all).  A record read whole is one segment,
    whose coherence is 1 by construction: the residual's incoherent power is the noise model's (without it the
    bound covered 52 % of the bins, its standard errors zero)."""
    from ebb_model.space.adequacy import excited_band

    lo0, hi0 = excited_band([_blow(N, 100, 0)], DT)
    lo1, hi1 = excited_band([_blow(N, N // 2, 0)], DT)
    assert hi0 > 100.0 and abs(hi0 - hi1) <= 2.0 / (N * DT) and lo0 == lo1
    cfg = bench_config()
    (tmp_path / "bench.toml").write_text(_toml(cfg))
    files, recs = [], []
    for seed in (5, 6):
        rec = synthesize(cfg, _blow(N, 100, seed), params=TRUTH, noise=0.01, seed=seed + 100)
        files.append(tmp_path / f"r{seed}.npz")
        np.savez(files[-1], time=rec.time, F1=rec.inputs[:, 0], y1=rec.outputs[:, 0], y2=rec.outputs[:, 1])
        recs.append(rec)
    res = identify(tmp_path / "bench.toml", [files[0]], tmp_path / "out", pop=8, generations=2, progress=False,
                   export=False)
    bound = load_bound(tmp_path / "out" / FOLDER / "bound.npz")
    m = bound["measured"]
    assert bound["f_hz"][m].max() >= hi0 - 1.0 and m.sum() > 100
    held = recs[1]
    ev = NativeEvaluator(res.config, res.space, experiments_from_arrays([("held", held.inputs, held.outputs)]))
    r = held.outputs - ev.simulate(res.polished[0].x).outputs[0]
    psd = np.stack([sp.psd(np.fft.rfftfreq(N, DT), DT) for sp in res.noise.spectra[0]], axis=-1)
    f, E, sigma = residual_response([held.inputs], [r], DT, N, "boxcar", [psd])
    assert np.allclose(f, bound["f_hz"])
    covered = np.abs(E[m]) - 2.0 * sigma[m] <= bound["additive"][m]
    w = np.median(bound["multiplicative"][m], axis=0)
    print(f"\nhammer: band {bound['f_hz'][m].min():.3g}-{bound['f_hz'][m].max():.3g} Hz, covered "
          f"{covered.mean(axis=0).ravel()}, multiplicative bound median {w}")
    assert covered.all()
