"""Pointwise confidence and prediction bands of a fitted model's output (the delta method).

For an output f(p) at points x_1..x_n with Jacobian J = df/dp (n x k) at the estimate and the parameter
covariance C, the variance of the estimated output is diag(J C J^T) (computed row by row, never an n x n
matrix). A *confidence* band covers the true output f(p_true); a *prediction* band covers a new
measurement, so it adds the residual noise variance at each point:

    confidence: f +- q * sqrt(diag(J C J^T))
    prediction: f +- q * sqrt(diag(J C J^T) + s^2(x))

with q the two-sided t quantile of ``level`` at the reference degrees of freedom (the normal quantile when
they are infinite). A point whose variance cannot be estimated (a parameter the data cannot identify acts
on it) gets NaN bounds, never a zero-width band.

With a per-maneuver covariance (``hac-maneuver``, ``cluster``) each point has its own degrees of freedom:
its effective number of maneuvers minus one (:func:`point_effective_maneuvers`, the parameters' rule applied
to the combination J_i p the point is). A point in attached flow rests on every maneuver; one deep in the
stall on the few that reach it; the fewest of the parameters' own (a deep-stall parameter's ~1) would make
every point's quantile that of the worst parameter.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from .sandwich import inverse_factor, maneuver_shares, satterthwaite


@dataclass(frozen=True)
class Band:
    """One output's band: the estimate and its lower and upper bounds for confidence and prediction."""

    estimate: np.ndarray
    confidence_low: np.ndarray
    confidence_high: np.ndarray
    prediction_low: np.ndarray
    prediction_high: np.ndarray
    level: float
    dof: np.ndarray                  # of each point's quantile (inf: normal)

    @property
    def confidence_half_width(self) -> np.ndarray:
        """Half the confidence band's width at each point."""
        return 0.5 * (self.confidence_high - self.confidence_low)

    def to_dict(self) -> dict:
        return {"estimate": self.estimate.tolist(), "confidence_low": self.confidence_low.tolist(),
                "confidence_high": self.confidence_high.tolist(), "prediction_low": self.prediction_low.tolist(),
                "prediction_high": self.prediction_high.tolist()}


def output_variance(jacobian: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """diag(J C J^T), row by row; NaN where a parameter with a non-finite covariance acts (J != 0)."""
    jacobian = np.asarray(jacobian, float)
    covariance = np.asarray(covariance, float)
    finite = np.isfinite(np.diag(covariance))   # a parameter that cannot be estimated: NaN row and column
    sub = covariance[np.ix_(finite, finite)]
    j = jacobian[:, finite]
    var = np.einsum("ij,jk,ik->i", j, sub, j)
    unknown = np.any(jacobian[:, ~finite] != 0.0, axis=1) if (~finite).any() else np.zeros(len(var), bool)
    var = np.where(unknown, np.nan, np.maximum(var, 0.0))
    return var


def quantile(level: float, dof) -> np.ndarray:
    """The two-sided t quantile of ``level`` at ``dof`` (each point's; inf: the normal one; NaN: NaN)."""
    if not 0.0 < level < 1.0:
        raise ValueError(f"a band's level is in (0, 1), not {level}")
    tail = 0.5 + level / 2.0
    dof = np.asarray(dof, float)
    # NaN dof (no maneuver's share could be computed): NaN, never a quantile the data do not support
    return np.where(np.isinf(dof), stats.norm.ppf(tail), stats.t.ppf(tail, np.maximum(dof, 1.0)))


def band(estimate: np.ndarray, jacobian: np.ndarray, covariance: np.ndarray, noise_variance: np.ndarray,
         level: float = 0.95, dof=float("inf")) -> Band:
    """Confidence and prediction bands of ``estimate`` (module docstring); ``noise_variance`` and ``dof`` per
    point (or one for all)."""
    estimate = np.asarray(estimate, float)
    dof = np.broadcast_to(np.asarray(dof, float), estimate.shape).copy()
    q = quantile(level, dof)
    var = output_variance(jacobian, covariance)
    half_c = q * np.sqrt(var)
    half_p = q * np.sqrt(var + np.asarray(noise_variance, float))
    return Band(estimate, estimate - half_c, estimate + half_c, estimate - half_p, estimate + half_p, level, dof)


def maneuver_meats(jac: np.ndarray, residual: np.ndarray, boundaries: np.ndarray, kind: str,
                   bandwidth: float | None = None, flights=None) -> np.ndarray:
    """Each maneuver's share of the sandwich's meat in the influence space, (G, k, k): S_g such that the
    per-maneuver covariance of g^T p is sum_g g^T S_g g (before the small-sample factor). ``jac`` is the model
    Jacobian on the fitted samples and ``residual`` the fit's residual there. ``hac-flight``: each flight's share
    (``flights``: each maneuver's flight)."""
    r_inv = inverse_factor(jac)
    u = (jac * residual[:, None]) @ (r_inv @ r_inv.T)          # (m, k): each sample's influence
    return maneuver_shares(u, boundaries, kind, bandwidth, diagonal=False, flights=flights)


def point_effective_maneuvers(jac: np.ndarray, residual: np.ndarray, boundaries: np.ndarray, kind: str,
                              gradients: np.ndarray, bandwidth: float | None = None, flights=None) -> np.ndarray:
    """Effective number of maneuvers behind the variance of each combination g^T p (rows of ``gradients``,
    in the columns of ``jac``): Satterthwaite's rule on c_g = g^T S_g g, maneuver g's share of the sandwich
    variance of g^T p (:func:`maneuver_meats`), as :func:`structsearch.engine.sandwich.effective_maneuvers`
    does for a parameter. ``hac-flight``: the effective number of flights (a flight's share, not positive
    semi-definite by construction, is clipped at 0)."""
    g = np.asarray(gradients, float)
    meats = maneuver_meats(jac, residual, boundaries, kind, bandwidth, flights)
    shares = np.einsum("pk,gkl,pl->gp", g, meats, g)
    return satterthwaite(np.clip(shares, 0.0, None) if kind == "hac-flight" else shares)


def parameter_draws(values: np.ndarray, covariance: np.ndarray, n_draws: int, seed: int) -> np.ndarray:
    """``n_draws`` parameter vectors from the normal distribution of the estimate (``values``, ``covariance``),
    (n_draws, k): the cross-check of the delta method by parameter sampling. A parameter whose variance cannot be
    estimated (NaN) is held at its estimate (a band it acts on is null by :func:`output_variance`; a sampled one
    must say so too). The covariance's rounding-level negative eigenvalues are clipped to zero."""
    values = np.asarray(values, float)
    covariance = np.asarray(covariance, float)
    if n_draws < 2:
        raise ValueError(f"parameter sampling needs at least 2 draws, not {n_draws}")
    finite = np.isfinite(np.diag(covariance))
    sub = covariance[np.ix_(finite, finite)]
    w, v = np.linalg.eigh(0.5 * (sub + sub.T)) if sub.size else (np.zeros(0), np.zeros((0, 0)))
    root = v * np.sqrt(np.maximum(w, 0.0))
    z = np.random.default_rng(seed).standard_normal((n_draws, int(finite.sum())))
    draws = np.tile(values, (n_draws, 1))
    draws[:, finite] += z @ root.T
    return draws


def sampled_limits(samples: np.ndarray, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """The pointwise equal-tailed ``level`` interval of sampled outputs (draws x points); NaN where a draw is
    not finite (a diverged replay, say)."""
    samples = np.asarray(samples, float)
    tail = 100.0 * (0.5 - level / 2.0)
    low, high = np.percentile(samples, [tail, 100.0 - tail], axis=0)
    bad = ~np.all(np.isfinite(samples), axis=0)
    return np.where(bad, np.nan, low), np.where(bad, np.nan, high)
