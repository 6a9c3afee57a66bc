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
``"none"``).  :func:`laplace_log_evidence` is checked against importance sampling on a small case in the tests.
"""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from .fitting import Fit, GapProblem

__all__ = ["FLAT_EIGENVALUE", "laplace_log_evidence", "posterior_probabilities", "prior_log_normaliser"]

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


def laplace_log_evidence(problem: GapProblem, fit: Fit) -> float:
    """The Laplace approximation of ``ln Z`` at a fit (baseline or refit; module docstring)."""
    J = np.asarray(fit.jac, dtype=float)
    d = J.shape[1] if J.ndim == 2 else 0
    if d == 0:
        return -0.5 * float(fit.rss) + prior_log_normaliser(problem)
    lam = np.linalg.eigvalsh(J.T @ J)
    log_det = float(np.sum(np.log(np.maximum(lam, FLAT_EIGENVALUE))))
    return -0.5 * float(fit.rss) + prior_log_normaliser(problem) + 0.5 * d * math.log(2.0 * math.pi) - 0.5 * log_det


def posterior_probabilities(problem: GapProblem, baseline: Fit, refits: Mapping[str, Fit]) -> dict[str, float]:
    """Posterior probability of the baseline (``"none"``) and of each refitted candidate (equal prior
    probabilities), from :func:`laplace_log_evidence`; ordered from the most probable."""
    logz = {"none": laplace_log_evidence(problem, baseline)}
    logz |= {lab: laplace_log_evidence(problem, fit) for lab, fit in refits.items()}
    top = max(logz.values())
    w = {lab: math.exp(v - top) for lab, v in logz.items()}
    total = sum(w.values())
    return dict(sorted(((lab, v / total) for lab, v in w.items()), key=lambda kv: -kv[1]))
