"""The immutable result of a fit; named statistics are derived lazily from stored arrays."""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Mapping

import numpy as np
from scipy import stats

from .scores import ManeuverScores
from .statistics import reference_dof

HIGH_CORRELATION = 0.9
# A parameter closer than this fraction of its bound interval to a bound is "at the bound". The
# trust-region solver stops short of an active bound by ~1e-7..1e-6 of the range (it keeps iterates
# strictly inside), so 1e-5 catches those stops without touching an interior optimum.
AT_BOUND_RTOL = 1e-5


@dataclass(frozen=True, eq=False)
class FitResult:
    """Estimates, covariance and fit statistics of one model on one data set.

    Parameters are ordered nonlinear first, then linear. ``covariance`` is the
    one requested (``covariance_kind``); ``white_covariance`` is always kept for
    comparison.
    """

    model: str
    coefficient: str | None
    nonlinear_names: tuple[str, ...]
    linear_names: tuple[str, ...]
    values: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    covariance: np.ndarray
    white_covariance: np.ndarray
    covariance_kind: str
    max_lag: int | None
    residuals: np.ndarray
    segment_names: tuple[str, ...]
    segments: ManeuverScores
    total_sst: float = float("nan")
    nfev: int = 0
    njev: int = 0
    message: str = ""
    success: bool = True
    n_starts: int = 1
    n_reached_best: int = 1
    start: np.ndarray | None = None
    significance: float = 0.05
    bandwidth: float | None = None   # HAC kernel bandwidth in samples (covariance "hac"/"hac-qs"/"hac-maneuver")
    # per parameter, for the per-maneuver covariances: how many maneuvers its variance rests on
    effective_maneuvers: np.ndarray | None = None
    condition_number: float = float("nan")  # of the column-scaled Jacobian at the solution
    # parameters the data cannot identify at the solution -> why (their covariance rows are NaN)
    unidentifiable: Mapping[str, str] = field(default_factory=dict)
    # what the covariance accounts for beyond this fit (drag/pitch: the lift model's estimation error)
    generated_regressors: str | None = None
    # the parameters the covariance was computed on (identifiability.covariance_basis), and R^-1 of the thin
    # QR of the column-scaled Jacobian on them (scaling folded back in; statistics.inverse_factor): a later
    # covariance estimator on the same Jacobian (the two-step one) reuses both instead of factorising the
    # m x p matrix again. The factor is None when it could not be formed; neither is serialised
    covariance_basis: np.ndarray | None = field(default=None, repr=False)
    jacobian_inverse_factor: np.ndarray | None = field(default=None, repr=False)

    # ----- sizes -------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        return self.nonlinear_names + self.linear_names

    @property
    def n_samples(self) -> int:
        return int(self.segments.counts.sum())

    @property
    def n_params(self) -> int:
        return len(self.values)

    @property
    def dof(self) -> int:
        return self.n_samples - self.n_params

    @cached_property
    def reference_dof(self) -> dict[str, float]:
        """Degrees of freedom of each parameter's t-test and interval: its effective number of maneuvers
        minus 1 for the per-maneuver covariances (``hac-maneuver``, ``cluster``), m - p otherwise."""
        effective = (self.effective_maneuvers if self.effective_maneuvers is not None
                     else np.full(self.n_params, float(len(self.segment_names))))
        return {n: reference_dof(self.covariance_kind, self.n_samples, self.n_params, float(g))
                for n, g in zip(self.names, effective)}

    # ----- estimates ---------------------------------------------------------
    @cached_property
    def params(self) -> dict[str, float]:
        return dict(zip(self.names, map(float, self.values)))

    @cached_property
    def stderr(self) -> dict[str, float]:
        return dict(zip(self.names, map(float, self._stderr)))

    @cached_property
    def _stderr(self) -> np.ndarray:
        return _standard_deviations(self.covariance)

    @cached_property
    def white_stderr(self) -> dict[str, float]:
        return dict(zip(self.names, map(float, _standard_deviations(self.white_covariance))))

    @cached_property
    def not_identifiable(self) -> dict[str, str]:
        """Parameters whose standard deviation cannot be estimated, with the reason (never reported as 0)."""
        out = dict(self.unidentifiable)
        for name, v in zip(self.names, np.diag(self.covariance)):
            if name in out:
                continue
            if not np.isfinite(v) and self.covariance_kind == "cluster" and len(self.segment_names) <= self.n_params:
                out[name] = (f"the maneuver-clustered covariance needs more maneuvers ({len(self.segment_names)}) "
                             f"than parameters + 1 ({self.n_params + 1})")
            elif not np.isfinite(v):
                out[name] = "its variance estimate is not finite: the data cannot identify it"
            elif v <= 0:
                out[name] = (f"its {self.covariance_kind} variance estimate is {'zero' if v == 0 else 'negative'} "
                             f"({v:.3g}): the data cannot identify it")
        return out

    @property
    def identifiable(self) -> bool:
        return not self.not_identifiable

    @cached_property
    def covariance_psd(self) -> bool:
        """Whether the estimated covariance of the identifiable parameters is positive semi-definite.

        Judged on the correlation scale (eigenvalues above -1e-10); an indefinite estimate is
        reported as such, never repaired by clipping.
        """
        finite = np.all(np.isfinite(self.covariance), axis=0)
        block = self.covariance[np.ix_(finite, finite)]
        if block.size == 0:
            return True
        d = np.sqrt(np.abs(np.diag(block)))
        d[d == 0] = 1.0
        return bool(np.linalg.eigvalsh(block / np.outer(d, d)).min() > -1e-10)

    @cached_property
    def correlation(self) -> np.ndarray:
        s = self._stderr
        with np.errstate(divide="ignore", invalid="ignore"):
            corr = self.covariance / np.outer(s, s)  # NaN for a parameter without a standard deviation
        np.fill_diagonal(corr, 1.0)
        return corr

    @cached_property
    def t_values(self) -> dict[str, float]:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = self.values / self._stderr
        return dict(zip(self.names, map(float, t)))

    @cached_property
    def p_values(self) -> dict[str, float]:
        """Two-sided t-test of H0: parameter = 0 with the parameter's ``reference_dof``."""
        t = np.array(list(self.t_values.values()))
        dof = np.array(list(self.reference_dof.values()))
        return dict(zip(self.names, map(float, 2.0 * stats.t.sf(np.abs(t), dof))))

    def confidence_intervals(self, level: float = 0.95) -> dict[str, tuple[float, float]]:
        """estimate -+ t_{dof} quantile x standard deviation (NaN where no standard deviation exists)."""
        half = stats.t.ppf(0.5 + level / 2, np.array(list(self.reference_dof.values()))) * self._stderr
        return {n: (float(v - h), float(v + h)) for n, v, h in zip(self.names, self.values, half)}

    @cached_property
    def significant(self) -> dict[str, bool]:
        return {n: p < self.significance for n, p in self.p_values.items()}

    @cached_property
    def at_bound(self) -> dict[str, str]:
        """Nonlinear parameters that ended on a bound: name -> "lower" or "upper"."""
        flags = {}
        for name, v, lo, hi in zip(self.nonlinear_names, self.values, self.lower, self.upper):
            span = hi - lo if np.isfinite(hi - lo) else max(abs(v), 1.0)
            if np.isfinite(lo) and v - lo <= AT_BOUND_RTOL * span:
                flags[name] = "lower"
            elif np.isfinite(hi) and hi - v <= AT_BOUND_RTOL * span:
                flags[name] = "upper"
        return flags

    @cached_property
    def high_correlations(self) -> list[tuple[str, str, float]]:
        """Pairs with |correlation| above 0.9, strongest first."""
        pairs = []
        c = self.correlation
        for i in range(self.n_params):
            for j in range(i + 1, self.n_params):
                if abs(c[i, j]) > HIGH_CORRELATION:
                    pairs.append((self.names[i], self.names[j], float(c[i, j])))
        return sorted(pairs, key=lambda x: -abs(x[2]))

    # ----- goodness of fit ---------------------------------------------------
    @property
    def rss(self) -> float:
        return float(self.segments.sse.sum())

    @property
    def mse(self) -> float:
        return self.rss / self.n_samples

    @property
    def rmse(self) -> float:
        return float(np.sqrt(self.mse))

    @property
    def r2(self) -> float:
        """R^2 over all samples, about the overall mean (Eq. 24)."""
        return float(1.0 - self.rss / self.total_sst) if self.total_sst > 0 else float("nan")

    @cached_property
    def r2_segments(self) -> np.ndarray:
        return self.segments.r2

    @cached_property
    def r2_summary(self) -> dict[str, float]:
        return self.segments.r2_summary().as_dict()

    @cached_property
    def mse_segments(self) -> dict[str, float]:
        return dict(zip(self.segment_names, map(float, self.segments.mse)))

    @cached_property
    def aic(self) -> float:
        return float(self.n_samples * np.log(self.mse) + 2 * self.n_params)

    @cached_property
    def bic(self) -> float:
        return float(self.n_samples * np.log(self.mse) + self.n_params * np.log(self.n_samples))

    # ----- serialisation -----------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready dict (no arrays of samples)."""
        return {
            "model": self.model,
            "coefficient": self.coefficient,
            "params": self.params,
            "stderr": self.stderr,
            "white_stderr": self.white_stderr,
            "t_values": self.t_values,
            "p_values": self.p_values,
            "nonlinear": list(self.nonlinear_names),
            "linear": list(self.linear_names),
            "bounds": {n: [float(lo), float(hi)] for n, lo, hi in
                       zip(self.nonlinear_names, self.lower, self.upper)},
            "at_bound": self.at_bound,
            "high_correlations": [list(p) for p in self.high_correlations],
            "correlation": {"names": list(self.names), "matrix": self.correlation.tolist()},
            "covariance": self.covariance_kind,
            "reference_dof": self.reference_dof,
            "generated_regressors": self.generated_regressors,
            "max_lag": self.max_lag,
            "bandwidth": self.bandwidth,
            "condition_number": self.condition_number,
            "identifiable": self.identifiable,
            "covariance_psd": self.covariance_psd,
            "not_identifiable": self.not_identifiable,
            "rss": self.rss,
            "mse": self.mse,
            "r2": self.r2,
            "r2_maneuvers": self.r2_summary,
            "mse_maneuvers": self.mse_segments,
            "n_samples": self.n_samples,
            "n_params": self.n_params,
            "aic": self.aic,
            "bic": self.bic,
            "optimizer": {"nfev": self.nfev, "njev": self.njev, "message": self.message,
                          "success": self.success, "n_starts": self.n_starts,
                          "n_reached_best": self.n_reached_best},
        }


def _standard_deviations(covariance: np.ndarray) -> np.ndarray:
    """sqrt of the diagonal; NaN where a variance is zero, negative or not finite (never clipped to 0)."""
    v = np.diag(covariance)
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(v) & (v > 0), np.sqrt(np.abs(v)), np.nan)
