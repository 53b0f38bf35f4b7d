"""Fit a separable problem (SNLS, or OLS when it has no nonlinear parameter) into a FitResult."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.errors import DataError, FitError
from .ols import solved
from .estimates import ParameterEstimates
from .results import FitResult
from .identifiability import covariance_basis, rank_reasons
from .snls import MultistartOutcome, Outcome, SeparableProblem, model_jacobian, multistart, project
from .scores import ManeuverScores, slices_of
from .defaults import SEPARABLE_DEFAULTS, STALL_DEFAULTS
from .statistics import (COVARIANCE_KINDS, Covariances, scaled_condition_number, scaled_factor,
                         scaled_factor_from_qr)


def check_observed(y: np.ndarray, boundaries: np.ndarray, names, source: str, column: str) -> np.ndarray:
    y = np.asarray(y, dtype=float)
    if y.ndim != 1 or len(y) != int(boundaries[-1]):
        raise DataError(f"observations have shape {y.shape}, expected ({int(boundaries[-1])},)",
                        source=source, column=column)
    bad = np.flatnonzero(~np.isfinite(y))
    if bad.size:
        seg = int(np.searchsorted(boundaries, bad[0], side="right") - 1)
        raise DataError(f"value is NaN or infinite (maneuver {names[seg]!r})", source=source,
                        column=column, row=int(bad[0] - boundaries[seg]))
    return y


# Beyond it a regressor's squares and their sums over a campaign overflow, or come close (``exp(1000*alpha)``): no
# physical regressor of a coefficient does, and a fit of such a column is a fit of overflowed numbers.
MAX_REGRESSOR = 1e100


def _check_regressors(problem: SeparableProblem, phi: np.ndarray, boundaries: np.ndarray, segment_names,
                      source: str, at_start: bool) -> None:
    """Raise a DataError naming the first regressor value that is NaN, infinite or beyond MAX_REGRESSOR
    (``at_start``: evaluated at the start of the nonlinear parameters)."""
    bad = np.argwhere(~(np.abs(phi) <= MAX_REGRESSOR))   # NaN fails the comparison too
    if bad.size:
        seg = int(np.searchsorted(boundaries, bad[0][0], side="right") - 1)
        inputs = problem.regressor_inputs(int(bad[0][1]), int(bad[0][0]))
        value = phi[bad[0][0], bad[0][1]]
        what = ("NaN or infinite" if not np.isfinite(value) else
                f"{value:.3g}, beyond {MAX_REGRESSOR:g} (an overflow: its squares would overflow the fit)")
        raise DataError(f"regressor {problem.linear_names[bad[0][1]]!r} is {what}"
                        f"{' at the start' if at_start else ''} (maneuver {segment_names[seg]!r}"
                        f"{'; inputs ' + inputs if inputs else ''})", source=source,
                        row=int(bad[0][0] - boundaries[seg]))


def _optimum(problem: SeparableProblem, solved: Outcome | MultistartOutcome, ev0):
    """The optimum a fit's statistics are computed at, the starts tried, those that reached it, and the regressors
    there: a given optimum (``ev0`` is evaluated at it already) or the best of a multistart."""
    if isinstance(solved, Outcome):
        return solved, 1, 1, ev0
    return solved.best, len(solved.outcomes), solved.n_reached_best, problem.evaluate(solved.best.theta)


@dataclass(frozen=True)
class Solved:
    """Where a fit's statistics are computed: the optimum, the starts tried and those that reached it, the
    regressors there, the projection of Phi (an OLS fit's; None after a nonlinear solve), and the box."""

    outcome: Outcome
    n_starts: int
    reached: int
    evaluation: object
    projection: object
    lower: np.ndarray
    upper: np.ndarray


def solve(problem: SeparableProblem, y: np.ndarray, *, boundaries: np.ndarray, segment_names, start=None,
          lower=None, upper=None, n_starts: int = 1, seed: int = 0, n_jobs: int = 1,
          tol: float = STALL_DEFAULTS.tol, max_nfev: int | None = None, also=(), source: str = "<memory>",
          solution: Outcome | None = None, starts: MultistartOutcome | None = None) -> Solved:
    """The optimum of ``problem`` on ``y`` (:func:`fit_problem` says what each keyword is); the regressors are
    checked at the start first."""
    k = len(problem.nonlinear_names)
    if solution is not None:
        start = solution.theta
    with np.errstate(all="ignore"):
        ev0 = problem.evaluate(np.asarray(start if k else np.zeros(0), float))
    _check_regressors(problem, ev0.phi, boundaries, segment_names, source, at_start=bool(k))
    if k == 0:  # the regressors evaluated and projected once serve the estimate and its statistics
        proj = project(ev0.phi, y)
        return Solved(solved(proj), 1, 1, ev0, proj, np.zeros(0), np.zeros(0))
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    ms = solution if solution is not None else starts if starts is not None else \
        multistart(problem, y, start, lower, upper, n_starts=n_starts, seed=seed, n_jobs=n_jobs, tol=tol,
                   max_nfev=max_nfev, also=also)
    outcome, n_used, reached, ev = _optimum(problem, ms, ev0)
    # the solve's coefficients are Phi^+ y at its theta already: no second projection of Phi
    return Solved(outcome, n_used, reached, ev, None, lower, upper)


def fit_problem(problem: SeparableProblem, y: np.ndarray, *, boundaries: np.ndarray,
                segment_names, start=None, lower=None, upper=None, n_starts: int = 1,
                seed: int = 0, n_jobs: int = 1, covariance: str = SEPARABLE_DEFAULTS.covariance, max_lag=None,
                tol: float = STALL_DEFAULTS.tol, max_nfev: int | None = None, also=(), model: str = "model",
                coefficient: str | None = None, source: str = "<memory>",
                solution: Outcome | None = None, flights=None,
                starts: MultistartOutcome | None = None) -> FitResult:
    """Estimate all parameters and their statistics: :func:`solve`, then :func:`with_statistics`.

    ``solution``, an optimum already found on this problem and these observations (a joint fit's last weight
    iteration), skips the solve: only its statistics are computed. ``starts``, the solves from every start of a
    multistart that ran elsewhere (each start a task of its own), skips the solve too and reports them as the
    multistart it is.

    ``boundaries`` are the maneuver boundaries ``[0, ..., m]``; they delimit the
    residual autocorrelation and the per-maneuver R^2. ``lower``/``upper`` are the box of the nonlinear
    parameters. The models pass their own defaults (:mod:`.defaults`). ``flights``: each maneuver's flight
    (None: not recorded), which the covariance kinds that group by flight read.
    """
    if covariance not in COVARIANCE_KINDS:
        raise FitError(f"covariance must be one of {COVARIANCE_KINDS}, not {covariance!r}")
    y = check_observed(y, boundaries, segment_names, source, coefficient or "y")
    found = solve(problem, y, boundaries=boundaries, segment_names=segment_names, start=start, lower=lower,
                  upper=upper, n_starts=n_starts, seed=seed, n_jobs=n_jobs, tol=tol, max_nfev=max_nfev, also=also,
                  source=source, solution=solution, starts=starts)
    asked = min(n_starts, found.n_starts) if solution is None else found.n_starts
    return with_statistics(problem, y, found, boundaries=boundaries, segment_names=segment_names,
                           covariance=covariance, max_lag=max_lag, flights=flights, model=model,
                           coefficient=coefficient, n_starts_asked=asked)


def with_statistics(problem: SeparableProblem, y: np.ndarray, found: Solved, *, boundaries: np.ndarray,
                    segment_names, covariance: str, max_lag=None, flights=None, model: str = "model",
                    coefficient: str | None = None, n_starts_asked: int = 1) -> FitResult:
    """The fit at ``found``'s optimum with its statistics: the Jacobian's rank and condition, the covariance of
    kind ``covariance`` without the unidentifiable parameters, and the per-maneuver scores."""
    outcome, ev, proj, k = found.outcome, found.evaluation, found.projection, len(problem.nonlinear_names)
    coef = outcome.coef
    jac = model_jacobian(ev, coef, k)
    residual = proj.residual if proj is not None else y - ev.phi @ coef
    extended = problem.extended_residual(outcome.theta, coef, y)
    if extended is not None:
        residual = extended
    names = tuple(problem.nonlinear_names) + tuple(problem.linear_names)
    reasons = dict(problem.identifiability(outcome.theta))
    # one QR of the m x p Jacobian serves the rank test, condition and covariance; an OLS Jacobian is Phi,
    # whose projection factorised it already
    factor = scaled_factor_from_qr(jac, proj.r, proj.columns) if k == 0 and proj.rank == jac.shape[1] \
        else scaled_factor(jac, problem.jacobian_blocks())
    reasons.update(rank_reasons(jac, names, skip=tuple(reasons), factor=factor[0]))
    basis = covariance_basis(jac, names, reasons, k)
    everything = bool(np.all(basis)) and bool(np.all(np.isfinite(jac)))
    estimate = Covariances.on(jac, basis, residual, boundaries, covariance, max_lag,
                              factor=factor if everything else None, flights=flights).without(
        [i for i, n in enumerate(names) if n in reasons])
    segments = ManeuverScores.of(y, residual, slices_of(boundaries))
    estimates = ParameterEstimates(
        nonlinear_names=tuple(problem.nonlinear_names), linear_names=tuple(problem.linear_names),
        values=np.concatenate([outcome.theta, coef]), lower=found.lower, upper=found.upper,
        covariance=estimate.covariance, covariance_kind=covariance, n_samples=int(segments.counts.sum()),
        n_maneuvers=len(segment_names), white_covariance=estimate.white, max_lag=estimate.max_lag,
        bandwidth=estimate.bandwidth, effective_maneuvers=estimate.effective_maneuvers,
        condition_number=scaled_condition_number(jac, factor[0]), unidentifiable=reasons,
        units=dict(problem.units), n_flights=estimate.flights,
        withheld=None if outcome.success else f"the optimizer did not converge: {outcome.message}")
    return FitResult(
        model=model, coefficient=coefficient, estimates=estimates,
        residuals=residual, segment_names=tuple(segment_names),
        segments=segments, total_sst=float(np.sum((y - y.mean()) ** 2)),
        nfev=outcome.nfev, njev=outcome.njev, message=outcome.message, converged=outcome.success,
        n_starts=found.n_starts, n_reached_best=found.reached, start=outcome.start,
        n_starts_asked=n_starts_asked, covariance_basis=basis, jacobian_inverse_factor=estimate.inverse_factor)
