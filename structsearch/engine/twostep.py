"""Covariance of a second-step fit whose regressors come from a first-step fit (generated regressors).

Drag and pitch models take their separation states and C_L from the fitted lift
model, so their estimates inherit the lift model's estimation error. Linearising
both least-squares problems about the truth (Murphy & Topel 1985; Newey &
McFadden 1994, section 6) gives

    beta2_hat - beta2 ~ H2^-1 sum_t u_t,   u_t = F2_t e2_t - K F1_t e1_t,
    K = F2^T G21 H1^-1,

with F1, F2 the model Jacobians of the two steps, H = F^T F, e the residuals and
G21 = d f2 / d beta1 the sensitivity of the second model's output to the
first model's parameters. The correction term therefore enters as an extra score
series, and every covariance kind estimates the variance of sum_t u_t the way it
estimates its one-step meat:

- ``hac``/``hac-qs``: the kernel estimate on the corrected scores u_t;
- ``colored``: the stationary version, with the Bartlett-tapered auto- and
  cross-covariances of (e1, e2) (the lift and drag residuals of one maneuver are
  correlated: buffet moves both);
- ``white``: the same with only lag 0 (homoscedastic, serially independent);
- ``cluster``: the sums of u_t per maneuver;
- ``hac-flight``: hac-maneuver's estimate plus the products of the maneuvers' sums of u_t within a flight.

Everything is conditional on the measured inputs (alpha, q, V, de, ...) being
exact; the lift model's own covariance is unaffected.
"""
from __future__ import annotations

import numpy as np

from .statistics import (HAC_KERNELS, PER_MANEUVER_KINDS, inverse_factor, _sandwich, autocovariance, choose_max_lag,
                         cluster_estimable, cluster_meat, cross_covariance, effective_maneuvers, flight_meat, hac_meat,
                         lag_weights,
                         shifted_product, toeplitz_product)


def generated_regressor_covariance(jac2: np.ndarray, residual2: np.ndarray, jac1: np.ndarray,
                                   residual1: np.ndarray, sensitivity: np.ndarray, boundaries: np.ndarray,
                                   kind: str, max_lag=None, a1_inv: np.ndarray | None = None,
                                   r2_inv: np.ndarray | None = None, flights=None):
    """Covariance of the second-step parameters including the first step's estimation error.

    ``jac1`` (m x p1) and ``jac2`` (m x p2) are the model Jacobians on the identifiable parameters of
    each step, ``sensitivity`` (m x p1) is d f2 / d beta1 on the same first-step parameters. Returns
    (covariance, lags, bandwidth, effective maneuvers per parameter) like the one-step estimators; the
    effective maneuvers (of the corrected scores) are NaN except for the per-maneuver kinds. ``a1_inv``:
    the first step's inverse factor (``statistics.inverse_factor(jac1)``) when the caller has it; ``r2_inv``
    the second step's (:attr:`FitResult.jacobian_inverse_factor` of its fit); ``flights``: each maneuver's
    flight, for ``hac-flight``.
    """
    m, p2 = jac2.shape
    a1_inv = inverse_factor(jac1) if a1_inv is None else a1_inv
    r2_inv = inverse_factor(jac2) if r2_inv is None else r2_inv
    gain = (jac2.T @ sensitivity) @ (a1_inv @ a1_inv.T)        # K, p2 x p1
    carry = -(jac1 @ gain.T)                                    # multiplies e1 in u_t
    lags = bandwidth = None
    scores = jac2 * residual2[:, None] + carry * residual1[:, None]   # u_t
    if kind in SCORE_KINDS:
        return _from_scores(jac2, scores, boundaries, kind, r2_inv, flights)
    if kind == "white":
        s22 = float(residual2 @ residual2) / max(m - p2, 1)
        s11 = float(residual1 @ residual1) / max(m - jac1.shape[1], 1)
        s12 = float(residual1 @ residual2) / m
        cross = jac2.T @ carry
        meat = s22 * (jac2.T @ jac2) + s11 * (carry.T @ carry) + s12 * (cross + cross.T)
    elif kind == "colored":
        lags = max(choose_max_lag(residual2, boundaries, max_lag), choose_max_lag(residual1, boundaries, max_lag))
        taper = lag_weights(lags, max_lag)
        two_sided = np.concatenate([taper[:0:-1], taper])
        lam22 = autocovariance(residual2, boundaries, lags) * taper
        lam11 = autocovariance(residual1, boundaries, lags) * taper
        gamma12 = cross_covariance(residual1, residual2, boundaries, lags) * two_sided  # E e1(t) e2(t+k)
        # sum_ts A_t' E[e_a(t) e_b(s)] B_s for (a, b) in {2, 1}^2; gamma21(k) = gamma12(-k)
        meat = (jac2.T @ toeplitz_product(jac2, lam22, boundaries)
                + carry.T @ toeplitz_product(carry, lam11, boundaries)
                + carry.T @ shifted_product(jac2, gamma12, boundaries)
                + jac2.T @ shifted_product(carry, gamma12[::-1], boundaries))
    else:
        raise ValueError(f"unknown covariance kind {kind!r}")
    return _sandwich(jac2, meat, r2_inv), lags, bandwidth, np.full(p2, np.nan)


# the kinds that estimate the variance of sum_t u_t from the corrected scores alone (not from residual series)
SCORE_KINDS = (*HAC_KERNELS, "cluster", "hac-flight")


def _from_scores(jac2: np.ndarray, scores: np.ndarray, boundaries: np.ndarray, kind: str, r2_inv: np.ndarray,
                 flights=None):
    m, p2 = jac2.shape
    bandwidth = None
    if kind == "hac-flight":
        meat, bandwidth = flight_meat(scores, boundaries, flights)
        meat *= m / max(m - p2, 1)
    elif kind in HAC_KERNELS:
        meat, bandwidth = hac_meat(scores, boundaries, kind)
        meat *= m / max(m - p2, 1)
    else:
        if not cluster_estimable(boundaries, p2):
            return np.full((p2, p2), np.nan), None, bandwidth, np.full(p2, np.nan)
        meat = cluster_meat(scores, boundaries) * ((m - 1) / max(m - p2, 1))
    effective = (effective_maneuvers(jac2, scores, boundaries, kind, bandwidth, r2_inv, flights)
                 if kind in PER_MANEUVER_KINDS else np.full(p2, np.nan))
    return _sandwich(jac2, meat, r2_inv), None, bandwidth, effective


def influence_covariance(jac2: np.ndarray, residual2: np.ndarray, influence1: np.ndarray, sensitivity: np.ndarray,
                         boundaries: np.ndarray, kind: str, r2_inv: np.ndarray | None = None, flights=None):
    """The same covariance when the first step is given by its influence series: ``influence1`` (m x p1) holds,
    per sample t, that sample's share of beta1_hat - beta1 (H1^-1 times the first step's scores, summed over
    every row of sample t). A first step that is not one least-squares problem on the same samples (a joint
    fit of C_L, C_D and C_m: three rows per sample, weighted) enters this way; then u_t = F2_t e2_t -
    F2^T G21 psi_t. Only the kinds that work on the scores alone are available (``SCORE_KINDS``): ``white``
    and ``colored`` model the two residual series, which a joint first step does not have."""
    if kind not in SCORE_KINDS:
        raise ValueError(f"the {kind!r} covariance needs the first step's residual series; with a first step "
                         f"given by its influence use one of {', '.join(SCORE_KINDS)}")
    r2_inv = inverse_factor(jac2) if r2_inv is None else r2_inv
    scores = jac2 * residual2[:, None] - influence1 @ (jac2.T @ sensitivity).T
    return _from_scores(jac2, scores, boundaries, kind, r2_inv, flights)


def influence_series(jac1: np.ndarray, residual1: np.ndarray, a1_inv: np.ndarray | None = None,
                     rows_per_sample: int = 1) -> np.ndarray:
    """Per sample, its share of a least-squares estimate's error: psi_t = H1^-1 sum_r F1_r e1_r over the rows r of
    sample t (``rows_per_sample`` consecutive rows each: a joint problem interleaves its blocks sample by sample),
    m x p1. ``a1_inv``: the first step's inverse factor when the caller has it (H1^-1 = a1_inv a1_inv^T)."""
    a1_inv = inverse_factor(jac1) if a1_inv is None else a1_inv
    scores = jac1 * residual1[:, None]
    if rows_per_sample > 1:
        scores = scores.reshape(-1, rows_per_sample, scores.shape[1]).sum(axis=1)
    return (scores @ a1_inv) @ a1_inv.T
