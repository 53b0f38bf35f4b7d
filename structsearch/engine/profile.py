"""Profile intervals of a separable fit's nonlinear parameters, on a statistic that respects the covariance.

For a nonlinear parameter theta_j the *profile* is S(theta_j), the least residual sum of squares with theta_j
held at a value and every other parameter refitted: the other nonlinear ones by the variable-projection solve
(warm-started from the nearest value already profiled), the linear ones by projection. lmfit's
``conf_interval`` is the model: the parameter is stepped away from its estimate on each side until the
profile statistic crosses the level's critical value, and the crossing is found by a root finder (here:
secant steps aimed just past the crossing until it is bracketed, then ``brentq`` on the refitted profile).

The statistic. lmfit compares (S(theta_j) - S_min) / sigma^2 with an F (or chi^2) quantile: a likelihood
ratio for independent residuals of one variance. Flight-test residuals are coloured and heteroscedastic, so
that statistic's curvature at the estimate is that of the *white* covariance sigma^2 (J^T J)^-1, and its
intervals are as narrow as the white ones (whose standard deviations are 0.12-0.21 of the Monte Carlo spread of
CL-VI's separation parameters on the held-out campaigns, results/calibration.md). The statistic used here is
adjusted, per parameter, by the ratio of the fit's reported variance to its white one:

    T_j(v) = (S(v) - S_min) / (sigma^2 c_j),    c_j = var_reported_j / var_naive_j,
    var_naive_j = sigma^2 [(J^T J)^-1]_jj,

with J the model Jacobian in every parameter at the estimate and var_reported_j the fit's own variance of
theta_j (``hac-maneuver`` by default). sigma^2 cancels: T_j(v) = (S(v) - S_min) [(J^T J)^-1]_jj / var_reported_j,
so no second estimate of it enters. T_j is compared with q^2, q the two-sided t quantile of the level at the
parameter's reference degrees of freedom: the quantile and dof of its Wald interval (``conf_int``).

Why this is the right comparison: for a model linear in its parameters, S(v) - S_min = (v - theta_j)^2 /
[(J^T J)^-1]_jj exactly, so T_j(v) = (v - theta_j)^2 / var_reported_j and the profile interval *is* the Wald
interval theta_j +- q sd_j. For a nonlinear model the two agree to first order (the curvature of S at the
estimate is the same) and part where the model is nonlinear over the interval: the profile follows the
shape of S (a skewed estimator of a time constant gets an asymmetric interval), the Wald interval cannot.
What c_j carries is the covariance's account of the residuals' colour and changing variance, a scale the
shape of S cannot know; the profile takes it as constant along the parameter (as the sandwich itself is
evaluated at the estimate only).

Bounds are honoured: a side whose statistic stays below q^2 up to the box edge ends at the edge and is
*open* (``open_low``/``open_high``, with the reason), never clipped silently; a side whose estimate lies on
the edge is open at once. A refit that fails gives NaN with the reason, never 0. A parameter whose reported
variance or dof cannot be estimated gets no interval (NaN, with the covariance's reason).
"""
from __future__ import annotations

import bisect
import math
import time
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..data.atomic import json_ready
from ..data.errors import FitError
from .estimates import AT_BOUND_RTOL, ParameterEstimates
from .snls import Evaluation, SeparableProblem, model_jacobian, project, solve
from .statistics import inverse_factor

LEVELS = (0.95, 0.68)
# the crossing is found to this fraction of the parameter's reported standard deviation
XTOL_SD = 2e-3
# refits per side of one parameter at most (the secant steps to the bracket and brentq's)
MAX_REFITS = 40
# a secant step aims this much past the crossing, so that it brackets it rather than stopping short
OVERSHOOT = 0.05
# a secant step goes at most this many times the distance already covered beyond the last point
MAX_GROWTH = 3.0
# a refit whose statistic is below this found a lower cost than the fit's (rounding stays far above it)
BELOW_MINIMUM = -1e-3
TOL = 1e-10          # the refits' tolerance: the stall fits' (defaults.STALL_DEFAULTS)
STATISTIC = ("(S(theta_j) - S_min) / (sigma^2 c_j), c_j = reported / white variance of theta_j, against the "
             "square of the Wald interval's t quantile (same reference dof)")


@dataclass(frozen=True)
class ProfileInterval:
    """One level's profile interval of one parameter, and its Wald interval beside it. A side that reached the
    box edge before the crossing is open there (its bound is the edge); a side whose refit failed is NaN; either
    says why in ``reason_low``/``reason_high``."""

    level: float
    critical: float                 # the t quantile q (the statistic's critical value is q^2)
    low: float
    high: float
    open_low: bool
    open_high: bool
    wald_low: float
    wald_high: float
    reason_low: str | None = None
    reason_high: str | None = None

    def covers(self, value: float) -> bool:
        return bool(self.low <= value <= self.high)

    def to_dict(self) -> dict[str, Any]:
        return json_ready({"level": self.level, "low": self.low, "high": self.high, "open_low": self.open_low,
                           "open_high": self.open_high, "reason_low": self.reason_low,
                           "reason_high": self.reason_high, "wald_low": self.wald_low, "wald_high": self.wald_high,
                           "critical": self.critical})


@dataclass(frozen=True)
class ParameterProfile:
    """The profile of one nonlinear parameter: its intervals (one per level) and the profiled points (value,
    signed root of the statistic: negative below the estimate)."""

    name: str
    estimate: float
    stderr: float                   # reported
    naive_stderr: float             # sigma sqrt([(J^T J)^-1]_jj)
    variance_ratio: float           # c_j
    dof: float
    intervals: tuple[ProfileInterval, ...]
    values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    signed_root: np.ndarray = field(default_factory=lambda: np.zeros(0))
    refits: int = 0
    reason: str | None = None       # why there is no interval at all
    notes: tuple[str, ...] = ()

    def interval(self, level: float) -> ProfileInterval:
        for i in self.intervals:
            if math.isclose(i.level, level):
                return i
        raise KeyError(f"{self.name}: no profile interval at level {level}")

    def to_dict(self) -> dict[str, Any]:
        """The first level's interval flat (``low``, ``high``, ``level``, ``open_low``, ...), every level under
        ``levels``, the statistic's scale and the profiled points."""
        first = self.intervals[0].to_dict() if self.intervals else {}
        return json_ready({
            "estimate": self.estimate, **first, "reason": self.reason, "stderr": self.stderr,
            "naive_stderr": self.naive_stderr, "variance_ratio": self.variance_ratio, "dof": self.dof,
            "levels": {f"{i.level:g}": i.to_dict() for i in self.intervals}, "refits": self.refits,
            "notes": list(self.notes),
            "points": [[float(v), float(r)] for v, r in zip(self.values, self.signed_root)]})


@dataclass(frozen=True)
class Profiles:
    """Profile intervals of a fit's nonlinear parameters (``parameters``, in the fit's order)."""

    parameters: tuple[ParameterProfile, ...]
    levels: tuple[float, ...]
    rss: float                      # S_min
    sigma2: float                   # S_min / (m - p), for c_j
    covariance_kind: str
    seconds: float = 0.0

    def __getitem__(self, name: str) -> ParameterProfile:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def to_dict(self) -> dict[str, Any]:
        """``fit.json``'s ``profile``."""
        return json_ready({"levels": list(self.levels), "level": self.levels[0] if self.levels else None,
                           "statistic": STATISTIC, "covariance": self.covariance_kind, "rss": self.rss,
                           "sigma2": self.sigma2, "seconds": self.seconds,
                           "parameters": {p.name: p.to_dict() for p in self.parameters}})


class _Held(SeparableProblem):
    """``problem`` with nonlinear parameter ``j`` held at ``value``: a separable problem in the others."""

    def __init__(self, problem: SeparableProblem, j: int, value: float):
        self.problem, self.j, self.value = problem, j, float(value)
        names = tuple(problem.nonlinear_names)
        self.nonlinear_names = names[:j] + names[j + 1:]
        self.linear_names = tuple(problem.linear_names)

    def full(self, theta: np.ndarray) -> np.ndarray:
        return np.insert(np.asarray(theta, float), self.j, self.value)

    def evaluate(self, theta: np.ndarray) -> Evaluation:
        ev = self.problem.evaluate(self.full(theta))
        keep = ev.params != self.j
        params = ev.params[keep]
        return Evaluation(ev.phi, ev.dphi[:, keep], ev.rows[keep], params - (params > self.j))


class _RefitFailed(Exception):
    pass


class _Side:
    """The profile of parameter ``j`` on one side of its estimate: refitted points ordered by distance."""

    def __init__(self, owner: "_Profiler", j: int, direction: int):
        self.owner, self.j, self.direction = owner, j, direction
        est = owner.theta[j]
        # (distance from the estimate, value, sqrt of the statistic clipped at 0, nuisance optimum, statistic)
        self.points: list[tuple[float, float, float, np.ndarray, float]] = [(0.0, est, 0.0, owner.nuisance(j), 0.0)]
        self.edge = float(owner.upper[j] if direction > 0 else owner.lower[j])
        self.refits = 0

    def distance(self, v: float) -> float:
        return abs(v - self.owner.theta[self.j])

    def root(self, v: float) -> float:
        """sqrt of the statistic at ``v`` (refitted, warm-started from the nearest point), memoised."""
        d = self.distance(v)
        for p in self.points:
            if p[1] == v:
                return p[2]
        if self.refits >= self.owner.max_refits:
            raise _RefitFailed(f"no crossing within {self.owner.max_refits} refits")
        nearest = min(self.points, key=lambda p: abs(p[1] - v))
        self.refits += 1
        rss, nuisance = self.owner.refit(self.j, v, nearest[3])
        stat = self.owner.statistic(self.j, rss)
        r = math.sqrt(max(stat, 0.0))
        bisect.insort(self.points, (d, v, r, nuisance, stat), key=lambda p: p[0])
        return r

    def _propose(self, q: float) -> float:
        vb, rb = self.points[-1][1], self.points[-1][2]
        if len(self.points) == 1:   # the Wald endpoint: exact for a model linear in theta_j
            step = (1.0 + OVERSHOOT) * q * self.owner.sd[self.j]
        else:
            va, ra = self.points[-2][1], self.points[-2][2]
            covered = self.distance(vb)
            slope = (rb - ra) / abs(vb - va) if vb != va else float("nan")
            step = (q * (1.0 + OVERSHOOT) - rb) / slope if slope > 0 else covered
            step = min(max(step, 0.05 * covered), MAX_GROWTH * covered)
        v = vb + self.direction * step
        return min(v, self.edge) if self.direction > 0 else max(v, self.edge)

    def at_edge(self, v: float) -> bool:
        span = abs(self.owner.upper[self.j] - self.owner.lower[self.j])
        tol = AT_BOUND_RTOL * span if math.isfinite(span) else 0.0
        return math.isfinite(self.edge) and abs(v - self.edge) <= tol

    def crossing(self, q: float) -> tuple[float, bool, str | None]:
        """Where the signed root crosses ``q`` on this side: (bound, open, reason)."""
        side = "upper" if self.direction > 0 else "lower"
        if self.at_edge(self.owner.theta[self.j]):
            return self.edge, True, f"the estimate is on the box's {side} edge ({self.edge:g})"
        try:
            while True:
                inside = [i for i, p in enumerate(self.points) if p[2] >= q]
                if inside:
                    break
                last = self.points[-1][1]
                if last == self.edge:
                    return self.edge, True, (f"the profile stays below the critical value up to the box's {side} "
                                             f"edge ({self.edge:g}): open there")
                self.root(self._propose(q))
            a, b = self.points[inside[0] - 1], self.points[inside[0]]
            if b[2] == q:
                return b[1], False, None
            from scipy.optimize import brentq
            xtol = XTOL_SD * self.owner.sd[self.j]
            return float(brentq(lambda v: self.root(v) - q, a[1], b[1], xtol=xtol, rtol=1e-12,
                                maxiter=self.owner.max_refits)), False, None
        except (_RefitFailed, RuntimeError) as exc:   # brentq's RuntimeError: no convergence in its iterations
            return float("nan"), False, f"{side} side: {exc}"


class _Profiler:
    def __init__(self, problem, y, estimates: ParameterEstimates, tol: float, max_refits: int):
        k = len(estimates.nonlinear_names)
        if tuple(problem.nonlinear_names) != tuple(estimates.nonlinear_names) \
                or tuple(problem.linear_names) != tuple(estimates.linear_names):
            raise ValueError("the problem's parameters are not the estimates' "
                             f"({problem.nonlinear_names + problem.linear_names} vs {estimates.names})")
        self.problem, self.y, self.tol, self.max_refits = problem, np.asarray(y, float), tol, max_refits
        self.theta = np.asarray(estimates.values[:k], float)
        self.lower, self.upper = np.asarray(estimates.lower, float), np.asarray(estimates.upper, float)
        with np.errstate(all="ignore"):
            ev = problem.evaluate(self.theta)
        proj = project(ev.phi, self.y)
        self.rss = float(proj.residual @ proj.residual)
        jac = model_jacobian(ev, proj.coef, k)
        variance = np.diag(estimates.covariance)
        self.sd = np.sqrt(np.where(np.isfinite(variance) & (variance > 0), variance, np.nan))
        keep = np.isfinite(variance) & np.all(np.isfinite(jac), axis=0)
        self.inverse_diagonal = np.full(len(variance), np.nan)   # [(J^T J)^-1]_jj on the estimable parameters
        if keep.any():
            try:
                r_inv = inverse_factor(jac[:, keep])
                self.inverse_diagonal[keep] = np.sum(r_inv * r_inv, axis=1)
            except np.linalg.LinAlgError:
                pass
        self.sigma2 = self.rss / max(len(self.y) - int(keep.sum()), 1)
        self.variance = variance
        self.unconverged = np.zeros(k, int)   # refits per parameter that stopped at the solver's evaluation limit

    def nuisance(self, j: int) -> np.ndarray:
        return np.delete(self.theta, j)

    def refit(self, j: int, value: float, start: np.ndarray) -> tuple[float, np.ndarray]:
        held = _Held(self.problem, j, value)
        try:
            with np.errstate(all="ignore"):
                if not held.nonlinear_names:
                    phi = held.evaluate(np.zeros(0)).phi
                    if not np.all(np.isfinite(phi)):   # a rank-revealing QR would drop NaN columns silently
                        raise FitError("the regression matrix is not finite there")
                    proj = project(phi, self.y)
                    rss, nuisance = float(proj.residual @ proj.residual), np.zeros(0)
                else:
                    lo, hi = np.delete(self.lower, j), np.delete(self.upper, j)
                    out = solve(held, self.y, np.clip(start, lo, hi), lo, hi, tol=self.tol)
                    rss, nuisance = 2.0 * out.cost, out.theta
                    self.unconverged[j] += not out.success
        except (FitError, np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
            raise _RefitFailed(f"the refit at {self.problem.nonlinear_names[j]} = {value:.6g} failed: {exc}") from None
        if not math.isfinite(rss):
            raise _RefitFailed(f"the refit at {self.problem.nonlinear_names[j]} = {value:.6g} has no finite cost")
        return rss, nuisance

    def statistic(self, j: int, rss: float) -> float:
        """T_j = (S - S_min) [(J^T J)^-1]_jj / var_reported_j (module docstring)."""
        return (rss - self.rss) * self.inverse_diagonal[j] / self.variance[j]


def _quantile(level: float, dof: float) -> float:
    from scipy import stats
    if not 0.0 < level < 1.0:
        raise ValueError(f"a profile interval's level is in (0, 1), not {level}")
    return float(stats.t.ppf(0.5 + level / 2.0, dof)) if math.isfinite(dof) else float("nan")


def profile_parameter(profiler: _Profiler, estimates: ParameterEstimates, name: str,
                      levels: Sequence[float]) -> ParameterProfile:
    j = estimates.nonlinear_names.index(name)
    est, sd = float(profiler.theta[j]), float(profiler.sd[j])
    dof = float(estimates.reference_dof.get(name, float("nan")))
    naive = math.sqrt(profiler.sigma2 * profiler.inverse_diagonal[j]) \
        if np.isfinite(profiler.inverse_diagonal[j]) else float("nan")
    ratio = sd * sd / (naive * naive) if naive > 0 else float("nan")
    qs = {level: _quantile(level, dof) for level in levels}
    why = (estimates.not_identifiable.get(name)
           or (None if math.isfinite(sd) else "its reported variance cannot be estimated")
           or (None if math.isfinite(dof) else "its reference degrees of freedom cannot be computed")
           or (None if math.isfinite(ratio) else "its white variance cannot be computed"))
    if why:
        nan = float("nan")
        return ParameterProfile(name, est, sd, naive, ratio, dof,
                                tuple(ProfileInterval(lv, qs[lv], nan, nan, False, False, nan, nan, why, why)
                                      for lv in levels), reason=why)
    sides = {d: _Side(profiler, j, d) for d in (-1, 1)}
    found = {}
    for level in sorted(levels, key=lambda lv: qs[lv]):   # the nearer crossing first: the farther reuses its points
        found[level] = {d: s.crossing(qs[level]) for d, s in sides.items()}
    intervals = []
    for level in levels:
        (low, open_low, why_low), (high, open_high, why_high) = found[level][-1], found[level][1]
        half = qs[level] * sd
        intervals.append(ProfileInterval(level, qs[level], low, high, open_low, open_high, est - half, est + half,
                                         why_low, why_high))
    points = sorted([(p[1], -p[2]) for p in sides[-1].points[1:]] + [(est, 0.0)]
                    + [(p[1], p[2]) for p in sides[1].points[1:]])
    notes: tuple[str, ...] = ()
    below = [p[1] for s in sides.values() for p in s.points if p[4] < BELOW_MINIMUM]
    if below:
        notes += (f"a refit at {name} = {below[0]:.6g} reached a cost below the fit's: the fit is not at its "
                  "optimum along this parameter",)
    if profiler.unconverged[j]:
        notes += (f"{profiler.unconverged[j]} refit(s) stopped at the solver's evaluation limit: their cost is an "
                  "upper bound of the profile there (the interval may be too narrow)",)
    return ParameterProfile(name, est, sd, naive, ratio, dof, tuple(intervals),
                            np.array([p[0] for p in points]), np.array([p[1] for p in points]),
                            sides[-1].refits + sides[1].refits, None, notes)


def profile(problem: SeparableProblem, y: np.ndarray, estimates: ParameterEstimates,
            names: Sequence[str] | None = None, *, levels: Sequence[float] = LEVELS, tol: float = TOL,
            max_refits: int = MAX_REFITS) -> Profiles:
    """Profile intervals at ``levels`` of the nonlinear parameters ``names`` (default: all) of a fit whose
    ``estimates`` were obtained on ``problem`` and the observations ``y`` (module docstring)."""
    t0 = time.perf_counter()
    names = tuple(estimates.nonlinear_names if names is None else names)
    unknown = [n for n in names if n not in estimates.nonlinear_names]
    if unknown:
        raise ValueError(f"{unknown[0]!r} is not a nonlinear parameter of this fit "
                         f"({', '.join(estimates.nonlinear_names) or 'none'})")
    levels = tuple(float(lv) for lv in levels)
    if not levels:
        raise ValueError("a profile needs at least one level")
    profiler = _Profiler(problem, y, estimates, tol, max_refits)
    out = tuple(profile_parameter(profiler, estimates, n, levels) for n in names)
    return Profiles(out, levels, profiler.rss, profiler.sigma2, estimates.covariance_kind, time.perf_counter() - t0)


def profile_statistic(problem: SeparableProblem, y: np.ndarray, estimates: ParameterEstimates, name: str,
                      values: Sequence[float], *, tol: float = TOL) -> np.ndarray:
    """The statistic T_j at each of ``values`` of parameter ``name`` (each a refit from the estimate's other
    parameters): 0 at the estimate, q^2 at a profile interval's bounds."""
    profiler = _Profiler(problem, y, estimates, tol, MAX_REFITS)
    j = estimates.nonlinear_names.index(name)
    return np.array([profiler.statistic(j, profiler.refit(j, float(v), profiler.nuisance(j))[0]) for v in values])


