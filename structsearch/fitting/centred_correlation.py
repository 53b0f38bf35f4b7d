"""Correlation of a fit's estimates with the data columns centred that can be centred.

A correlation that moving a column's datum removes (Marquardt 1980: "non-essential
ill-conditioning") says nothing about what the data can separate: x_cg in ``C_L`` and
``x_cg/cbar*C_L`` is one (the thesis' C_m,K0 / C_m,cg pair, -1.00 in its Table 16). Admissibility
judges correlations on this matrix; the fit computes it once, with its covariance.
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import qr, solve_triangular

from ..engine.regressors import symbol_names
from .candidates import Candidate

# Centring a column keeps the model when the centred regressors span the same space (to this
# relative residual); only such centrings are applied.
SAME_SPAN_RTOL = 1e-8


def _centred(data, names):
    columns = dict(data.columns)
    for n in names:
        columns[n] = columns[n] - float(np.mean(columns[n]))
    return data.with_columns(columns)


def _basis_change(phi: np.ndarray, q: np.ndarray, r: np.ndarray, phi_c: np.ndarray) -> np.ndarray | None:
    """M with phi_c = phi M when the two span the same space, else None; phi = q r (thin QR, r invertible).
    Only the columns centring changed are projected: the others are phi's own (M's identity columns)."""
    change = np.eye(phi.shape[1])
    moved = [j for j in range(phi.shape[1]) if not np.array_equal(phi[:, j], phi_c[:, j])]
    if not moved:
        return change
    columns = phi_c[:, moved]
    projected = q.T @ columns
    miss = np.linalg.norm(columns - q @ projected)
    if not miss <= SAME_SPAN_RTOL * max(np.linalg.norm(columns), np.finfo(float).tiny):
        return None
    change[:, moved] = solve_triangular(r, projected, check_finite=False)
    return change


def centred_correlation(candidate: Candidate, model, data, fit) -> np.ndarray | None:
    """Correlation matrix of ``fit``'s estimates with every data column of the regressors centred whose
    centring keeps the model (None when no column can be centred or the covariance is incomplete).

    The linear coefficients of the centred model are M^-1 beta for phi_centred = phi M, so their
    covariance is T Cov T^T with T = diag(I, M^-1); nonlinear parameters are unchanged."""
    if not np.all(np.isfinite(fit.covariance)):
        return None
    k = len(fit.nonlinear_names)
    theta = np.asarray(fit.values[:k], float)
    problem = model.bind(data)
    phi = problem.regression_matrix(theta)
    q, r = qr(phi, mode="economic", check_finite=False)
    # |r_jj| is column j's distance from the span of the columns before it: relative to its own norm, a
    # test of dependence that columns of very different sizes do not fool
    if np.any(np.abs(np.diag(r)) <= SAME_SPAN_RTOL * np.linalg.norm(phi, axis=0)):
        return None  # dependent regressors: no basis change is defined

    def centred_phi(names):
        # the states are computed once unless a state input (alpha, alpha_dot, t) is centred
        if set(model.state_inputs) & set(names):
            return model.bind(_centred(data, names)).regression_matrix(theta)
        return problem.regression_matrix(theta, _centred(data, names), changed=(phi, set(names)))

    used = {n for _, text in candidate.regressors for n in symbol_names(text)} & set(data.columns)
    movable = [n for n in sorted(used)
               if np.ptp(data[n]) > 0 and _basis_change(phi, q, r, centred_phi([n])) is not None]
    if not movable:
        return None
    change = _basis_change(phi, q, r, centred_phi(movable))
    if change is None:
        return None
    try:
        inverse = np.linalg.inv(change)
    except np.linalg.LinAlgError:
        return None
    t = np.eye(len(fit.values))
    t[k:, k:] = inverse
    cov = t @ fit.covariance @ t.T
    with np.errstate(invalid="ignore"):   # a negative variance: NaN, judged as not estimable below
        sd = np.sqrt(np.diag(cov))
    with np.errstate(divide="ignore", invalid="ignore"):
        return cov / np.outer(sd, sd)
