r"""Model evidence of the baseline and of each refitted candidate, and their posterior probabilities.

For a model with unknowns ``z`` (the baseline's, plus an effect's) mapped to the unit box ``u ∈ [0, 1]^d`` of the
fits, whitened residuals of unit variance and the user's priors, the Laplace approximation at the fit (the
posterior mode) is

.. math::

    \ln Z \approx -\tfrac12 \chi^2(\hat u) + \ln \pi(\hat u) + \tfrac{d}{2}\ln 2\pi - \tfrac12 \ln\det H,
    \qquad H = J^\top J ,

with ``χ²`` the fit's sum of squares (whitened residuals and the Gaussian priors' rows), ``ln π`` the priors'
normalisers — ``-½ ln(2π σ_u²)`` for a Gaussian prior of standard deviation ``σ_u`` in box units, ``0`` for a
uniform prior over the bounds — and ``J`` the fit's Jacobian in box units (MacKay, *Information Theory, Inference,
and Learning Algorithms*, ch. 27-28; Beck & Katafygiotis 1998 for structural models).  Terms common to every
candidate (the data's normaliser, the noise model's) cancel in the probabilities and are left out.

A direction the data do not constrain (an effect degenerate with the baseline, with no prior to break it) would
make ``det H`` vanish: its eigenvalue is floored at ``2π``, where the Gaussian's normaliser equals that of the
uniform prior over the whole box — the direction then neither adds nor costs evidence, as an exact integral over
a flat posterior in a box of width 1 gives.  A one-sided effect whose optimum sits on its "off" bound is half a
Gaussian; the approximation keeps the full one (an error of ``ln 2`` at most, far below the differences that
decide a verdict).

Posterior probabilities across the candidates take equal prior probabilities per model (the baseline included:
``"none"``), or an earlier diagnosis' posteriors of the same bench (:func:`log_posteriors`: the records a design
of :mod:`diagnosis.design` asked for, weighed with those that asked for it).  :func:`laplace_log_evidence` is
checked against importance sampling on a small case in the tests.

**On the finer numerics.**  The evidence assumes the model exact; a grid's discretisation error is not, and an
effect's extra freedom absorbs part of it: on the clamped strip in tension under a broadband force (three sensors,
323 nodes, no effect in the record) a weak segment of factor 0.9997 lowered χ² by 181 — the grid's error at the
high, lightly damped modes, not a crack — and "none" was quoted at a posterior probability of 4e-31.  Refitted on
four times the grid, the same refits lower χ² by 25 (the crack), 10, 6 and −1, and "none" takes 0.999.  Those refits
cost 110 s; the evidence here takes them to first order instead (:func:`numerics_shift`, :func:`chi2_on_finer`):
the whitened residuals' change ``δr`` from the problem's numerics to the finer ones is measured once at the baseline
(one evaluation), and each model's χ² is its bounded Gauss–Newton minimum of ``r + δr + J Δ`` — the fits' own
Jacobians.  On that case: 30, 12, 9 and 0.3 for the refits' 25, 10, 6 and −1, the baseline's χ² within 0.01 of its
refit on the finer grid.
"""
from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Mapping

import numpy as np
from scipy.optimize import lsq_linear

from ebb_model.errors import DataError
from identification.objectives import PENALTY
from identification.numerics import refinements

from ..effects import Effect
from .fitting import Fit, GapProblem

__all__ = ["FLAT_EIGENVALUE", "chi2_on_finer", "earlier_evidence", "earlier_log_posteriors", "laplace_log_evidence",
           "log_posteriors", "numerics_shift", "posterior_probabilities", "prior_log_normaliser"]

#: Floor of the Hessian's eigenvalues in box units: a Gaussian of this precision has the uniform box's normaliser.
FLAT_EIGENVALUE = 2.0 * math.pi


def prior_log_normaliser(problem: GapProblem) -> float:
    """``Σ -½ ln(2π σ_u²) − ½ ln det R`` over the baseline unknowns with a Gaussian prior (``σ_u``: the prior's
    standard deviation in units of the unknown's bounds, ``R`` the priors' correlation); ``0`` without priors."""
    prior = problem.prior
    if prior is None or not prior.count:
        return 0.0
    span = np.asarray(problem.space.upper, dtype=float) - np.asarray(problem.space.lower, dtype=float)
    g = prior.given
    sigma_u = prior.std[g] / span[g]
    return float(np.sum(-0.5 * np.log(2.0 * math.pi * sigma_u ** 2))) - 0.5 * prior.log_det_corr()


def laplace_log_evidence(problem: GapProblem, fit: Fit, chi2: float | None = None) -> float:
    """The Laplace approximation of ``ln Z`` at a fit (baseline or refit; module docstring), with the fit's χ²
    or ``chi2`` in its place (:func:`chi2_on_finer`)."""
    rss = float(fit.rss if chi2 is None else chi2)
    J = np.asarray(fit.jac, dtype=float)
    d = J.shape[1] if J.ndim == 2 else 0
    if d == 0:
        return -0.5 * rss + prior_log_normaliser(problem)
    lam = np.linalg.eigvalsh(J.T @ J)
    log_det = float(np.sum(np.log(np.maximum(lam, FLAT_EIGENVALUE))))
    return -0.5 * rss + prior_log_normaliser(problem) + 0.5 * d * math.log(2.0 * math.pi) - 0.5 * log_det


def numerics_shift(problem: GapProblem, baseline: Fit, band_hz: float) -> np.ndarray | None:
    """The change of the baseline's whitened residuals (the priors' rows included, unchanged) from the problem's
    numerics to the finer ones (every :func:`identification.numerics.refinements` at once, for the excited band's
    top ``band_hz``), or ``None`` when there are none or the finer model cannot be evaluated."""
    at, params = problem.space.apply(problem.config, baseline.beta)
    finer = problem.config
    for _what, refine in refinements(at, params, [r.inputs for r in problem.records], band_hz):
        finer = refine(finer)
    if finer is problem.config:
        return None
    r_fine = replace(problem, config=finer).residuals(baseline.beta)
    if np.any(r_fine == PENALTY):
        return None
    return r_fine - problem.residuals(baseline.beta)


def chi2_on_finer(problem: GapProblem, fit: Fit, effect: Effect | None, shift: np.ndarray) -> float:
    """The χ² of ``fit``'s model (``effect``'s refit, or the baseline's for ``None``) on the finer numerics, to
    first order: the bounded Gauss–Newton minimum of ``r + shift + J Δ`` over the fit's box (module docstring)."""
    box = problem.box(effect)
    u = box.to_unit(np.concatenate([fit.beta, fit.s]) if effect is not None else fit.beta)
    r = np.asarray(fit.residuals, dtype=float) + shift
    J = np.asarray(fit.jac, dtype=float)
    if J.ndim != 2 or J.shape[1] == 0:
        return float(r @ r)
    step = lsq_linear(J, -r, bounds=(-u, 1.0 - u)).x
    rr = r + J @ step
    return float(rr @ rr)


def posterior_probabilities(problem: GapProblem, baseline: Fit, refits: Mapping[str, Fit], *,
                            effects: Mapping[str, Effect] | None = None, shift: np.ndarray | None = None,
                            earlier: Mapping[str, float] | None = None) -> dict[str, float]:
    """Posterior probability of the baseline (``"none"``) and of each refitted candidate, ordered from the most
    probable: ``exp`` of :func:`log_posteriors` (the same arguments)."""
    logp = log_posteriors(problem, baseline, refits, effects=effects, shift=shift, earlier=earlier)
    return {lab: math.exp(v) for lab, v in logp.items()}


def log_posteriors(problem: GapProblem, baseline: Fit, refits: Mapping[str, Fit], *,
                   effects: Mapping[str, Effect] | None = None, shift: np.ndarray | None = None,
                   earlier: Mapping[str, float] | None = None) -> dict[str, float]:
    """The natural logarithm of the posterior probability of the baseline (``"none"``) and of each refitted
    candidate, from :func:`laplace_log_evidence`, ordered from the most probable (kept as logarithms: a model
    the records rule out decisively underflows as a probability, and a later record is weighed against it).

    The prior probabilities are equal, or with ``earlier`` — the log posteriors of an earlier diagnosis of the
    same bench on other records (:func:`earlier_log_posteriors`) — that diagnosis' posterior: the evidence of
    independent records multiplies.  A model the earlier diagnosis did not weigh (not refitted there) takes the
    earlier's largest, so it is neither favoured nor ruled out by records that said nothing of it.  Each record's
    evidence integrates its own fit of the beam's unknowns (their sharing across records is not used: the
    product is the evidence of records whose set-ups may differ, e.g. a sensor added by the design of
    :mod:`diagnosis.design`).  With ``shift`` (:func:`numerics_shift`) and the refits' ``effects``, each model's
    χ² is taken on the finer numerics (:func:`chi2_on_finer`)."""
    def chi2(fit: Fit, effect: Effect | None) -> float | None:
        return None if shift is None else chi2_on_finer(problem, fit, effect, shift)

    if shift is not None and effects is None:
        raise ValueError("the refits' effects are needed to take their χ² on the finer numerics")
    logz = {"none": laplace_log_evidence(problem, baseline, chi2(baseline, None))}
    logz |= {lab: laplace_log_evidence(problem, fit, chi2(fit, None if effects is None else effects[lab]))
             for lab, fit in refits.items()}
    if earlier:
        unweighed = max(earlier.values())
        logz = {lab: v + earlier.get(lab, unweighed) for lab, v in logz.items()}
    top = max(logz.values())
    norm = top + math.log(sum(math.exp(v - top) for v in logz.values()))
    return dict(sorted(((lab, v - norm) for lab, v in logz.items()), key=lambda kv: -kv[1]))


def earlier_evidence(path: str | Path, file_name: str) -> dict[str, float]:
    """The log posteriors of an earlier diagnosis (:func:`earlier_log_posteriors`), read from its document
    ``file_name`` (``gap.json``) or the directory holding it.

    Raises
    ------
    DataError
        No such file, not JSON, or not a diagnosis' document with its log posteriors.
    """
    where = Path(path)
    where = where / file_name if where.is_dir() else where
    try:
        document = json.loads(where.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DataError(f"earlier: no such file {where}") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise DataError(f"earlier: {where} is not a readable {file_name} ({type(exc).__name__})") from None
    return earlier_log_posteriors(document, f"earlier: {where}")


def earlier_log_posteriors(document: Mapping[str, object], where: str) -> dict[str, float]:
    """The log posteriors of an earlier diagnosis from its ``gap.json`` document (``log_posterior``), checked.

    Raises
    ------
    DataError
        The document holds no log posteriors (not a diagnosis' ``gap.json``, or one that weighed no model), or a
        value that is not a number below or at 0.
    """
    got = document.get("log_posterior") if isinstance(document, Mapping) else None
    if not isinstance(got, Mapping) or not got:
        raise DataError(f"{where}: no 'log_posterior' — not the gap.json of a diagnosis that weighed its models")
    out: dict[str, float] = {}
    for lab, v in got.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v > 1e-9:
            raise DataError(f"{where}: log_posterior of {lab!r} is {v!r}, not a log probability (a number <= 0)")
        out[str(lab)] = float(v)
    return out
