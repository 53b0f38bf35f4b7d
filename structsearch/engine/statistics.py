"""The covariance kinds: a registry of named estimators (:data:`KINDS`; :data:`COVARIANCE_KINDS` their names in
the order the command line offers them). Each kind has a one-line description, how its covariance is
computed (the functions of :mod:`.sandwich`), its rule for the reference degrees of freedom of t-tests and
intervals, and the reason it gives when it cannot be estimated; :class:`Covariances` computes one on a fit.

``hac-maneuver`` (below) is the default: it is the one estimate that met the calibration goals of
issue 11 on the flight simulator (``structsearch bench --calibration``, results/calibration.md).

``colored`` is the sandwich of the thesis' Eqs. 19 and 22,

    Cov = (F^T F)^-1 (F^T Lambda F) (F^T F)^-1,

with F = [DPhi c, Phi] the model Jacobian w.r.t. all parameters and Lambda the
Toeplitz matrix of the residual autocorrelation. Lambda is block diagonal over
maneuvers (residuals of different maneuvers are independent), and Lambda F is
computed by FFT convolution per maneuver, O(m log m). ``white`` is
s^2 (F^T F)^-1 with s^2 = RSS / (m - p).

The autocorrelation is the biased (1/m) estimate pooled over maneuvers. Using
every lag, as the thesis does, makes the estimate noisy and biased for
intercept-like columns (the sample autocovariances of a residual with zero mean
sum to zero), and truncating it abruptly can make variances negative when the
residuals oscillate (buffet). By default lags are kept up to four times the lag
from which the autocorrelation envelope stays inside the +-2/sqrt(m) white-noise
band, tapered by a Bartlett window (a positive semi-definite estimate).
``max_lag="full"`` reproduces the thesis (every lag, no taper).

``hac`` (Bartlett kernel) and ``hac-qs`` (quadratic-spectral kernel) are
heteroscedasticity- and autocorrelation-consistent sandwiches (Newey-West 1987,
Andrews 1991): the meat is sum_t sum_s w(|t-s|/b) g_t g_s^T over the scores
g_t = F_t r_t of each maneuver (never across a boundary), so noise whose level
changes along a maneuver (buffet growing with flow separation) is weighted where
it occurs, which the stationary Toeplitz estimate cannot do. Both kernels have a
non-negative spectral window, so the estimate is positive semi-definite by
construction. The bandwidth b follows Andrews' (1991) AR(1) plug-in rule on the
standardised score columns; the sums over lags are FFT convolutions per maneuver,
O(p m log m) plus O(p^2 m) for the products.

``hac-maneuver`` is the Bartlett sandwich with the bandwidth of the whole maneuver (b = 1 in the
fixed-b theory of Kiefer & Vogelsang 2002, "heteroskedasticity-autocorrelation robust testing
without truncation"): it needs no bandwidth rule, so it keeps the slow errors that data-driven
bandwidths cut off, and it stays positive semi-definite. Its noise is that of a few effective
observations per maneuver, so its t-tests and intervals use Student's t with G - 1 degrees of
freedom, as for clustered sandwiches (Cameron & Miller 2015), with G the effective number of
maneuvers behind each parameter (:func:`effective_maneuvers`: a deep-stall term that only two
maneuvers inform gets 1 dof, not G - 1); the other kinds use m - p. See :func:`reference_dof`.

``hac-flight`` is ``hac-maneuver`` for a campaign whose maneuvers were flown on recorded flights
(campaign.toml ``flight``): it adds to hac-maneuver's meat, for every two maneuvers i != j of one flight,
S_i S_j^T (S: a maneuver's score sum), the covariance that errors shared by a flight's maneuvers give (its
mass, engine-model and vane-calibration errors), estimated as a flight-clustered sandwich estimates it, and
keeps hac-maneuver's Bartlett sum inside each maneuver. It assumes flights independent of each other; the
between-maneuver sum is not positive semi-definite by construction, and only its positive part is added (its
negative eigenvalues set to 0), so hac-flight is never below hac-maneuver: clipping the whole meat instead, as
two-way clustered sandwiches do (Cameron, Gelbach & Miller 2011), let a few flights' negative products cancel
the maneuvers' own variance (95 % coverage 0.59 with 2 flights and no shared error). It needs at least two
flights (a flight-shared variance is not estimable from one: NaN with that reason). Its t references use the
effective number of flights minus one. Without recorded flights every maneuver is a flight of its own and it is hac-maneuver,
to the bit (:func:`~.sandwich.flight_meat`).

``cluster`` sums the scores of each maneuver and allows any dependence inside it
(a per-maneuver sensor bias, for one); it needs more maneuvers than parameters.
Which estimate is the default is decided by ``structsearch bench --calibration``: ``colored``
under-reports intercept-like parameters (CL0, Cm0: 0.75 of the Monte Carlo spread, 95 % coverage
0.84), the data-driven HAC bandwidths cut the slow errors off (pooled coverage 0.83).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .sandwich import (HAC_KERNELS, _sandwich, andrews_bandwidth, autocovariance,  # noqa: F401  (re-exported)
                       bartlett_maneuver_sums, choose_max_lag, cluster_covariance, cluster_estimable, cluster_meat,
                       colored_covariance, cross_covariance, effective_maneuvers, flight_count, flight_covariance,
                       flight_meat, hac_covariance, hac_meat,
                       inverse_factor, kernel_weights, lag_weights, scaled_condition_number, scaled_factor,
                       scaled_factor_from_qr, shifted_product, toeplitz_product, white_covariance)

# What an estimator returns besides the covariance: the lags of a Toeplitz estimate, the kernel bandwidth
Estimate = tuple[np.ndarray, "int | None", "float | None"]


@dataclass(frozen=True)
class CovarianceKind:
    """One named covariance estimator: what it is, how it is computed, which t reference it implies and
    when it cannot be estimated. ``estimate(jac, residual, boundaries, max_lag, r_inv)`` returns
    (covariance, lags, bandwidth) on the Jacobian's columns."""

    name: str
    description: str
    estimate: Callable[..., Estimate]
    # the estimate has the precision of a few numbers per maneuver: Student's t with (effective maneuvers
    # - 1) degrees of freedom, and the effective maneuvers are computed; m - p otherwise
    per_maneuver: bool = False
    # the sandwich's meat has rank <= G - 1 (maneuver sums): not estimable with fewer than p + 1 maneuvers
    needs_maneuvers: bool = False
    # the groups are the campaign's flights (maneuvers of one flight share errors): ``estimate`` takes each
    # maneuver's flight as a further argument, and the effective groups are flights
    by_flight: bool = False

    def reference_dof(self, n_samples: int, n_params: int, n_maneuvers: float) -> float:
        """Degrees of freedom of the Student-t reference of a t-test or interval with this covariance."""
        if self.per_maneuver:
            return float(max(n_maneuvers - 1.0, 1.0)) if np.isfinite(n_maneuvers) else float("nan")
        return float(max(n_samples - n_params, 1))

    def not_estimable(self, n_maneuvers: int, n_params: int, n_flights: int | None = None) -> str | None:
        """Why this estimate cannot exist for a fit of this size (None when it can)."""
        if self.needs_maneuvers and n_maneuvers <= n_params:
            return (f"the maneuver-clustered covariance needs more maneuvers ({n_maneuvers}) "
                    f"than parameters + 1 ({n_params + 1})")
        if self.by_flight and n_flights is not None and n_flights < 2 and n_maneuvers > 1:
            return f"{self.name} needs maneuvers of at least two flights ({n_flights} recorded)"
        return None


def _colored(jac, residual, boundaries, max_lag, r_inv) -> Estimate:
    cov, lags = colored_covariance(jac, residual, boundaries, max_lag, r_inv)
    return cov, lags, None


def _white(jac, residual, boundaries, max_lag, r_inv) -> Estimate:
    return white_covariance(jac, residual, r_inv), None, None


def _hac(kind: str):
    def estimate(jac, residual, boundaries, max_lag, r_inv) -> Estimate:
        cov, bandwidth = hac_covariance(jac, residual, boundaries, kind, r_inv=r_inv)
        return cov, None, bandwidth
    return estimate


def _cluster(jac, residual, boundaries, max_lag, r_inv) -> Estimate:
    return cluster_covariance(jac, residual, boundaries, r_inv), None, None


def _hac_flight(jac, residual, boundaries, max_lag, r_inv, flights=None) -> Estimate:
    cov, bandwidth = flight_covariance(jac, residual, boundaries, flights, r_inv)
    return cov, None, bandwidth


# The registry, in the order the command line offers the kinds and the calibration runs them.
KINDS: dict[str, CovarianceKind] = {k.name: k for k in (
    CovarianceKind("colored", "Toeplitz-autocorrelation sandwich of stationary residuals (the thesis' Eqs. 19, 22)",
                   _colored),
    CovarianceKind("white", "s^2 (J^T J)^-1: independent residuals of constant variance", _white),
    CovarianceKind("hac", "Bartlett-kernel HAC sandwich, Andrews' plug-in bandwidth", _hac("hac")),
    CovarianceKind("hac-qs", "quadratic-spectral-kernel HAC sandwich, Andrews' plug-in bandwidth", _hac("hac-qs")),
    CovarianceKind("hac-maneuver", "Bartlett HAC sandwich with the whole maneuver as bandwidth (fixed-b)",
                   _hac("hac-maneuver"), per_maneuver=True),
    CovarianceKind("cluster", "maneuver-clustered sandwich (Liang-Zeger, CR1)", _cluster, per_maneuver=True,
                   needs_maneuvers=True),
    CovarianceKind("hac-flight", "hac-maneuver plus the covariance of the maneuvers of one flight (campaign.toml "
                   "flight; hac-maneuver when none is recorded)", _hac_flight, per_maneuver=True, by_flight=True),
)}
COVARIANCE_KINDS = tuple(KINDS)
# kinds whose estimate has the precision of a few numbers per maneuver: t references with few dof
PER_MANEUVER_KINDS = tuple(k.name for k in KINDS.values() if k.per_maneuver)


def covariance_kind(name: str) -> CovarianceKind:
    try:
        return KINDS[name]
    except KeyError:
        raise ValueError(f"covariance must be one of {COVARIANCE_KINDS}, not {name!r}") from None


def reference_dof(kind: str, n_samples: int, n_params: int, n_maneuvers: float) -> float:
    """Degrees of freedom of the Student-t reference for t-tests and intervals with this covariance:
    (effective) maneuvers - 1 for the per-maneuver kinds, m - p otherwise."""
    return covariance_kind(kind).reference_dof(n_samples, n_params, n_maneuvers)


# Chosen by the Monte Carlo calibration on the flight simulator (structsearch bench --calibration).
DEFAULT_COVARIANCE = "hac-maneuver"


@dataclass(frozen=True)
class Covariances:
    """The requested covariance and the white one, on the identifiable parameters (NaN elsewhere)."""

    covariance: np.ndarray
    white: np.ndarray
    max_lag: int | None = None
    bandwidth: float | None = None
    # per parameter, for the per-maneuver kinds (NaN for the others and the non-identifiable ones)
    effective_maneuvers: np.ndarray | None = None
    # inverse_factor of the Jacobian's kept columns (None when none could be formed): an estimator that
    # refines this covariance later (the two-step one) reuses it instead of factorising the m x p Jacobian
    inverse_factor: np.ndarray | None = None
    # a by-flight kind's number of flights (None: another kind, or no flight recorded)
    flights: int | None = None

    @classmethod
    def on(cls, jac: np.ndarray, keep: np.ndarray, residual: np.ndarray, boundaries: np.ndarray, kind: str,
           max_lag=None, factor: tuple[np.ndarray, np.ndarray] | None = None, flights=None) -> "Covariances":
        """Covariances of the parameters selected by ``keep`` (the others held at their estimates);
        ``boundaries``: the maneuvers' ``[0, ..., m]``; ``factor``: :func:`scaled_factor` of ``jac[:, keep]``
        when the caller has it; ``flights``: each maneuver's flight (None: not recorded), read by the kinds
        that group by flight."""
        estimator = covariance_kind(kind)
        p = jac.shape[1]
        full, white = np.full((p, p), np.nan), np.full((p, p), np.nan)
        lags = bandwidth = r_inv = None
        effective = np.full(p, np.nan)
        sub = jac[:, keep]
        if sub.shape[1] and np.all(np.isfinite(sub)) and np.all(np.isfinite(residual)):
            block = np.ix_(keep, keep)
            try:
                r_inv = inverse_factor(sub, factor)
                white[block] = white_covariance(sub, residual, r_inv)
                if kind == "white":  # the same numbers: computed once
                    full[block] = white[block]
                else:
                    full[block], lags, bandwidth = estimator.estimate(
                        sub, residual, boundaries, max_lag, r_inv, **({"flights": flights} if estimator.by_flight
                                                                       else {}))
                if estimator.per_maneuver:
                    effective[keep] = effective_maneuvers(sub, sub * residual[:, None], boundaries, kind,
                                                          bandwidth, r_inv, flights if estimator.by_flight else None)
            except np.linalg.LinAlgError:
                # an exactly singular factor despite the basis choice: report "not estimable" (NaN)
                full[block] = white[block] = np.nan
                r_inv = None
        recorded = estimator.by_flight and flights is not None
        return cls(full, white, lags, bandwidth, effective, r_inv,
                   flight_count(flights, len(boundaries) - 1) if recorded else None)

    def without(self, indices) -> "Covariances":
        """The same estimate with the rows and columns of ``indices`` set to NaN (not estimable)."""
        cov, white = self.covariance.copy(), self.white.copy()
        for m in (cov, white):
            m[indices, :] = np.nan
            m[:, indices] = np.nan
        effective = None if self.effective_maneuvers is None else self.effective_maneuvers.copy()
        if effective is not None:
            effective[indices] = np.nan
        return Covariances(cov, white, self.max_lag, self.bandwidth, effective, self.inverse_factor, self.flights)
