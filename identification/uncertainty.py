r"""Uncertainty a robust-control designer can use: the parameters' covariance, models sampled from it, and a
frequency-dependent multiplicative bound per output.

The identified model :math:`G_0` (the design model of the export, :func:`ebb_model.modal.truncation.design_model`, at
the identified unknowns :math:`\hat x`) comes with

* the **covariance** :math:`P = S F^{-1} S` of the unknowns, :math:`F` the Fisher information of the scaled
  unknowns under the run's noise model and :math:`S` their scales (:mod:`identification.fisher`: the Cramér–Rao
  bound, valid when the fit's residual is at the noise floor);
* **K models sampled** from :math:`\mathcal N(\hat x, P)` inside the bounds — what a Monte-Carlo robustness check
  runs;
* per output :math:`s` a **multiplicative bound** :math:`w_s(f)` such that

  .. math::  |G[s,k] - G_0[s,k]| \le w_s(f)\,|G_0[s,k]| \quad\text{for every input } k,

  for every model of the set *and* for the dynamics the fit left unexplained:
  :math:`w_s = \max_k (a^{par}_{sk} + a^{res}_{sk}) / |G_0[s,k]|` with

  - :math:`a^{par}_{sk}(f) = \max_j |G_j[s,k] - G_0[s,k]|` over the sampled models (the parameters' share), and
  - :math:`a^{res}_{sk}(f) = |\hat E_{sk}| + 2\,\sigma(\hat E_{sk})`: the fit residual's part coherent with the
    inputs, :math:`\hat E = S_{ur}^{T} S_{uu}^{-1}` (Welch cross-spectra of the records' inputs :math:`u` and
    residuals :math:`r = y - G_0 u`, the unmodelled dynamics), plus twice its standard error,
    :math:`\sigma^2(\hat E_{sk}) = (1-\gamma_s^2)\,S_{r_s r_s}\,[S_{uu}^{-1}]_{kk} / n_d` (Bendat & Piersol,
    multiple-input frequency responses; :math:`\gamma_s^2` the multiple coherence of the residual with the
    inputs, :math:`n_d` the number of averages).

Outside the band the records' inputs excite, the records say nothing about unmodelled dynamics: there the bound is
the parameters' share only and ``measured`` is false — a designer must add his own weight above the band.
Near an anti-resonance :math:`|G_0|` is small and the multiplicative bound large: that is what multiplicative
uncertainty means there; the additive parts are kept too.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from scipy import signal

from ebb_model.space.adequacy import excited_band, is_transient
from ebb_model.errors import DataError, StabilityError
from ebb_model.io.jsonio import write_json
from ebb_model.modal.modal import frequency_response
from ebb_model.io.output import atomic_path, make_dir
from ebb_model.theta.modal_form import ModalStateSpace
from ebb_model.statespace import DiscreteStateSpace
from ebb_model.modal.truncation import ModeResolution, design_modal_model, design_resolution

from .fisher import fisher_information
from .native import NativeEvaluator
from .noise import welch_dof, welch_nperseg
from .noise_model import NoiseModel

__all__ = ["UncertaintyModel", "uncertainty_model", "write_uncertainty", "load_bound", "N_SAMPLES", "FOLDER"]

#: Models sampled from the covariance by default.
N_SAMPLES = 32
#: The folder of a run's output directory that takes the uncertainty.
FOLDER = "uncertainty"


@dataclass(frozen=True, eq=False)
class UncertaintyModel:
    """The identified model's uncertainty (module docstring).

    Attributes
    ----------
    names, point, covariance
        The unknowns, their identified values and covariance (``inf`` everywhere when not identifiable).
    samples
        Parameter sets drawn from the covariance inside the bounds, shape ``(K, p)`` (the stable ones).
    f_hz, measured
        The frequency grid [Hz] and where the records' inputs excite it (the residual's share is known there).
    nominal
        :math:`G_0` on the grid, ``(nf, n_out, n_in)``.
    parametric, residual
        The additive shares :math:`a^{par}`, :math:`a^{res}` (``nan`` outside the band), ``(nf, n_out, n_in)``.
    input_names, output_names
        The signals.
    systems
        The sampled models as StateSpace design models, one per row of ``samples``.
    """

    names: tuple[str, ...]
    point: np.ndarray
    covariance: np.ndarray
    samples: np.ndarray
    f_hz: np.ndarray
    measured: np.ndarray
    nominal: np.ndarray
    parametric: np.ndarray
    residual: np.ndarray
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    systems: tuple[DiscreteStateSpace, ...] = ()

    @property
    def additive(self) -> np.ndarray:
        """The additive bound per output and input, ``(nf, n_out, n_in)`` (the residual's share where known)."""
        return self.parametric + np.where(np.isnan(self.residual), 0.0, self.residual)

    @property
    def multiplicative(self) -> np.ndarray:
        """The multiplicative bound :math:`w_s(f)` per output, ``(nf, n_out)``: the largest over the inputs."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.max(self.additive / np.abs(self.nominal), axis=2)

    def summary(self) -> dict[str, Any]:
        """JSON-ready: the covariance, the standard deviations, the band and the bound's size in it."""
        w = self.multiplicative[self.measured]
        share = (self.parametric / np.maximum(self.additive, 1e-300))[self.measured]
        return {"parameters": list(self.names), "point": dict(zip(self.names, map(float, self.point))),
                "covariance": [[float(v) for v in row] for row in self.covariance],
                "std": dict(zip(self.names, map(float, np.sqrt(np.diag(self.covariance))))),
                "samples": int(self.samples.shape[0]),
                "band_hz": [float(self.f_hz[self.measured].min()), float(self.f_hz[self.measured].max())]
                if self.measured.any() else None,
                "multiplicative_bound_in_band": {
                    s: {"median": float(np.median(w[:, i])), "max": float(np.max(w[:, i]))}
                    for i, s in enumerate(self.output_names)} if w.size else {},
                "parametric_share_in_band_median": float(np.median(share)) if share.size else None,
                "samples_note": self._samples_note()}

    def _samples_note(self) -> str | None:
        """Why no model was sampled, when none was."""
        if self.samples.shape[0]:
            return None
        if not np.all(np.isfinite(self.covariance)):
            return ("no model sampled: the parameters' covariance is not finite (the Fisher information is singular "
                    "at the identified point; the bound is the fit residual's share alone)")
        return ("no model sampled: every draw from the parameters' covariance fell outside the search bounds or was "
                "unstable (the bound is the fit residual's share alone)")


def parameter_covariance(matrix: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """:math:`P = S F^{-1} S` from the Fisher information ``matrix`` of the scaled unknowns and their ``scales``;
    ``inf`` everywhere when ``matrix`` is singular."""
    try:
        Finv = np.linalg.inv(matrix)
    except np.linalg.LinAlgError:
        return np.full(matrix.shape, np.inf)
    P = scales[:, None] * Finv * scales[None, :]
    return 0.5 * (P + P.T)


def _draw(point: np.ndarray, cov: np.ndarray, lower: np.ndarray, upper: np.ndarray, k: int,
          rng: np.random.Generator) -> np.ndarray:
    """``k`` draws from :math:`\\mathcal N(point, cov)` inside ``[lower, upper]`` (rejection; fewer when the
    bounds cut most of the distribution away)."""
    if not np.all(np.isfinite(cov)):
        return np.empty((0, point.size))
    L = np.linalg.cholesky(cov + 1e-30 * np.eye(point.size) * np.max(np.abs(np.diag(cov)), initial=1.0))
    out: list[np.ndarray] = []
    for _ in range(20):
        x = point + rng.standard_normal((2 * k, point.size)) @ L.T
        out += [v for v in x if np.all(v >= lower) and np.all(v <= upper)]
        if len(out) >= k:
            break
    return np.array(out[:k]).reshape(-1, point.size)


def _responses(evaluator: NativeEvaluator, xs: Sequence[np.ndarray], f_hz: np.ndarray,
               resolution: ModeResolution | None
               ) -> tuple[list[np.ndarray], list[np.ndarray], list[ModalStateSpace | DiscreteStateSpace]]:
    """The design models' responses at ``f_hz`` of the parameter sets ``xs`` that are stable, those sets and
    their design models (:func:`ebb_model.modal.truncation.design_modal_model`, keeping the modes ``resolution``
    keeps: the identified model's)."""
    H, kept, models = [], [], []
    for x in xs:
        try:
            model = design_modal_model(*evaluator.space.apply(evaluator.config, x), resolution=resolution)
        except StabilityError:
            continue
        H.append(frequency_response(model, f_hz).H)
        kept.append(x)
        models.append(model)
    return H, kept, models


def residual_response(inputs: Sequence[np.ndarray], residuals: Sequence[np.ndarray], dt: float,
                      nperseg: int, window: str = "hann", noise_psd: Sequence[np.ndarray] | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The residuals' part coherent with the inputs and its standard error (module docstring); ``window`` of the
    Welch segments (``"boxcar"`` for a blow read as one segment: a Hann window would all but hide it).

    ``noise_psd``: per record the noise's one-sided PSD ``(nf, n_out)`` on the Welch grid, taken as the residual's
    incoherent power instead of what the averages leave — for records read as one segment each (a blow), where
    the coherence of a single segment is 1 by construction and the averages leave nothing to estimate it from.

    Returns
    -------
    f_hz, E, sigma
        The Welch grid and, on it, :math:`\\hat E` ``(nf, n_out, n_in)`` and :math:`\\sigma(\\hat E)` (real).
    """
    n_in, n_out = inputs[0].shape[1], residuals[0].shape[1]
    fs = 1.0 / dt

    def cs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return signal.csd(a, b, fs=fs, nperseg=nperseg, window=window)[1]

    parts, weights, n_d = [], [], 0.0
    for k, (u, r) in enumerate(zip(inputs, residuals)):
        uu = np.stack([np.stack([cs(u[:, i], u[:, j]) for j in range(n_in)], -1) for i in range(n_in)], 1)
        ur = np.stack([np.stack([cs(u[:, i], r[:, s]) for s in range(n_out)], -1) for i in range(n_in)], 1)
        rr = np.stack([cs(r[:, s], r[:, s]).real for s in range(n_out)], -1)
        parts.append((uu, ur, rr, np.zeros_like(rr) if noise_psd is None else np.asarray(noise_psd[k], float)))
        dof = welch_dof(u.shape[0], nperseg)
        weights.append(dof)
        n_d += dof / 2.0                    # complex averages: two degrees of freedom each
    w = np.array(weights) / sum(weights)    # records averaged by their equivalent degrees of freedom
    Suu, Sur, Srr, Snn = (sum(wi * p[k] for wi, p in zip(w, parts)) for k in range(4))
    f = signal.welch(inputs[0][:, 0], fs=fs, nperseg=nperseg, window=window)[0]
    # Suu[f, i, j] = E[U_i* U_j], Sur[f, i, s] = E[U_i* R_s]; R_s = Σ_j E_sj U_j  ⇒  Sur = Suu Eᵀ
    # the pseudo-inverse: inputs driven by one signal (or a bin without power) leave S_uu singular
    Suu_inv = np.linalg.pinv(Suu, rcond=1e-12, hermitian=True)
    Et = Suu_inv @ Sur                                                  # (nf, n_in, n_out)
    E = Et.transpose(0, 2, 1)
    coherent = np.einsum("fis,fij,fjs->fs", Et.conj(), Suu, Et).real    # the residual's power the inputs explain
    incoherent = np.maximum(Srr - coherent, 0.0) if noise_psd is None else Snn
    inv_diag = np.real(np.diagonal(Suu_inv, axis1=1, axis2=2))          # [S_uu⁻¹]_kk
    sigma = np.sqrt(incoherent[:, :, None] * inv_diag[:, None, :] / n_d)
    return f, E, sigma


def uncertainty_model(evaluator: NativeEvaluator, x: np.ndarray, noise: NoiseModel, *, n_samples: int = N_SAMPLES,
                      seed: int = 0) -> UncertaintyModel:
    """The uncertainty of the model identified at ``x`` from ``evaluator``'s records under ``noise``.

    Raises
    ------
    StabilityError
        The model at ``x`` is unstable.
    DataError
        The records' inputs carry no power.
    """
    x = np.asarray(x, dtype=float)
    cfg, space, exps = evaluator.config, evaluator.space, evaluator.experiments
    dt = cfg.time.dt
    fi = fisher_information(evaluator, x, noise=noise)
    cov = parameter_covariance(fi.matrix, fi.scales) if not fi.singular else np.full((x.size, x.size), np.inf)
    draws = _draw(x, cov, space.lower, space.upper, n_samples, np.random.default_rng(seed))
    sim = evaluator.simulate(x)
    if not sim.stable:
        raise StabilityError("uncertainty: the identified model is unstable")
    # a blow is read as one segment, the whole record (2 degrees of freedom per record), as the records' start does
    transient = any(is_transient(e.inputs) for e in exps)
    nperseg = min(e.inputs.shape[0] if transient else welch_nperseg(e.inputs.shape[0]) for e in exps)
    # (its residual's incoherent power is the noise model's: one segment's coherence is 1 by construction)
    grid = np.fft.rfftfreq(nperseg, dt)
    noise_psd = [np.stack([sp.psd(grid, dt) for sp in row], axis=-1) for row in noise.spectra] if transient else None
    f, E, sigma = residual_response([e.inputs for e in exps], [e.outputs - y for e, y in zip(exps, sim.outputs)],
                                    dt, nperseg, "boxcar" if transient else "hann", noise_psd)
    lo, hi = excited_band([e.inputs for e in exps], dt)
    measured = (f >= lo) & (f <= hi) & (f > 0)
    # the export's design model: the modes the grid resolves at the identified point, kept in every draw too
    resolution = design_resolution(*space.apply(cfg, x))
    (G0,), _, _ = _responses(evaluator, [x], f, resolution)
    H, kept, models = _responses(evaluator, list(draws), f, resolution)
    parametric = np.max(np.abs(np.array(H) - G0[None]), axis=0) if H else np.zeros(G0.shape)
    residual = np.where(measured[:, None, None], np.abs(E) + 2.0 * sigma, np.nan)
    return UncertaintyModel(tuple(space.names), x, cov, np.array(kept).reshape(-1, x.size), f, measured, G0,
                            parametric, residual, tuple(cfg.input_names), tuple(cfg.output_names),
                            tuple(m if isinstance(m, DiscreteStateSpace) else m.to_statespace() for m in models))


def write_uncertainty(model: UncertaintyModel, evaluator: NativeEvaluator, out_dir: str | Path,
                      title: str) -> list[Path]:
    """Write ``<out_dir>/uncertainty/``: ``bound.npz`` (the grid, the bound and its shares, the covariance and the
    samples; :func:`load_bound`), ``bound.json`` (:meth:`UncertaintyModel.summary`) and ``sample_<j>.npz``, each
    sampled model as a StateSpace (:func:`identification.export_statespace.load_statespace`)."""
    from .export_statespace import save_statespace

    d = make_dir(Path(out_dir) / FOLDER, exist_ok=True)
    # Any: mypy matches a dict[str, ndarray] passed as **kwargs against savez's allow_pickle (these keys are not)
    arrays: dict[str, Any] = {
        "f_hz": model.f_hz, "measured": model.measured, "multiplicative": model.multiplicative,
        "additive": model.additive, "parametric": model.parametric, "residual": model.residual,
        "nominal": model.nominal, "covariance": model.covariance, "point": model.point,
        "samples": model.samples, "parameters": np.array(model.names), "inputs": np.array(model.input_names),
        "outputs": np.array(model.output_names)}
    with atomic_path(d / "bound.npz", suffix=".npz") as tmp:
        np.savez(tmp, **arrays)
    written = [d / "bound.npz", write_json(d / "bound.json", model.summary())]
    for stale in d.glob("sample_*.npz"):          # a resumed run's earlier samples (it may draw fewer)
        index = stale.stem.removeprefix("sample_")
        if index.isdigit() and int(index) >= len(model.samples):
            stale.unlink()
    for j, xj in enumerate(model.samples):
        c, params = evaluator.space.apply(evaluator.config, xj)
        written.append(save_statespace(model.systems[j], d / f"sample_{j}.npz", name=f"{title}_sample_{j}",
                                       parameters=params, config=c.to_dict()))
    return written


def load_bound(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays of a written ``bound.npz`` (:func:`write_uncertainty`).

    Raises
    ------
    DataError
        Not such a file.
    """
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise DataError(f"{path}: not an uncertainty bound file ({exc})") from None

