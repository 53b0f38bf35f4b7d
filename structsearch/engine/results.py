"""The immutable result of a fit: the parameters' estimates and statistics (:class:`ParameterEstimates`,
``result.estimates``), the residuals and the optimizer's account. Every statistic of the estimates is
reachable on the result under the same name (``result.params``, ``result.stderr``, ``result.p_values``,
``result.cov_params()``, ...)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from .estimates import AT_BOUND_RTOL, HIGH_CORRELATION, ParameterEstimates, WaldTest  # noqa: F401  (re-exported)
from .scores import ManeuverScores

if TYPE_CHECKING:
    import pandas

    from .equations import Equations
    from .summary import FitSummary

_ESTIMATE_FIELDS = frozenset(f.name for f in dataclasses.fields(ParameterEstimates))


def starts_line(reached: int, used: int, asked: int | None) -> str:
    """How many starts reached the best cost, of those solved; the warm starts a fit adds to those asked for
    named, so that ``starts=1`` reading "3 of 3" says where the other two came from."""
    if asked is None or used <= asked:
        return f"{reached} of {used}"
    more = used - asked
    return (f"{reached} of {used} ({asked} asked for and {more} the fit adds: the declared start, a fitted "
            "stage's or contained structure's estimates)")


def _delegate(name: str):
    def get(self):
        return getattr(self.estimates, name)
    get.__name__ = name
    get.__doc__ = f"``estimates.{name}`` (:class:`~structsearch.engine.estimates.ParameterEstimates`)."
    return property(get)


@dataclass(frozen=True, eq=False, init=False)
class FitResult:
    """Estimates, covariance and fit statistics of one model on one data set.

    Parameters are ordered nonlinear first, then linear. ``estimates`` holds them with their covariance
    (the one requested, ``covariance_kind``; the white one is kept for comparison). A copy with other
    estimates is ``dataclasses.replace(result, covariance=..., covariance_kind=...)``: any field of
    :class:`ParameterEstimates` may be given and replaces that of ``estimates``.
    """

    model: str
    coefficient: str | None
    estimates: ParameterEstimates
    residuals: np.ndarray
    segment_names: tuple[str, ...]
    segments: ManeuverScores
    total_sst: float
    nfev: int
    njev: int
    message: str
    converged: bool                   # the optimizer's own verdict on the best start
    n_starts: int
    n_reached_best: int
    start: np.ndarray | None
    # the starts the caller asked for (``n_starts`` of the fit); the rest of n_starts are warm starts the fit
    # adds (a stage's or donor's estimates, the declared start after them, a contained structure's optimum)
    n_starts_asked: int | None
    # the parameters the covariance was computed on (identifiability.covariance_basis), and R^-1 of the thin
    # QR of the column-scaled Jacobian on them (scaling folded back in; statistics.inverse_factor): a later
    # covariance estimator on the same Jacobian (the two-step one) reuses both instead of factorising the
    # m x p matrix again. The factor is None when it could not be formed; neither is serialised
    covariance_basis: np.ndarray | None
    jacobian_inverse_factor: np.ndarray | None
    # the model as equations (what summary() opens with); None: a problem fitted without a declared model
    equations: Equations | None

    def __init__(self, model: str, coefficient: str | None, estimates: ParameterEstimates, residuals: np.ndarray,
                 segment_names: Sequence[str], segments: ManeuverScores, total_sst: float = float("nan"),
                 nfev: int = 0, njev: int = 0, message: str = "", converged: bool = True, n_starts: int = 1,
                 n_reached_best: int = 1, start: np.ndarray | None = None, n_starts_asked: int | None = None,
                 covariance_basis: np.ndarray | None = None, jacobian_inverse_factor: np.ndarray | None = None,
                 equations: Equations | None = None, **estimate_changes: Any):
        unknown = set(estimate_changes) - _ESTIMATE_FIELDS
        if unknown:
            raise TypeError(f"FitResult() got an unexpected keyword argument {sorted(unknown)[0]!r}")
        if estimate_changes:
            estimates = dataclasses.replace(estimates, **estimate_changes)
        for name, value in (("model", model), ("coefficient", coefficient), ("estimates", estimates),
                            ("residuals", residuals), ("segment_names", tuple(segment_names)),
                            ("segments", segments), ("total_sst", total_sst), ("nfev", nfev), ("njev", njev),
                            ("message", message), ("converged", converged), ("n_starts", n_starts),
                            ("n_reached_best", n_reached_best), ("start", start),
                            ("n_starts_asked", n_starts_asked),
                            ("covariance_basis", covariance_basis),
                            ("jacobian_inverse_factor", jacobian_inverse_factor), ("equations", equations)):
            object.__setattr__(self, name, value)

    @property
    def success(self) -> bool:
        """The name scipy gives :attr:`converged` (and ``to_dict()["optimizer"]["success"]``)."""
        return self.converged

    # ----- the estimates (ParameterEstimates) ----------------------------------
    nonlinear_names = _delegate("nonlinear_names")
    linear_names = _delegate("linear_names")
    names = _delegate("names")
    values = _delegate("values")
    lower = _delegate("lower")
    upper = _delegate("upper")
    covariance = _delegate("covariance")
    white_covariance = _delegate("white_covariance")
    covariance_kind = _delegate("covariance_kind")
    max_lag = _delegate("max_lag")
    bandwidth = _delegate("bandwidth")
    effective_maneuvers = _delegate("effective_maneuvers")
    significance = _delegate("significance")
    unidentifiable = _delegate("unidentifiable")
    condition_number = _delegate("condition_number")
    generated_regressors = _delegate("generated_regressors")
    units = _delegate("units")
    withheld = _delegate("withheld")
    n_params = _delegate("n_params")
    params = _delegate("params")
    stderr = _delegate("stderr")
    white_stderr = _delegate("white_stderr")
    t_values = _delegate("t_values")
    p_values = _delegate("p_values")
    reference_dof = _delegate("reference_dof")
    correlation = _delegate("correlation")
    at_bound = _delegate("at_bound")
    high_correlations = _delegate("high_correlations")
    not_identifiable = _delegate("not_identifiable")
    identifiable = _delegate("identifiable")
    covariance_psd = _delegate("covariance_psd")
    significant = _delegate("significant")

    def cov_params(self) -> "pandas.DataFrame":
        return self.estimates.cov_params()

    def conf_int(self, level: float = 0.95) -> "pandas.DataFrame":
        return self.estimates.conf_int(level)

    def wald_test(self, names: Sequence[str]) -> WaldTest:
        return self.estimates.wald_test(names)

    # ----- sizes -------------------------------------------------------------
    @property
    def n_samples(self) -> int:
        return int(self.segments.counts.sum())

    @property
    def dof(self) -> int:
        return self.n_samples - self.n_params

    # ----- goodness of fit ---------------------------------------------------
    @property
    def rss(self) -> float:
        return float(self.segments.sse.sum())

    @property
    def mse(self) -> float:
        return self.rss / self.n_samples

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

    # ----- presentation and serialisation --------------------------------------
    def summary(self) -> "FitSummary":
        """Goodness of fit, parameters with tests and flags, strong correlations (text, Markdown, HTML, LaTeX)."""
        from .summary import FitSummary, covariance_head, covariance_line
        r2 = self.r2_summary
        head = (
            ("model", self.model),
            ("coefficient", self.coefficient or "-"),
            ("samples / maneuvers", f"{self.n_samples} / {len(self.segment_names)}"),
            ("parameters (nonlinear + linear)", f"{len(self.nonlinear_names)} + {len(self.linear_names)}"),
            ("RSS", f"{self.rss:.6g}"),
            ("MSE", f"{self.mse:.6g}"),
            ("R^2 (all samples)", f"{self.r2:.6f}"),
            ("R^2 per maneuver mean / min / max", f"{r2['mean']:.4f} / {r2['min']:.4f} / {r2['max']:.4f}"),
            ("covariance", covariance_line(self.covariance_kind, self.max_lag, self.bandwidth)),
            ("optimizer", f"{'converged' if self.converged else 'NOT CONVERGED'}: {self.message} "
                          f"({self.nfev} evaluations)"),
            ("starts reaching the best cost", starts_line(self.n_reached_best, self.n_starts, self.n_starts_asked)),
            *covariance_head(self.estimates),
        )
        return FitSummary(self.estimates, head, self.equations)

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
            "units": dict(self.units),
            "generated_regressors": self.generated_regressors,
            "max_lag": self.max_lag,
            "bandwidth": self.bandwidth,
            "condition_number": self.condition_number,
            "identifiable": self.identifiable,
            "covariance_psd": self.covariance_psd,
            "not_identifiable": self.not_identifiable,
            "statistics_withheld": self.withheld,
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
                          "success": self.converged, "n_starts": self.n_starts,
                          "n_reached_best": self.n_reached_best},
        }
