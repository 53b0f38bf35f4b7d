"""Separable nonlinear least squares by variable projection (Golub-Pereyra).

A *problem* is anything with ``nonlinear_names``, ``linear_names`` and
``evaluate(theta) -> Evaluation``: the regression matrix Phi(theta) (m x n) and
only the non-zero columns of its derivative tensor, with a lookup table saying
which regressor and which nonlinear parameter each column belongs to (O'Leary &
Rust). For a given theta the linear coefficients are the least-squares solution
c = Phi^+ y (pivoted QR); the optimiser sees only theta.

The residual Jacobian is the full Golub-Pereyra one in the memory-lean form of
the thesis' Eq. 18,

    Dr = -DPhi c + Phi (Phi^+ (DPhi c)) - (Phi^+)^T (DPhi)^T r,

evaluated with the thin QR factors, so nothing larger than m x max(n, k) is
ever formed.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy.linalg import qr, solve_triangular
from scipy.optimize import least_squares

from ..data.errors import FitError
from .ties import first_of_lowest


@dataclass(frozen=True)
class Evaluation:
    """Phi(theta) and its non-zero derivative columns.

    ``dphi[:, j]`` is d Phi[:, rows[j]] / d theta[params[j]].
    """

    phi: np.ndarray
    dphi: np.ndarray
    rows: np.ndarray
    params: np.ndarray


class SeparableProblem(Protocol):
    """What the solver and the statistics may use of a problem: ``evaluate`` is the whole contract; the rest
    are capabilities with defaults, which a problem gets by subclassing this protocol (and overrides where it
    has more to say)."""

    nonlinear_names: tuple[str, ...]
    linear_names: tuple[str, ...]

    def evaluate(self, theta: np.ndarray) -> Evaluation: ...

    def identifiability(self, theta: np.ndarray) -> dict[str, str]:
        """The parameters the structure cannot identify at ``theta``, each with why (domain rules: a state its
        regressors cannot see, ...); default: none beyond what the Jacobian's rank shows."""
        return {}

    def jacobian_blocks(self) -> list[tuple[slice, list[int]]] | None:
        """Row blocks and the columns each touches (a stacked problem's), for a blockwise scaled QR; default
        None: the Jacobian is one block."""
        return None

    def extended_residual(self, theta: np.ndarray, coef: np.ndarray, y: np.ndarray) -> np.ndarray | None:
        """``y - Phi(theta) coef`` in extended precision where the problem can give it; default None."""
        return None

    def regressor_inputs(self, index: int, row: int) -> str:
        """The inputs of regressor ``index`` at ``row``, in words, for an error naming a bad value; default
        empty."""
        return ""

    @property
    def units(self) -> dict[str, str]:
        """Each parameter's unit where the problem knows it; default none (the tables then say "unknown")."""
        return {}

    def reduce(self, theta: np.ndarray, y: np.ndarray) -> Reduced | None:
        """The reduced problem at ``theta`` (None where Phi, its derivative or the Jacobian is not finite); default
        the projection of the whole Phi (:func:`projected`). A problem with structure to exploit overrides it (a
        joint problem's block-diagonal Phi projects block by block, never forming the stacked matrix)."""
        return projected(self, theta, y, len(self.nonlinear_names))


class BoundProblem(SeparableProblem):
    """Base of a model bound to data (attribute ``model``): parameter names come from the model."""

    @property
    def nonlinear_names(self) -> tuple[str, ...]:
        return self.model.nonlinear_names

    @property
    def linear_names(self) -> tuple[str, ...]:
        return self.model.linear_names


@dataclass(frozen=True)
class Projection:
    """Thin pivoted QR of Phi restricted to its numerical rank, and the LS solution."""

    q: np.ndarray          # (m, rank)
    r: np.ndarray          # (rank, rank)
    columns: np.ndarray    # indices of Phi's columns that span its range, in QR order
    dependent: np.ndarray  # indices of columns dropped as linearly dependent
    coef: np.ndarray       # (n,), zero on dependent columns
    residual: np.ndarray   # (m,)

    @property
    def rank(self) -> int:
        return len(self.columns)


def project(phi: np.ndarray, y: np.ndarray, rtol: float | None = None) -> Projection:
    """Least-squares solution of Phi c = y by rank-revealing QR."""
    m, n = phi.shape
    if n == 0:
        return Projection(np.zeros((m, 0)), np.zeros((0, 0)), np.zeros(0, int), np.zeros(0, int),
                          np.zeros(0), y.copy())
    q, r, perm = qr(phi, mode="economic", pivoting=True, check_finite=False)
    diag = np.abs(np.diag(r))
    tol = (rtol if rtol is not None else max(m, n) * np.finfo(float).eps) * (diag[0] if diag[0] > 0 else 1.0)
    rank = int(np.sum(diag > tol)) if diag[0] > 0 else 0
    q, r = np.ascontiguousarray(q[:, :rank]), r[:rank, :rank]
    qty = q.T @ y
    coef = np.zeros(n)
    coef[perm[:rank]] = solve_triangular(r, qty, check_finite=False)
    residual = y - q @ qty
    return Projection(q, r, perm[:rank], np.sort(perm[rank:]), coef, residual)


def _dphi_times_coef(ev: Evaluation, coef: np.ndarray, k: int) -> np.ndarray:
    """DPhi c (m x k): column j is sum_i dPhi_i/dtheta_j c_i, as one matrix product."""
    select = np.zeros((len(ev.rows), k))
    select[np.arange(len(ev.rows)), ev.params] = coef[ev.rows]
    return ev.dphi @ select


def residual_jacobian(ev: Evaluation, proj: Projection, k: int) -> np.ndarray:
    """Golub-Pereyra Jacobian d r / d theta (m x k) of the projected residual, Eq. 18.

    Dr = -(I - Q Q^T) DPhi c - Q R^-T P^T (DPhi)^T r, with the two Q-products merged.
    """
    dphi_c = _dphi_times_coef(ev, proj.coef, k)
    # (DPhi)^T r, arranged as (n, k), restricted to the independent columns
    w = np.zeros((ev.phi.shape[1], k))
    np.add.at(w, (ev.rows, ev.params), ev.dphi.T @ proj.residual)
    small = proj.q.T @ dphi_c - solve_triangular(proj.r, w[proj.columns], trans="T", check_finite=False)
    dphi_c -= proj.q @ small
    return np.negative(dphi_c, out=dphi_c)


def model_jacobian(ev: Evaluation, coef: np.ndarray, k: int) -> np.ndarray:
    """Jacobian of the model Phi(theta) c w.r.t. (theta, c) with c held fixed: [DPhi c, Phi]."""
    return np.hstack([_dphi_times_coef(ev, coef, k), ev.phi])


@dataclass(frozen=True)
class Reduced:
    """What the optimiser needs at one theta: the linear coefficients, the projected residual and its
    Golub-Pereyra Jacobian (m x k). Their rows may come in any order the problem finds cheap (the same for
    both): the optimiser sees only the residual's norm, J^T r and J^T J."""

    coef: np.ndarray
    residual: np.ndarray
    jacobian: np.ndarray


def projected(problem: SeparableProblem, theta: np.ndarray, y: np.ndarray, k: int) -> Reduced | None:
    """The reduced problem at ``theta`` by the projection of the whole Phi (None where Phi, its derivative or the
    Jacobian is not finite)."""
    ev = problem.evaluate(theta)
    if not (np.all(np.isfinite(ev.phi)) and np.all(np.isfinite(ev.dphi))):
        return None
    proj = project(ev.phi, y)
    jac = residual_jacobian(ev, proj, k)
    return Reduced(proj.coef, proj.residual, jac) if np.all(np.isfinite(jac)) else None


def gauss_newton_step(problem: SeparableProblem, y: np.ndarray, theta, lower, upper) -> np.ndarray | None:
    """The Gauss-Newton step of the reduced problem from ``theta``, projected on the box (None where the
    problem is not finite there): what one more solve would move the estimate, to first order, at the cost of
    one evaluation and no line search. Parameters on a bound that the step pushes outward do not move."""
    theta = np.asarray(theta, float)
    reduced = problem.reduce(theta, y)
    if reduced is None:
        return None
    step = np.linalg.lstsq(reduced.jacobian, -reduced.residual, rcond=None)[0]
    return np.clip(theta + step, lower, upper) - theta


# Slow but steady starts (NIST Rat42 from start 1 needs ~380 evaluations) should finish.
DEFAULT_MAX_NFEV = 1000


class _Objective:
    """Residual and Jacobian of the reduced problem, sharing one evaluation per theta.

    The optimiser is handed the problem in compressed form: with J = Q_J R_J
    (thin QR, m x k), the residual r becomes [Q_J^T r, |r - Q_J Q_J^T r|] and the
    Jacobian [R_J; 0]. Norm, gradient J^T r and Gauss-Newton matrix J^T J are
    unchanged, so every trust-region step is the same, but the solver's own
    linear algebra works on k + 1 rows instead of m.
    """

    def __init__(self, problem: SeparableProblem, y: np.ndarray):
        self.problem, self.y = problem, y
        self.k = len(problem.nonlinear_names)
        self._theta = None
        self._cached = None
        self.evaluations = 0

    def _at(self, theta):
        if self._theta is None or not np.array_equal(theta, self._theta):
            with np.errstate(all="ignore"):
                reduced = self.problem.reduce(theta, self.y)
            if reduced is not None:
                q_j, r_j = qr(np.asfortranarray(reduced.jacobian), mode="economic", overwrite_a=True,
                              check_finite=False)
                head = q_j.T @ reduced.residual
                rest = max(float(reduced.residual @ reduced.residual - head @ head), 0.0)
                self._cached = (reduced, np.append(head, np.sqrt(rest)),
                                np.vstack([r_j, np.zeros((1, self.k))]))
            else:
                self._cached = (None, None, None)
            self._theta = np.array(theta, copy=True)
            self.evaluations += 1
        return self._cached

    def residual(self, theta):
        compressed = self._at(theta)[1]
        # the trust-region solver shrinks its step when it meets a non-finite residual
        return np.full(self.k + 1, np.inf) if compressed is None else compressed

    def jacobian(self, theta):
        reduced, _, compressed_jac = self._at(theta)
        if reduced is None:
            raise FitError("the regression matrix or its derivative is not finite at theta = "
                           + _fmt(self.problem.nonlinear_names, theta))
        return compressed_jac


def _fmt(names, values) -> str:
    return "{" + ", ".join(f"{n}={v:.6g}" for n, v in zip(names, values)) + "}"


@dataclass(frozen=True)
class Outcome:
    """What one local solve produced."""

    start: np.ndarray
    theta: np.ndarray
    coef: np.ndarray
    cost: float           # 0.5 * RSS
    nfev: int
    njev: int
    status: int
    message: str
    success: bool
    error: str | None = None


def check_start_in_box(names, start, lower, upper) -> None:
    for name, s, lo, hi in zip(names, start, lower, upper):
        if not lo < hi:
            raise FitError(f"parameter {name!r}: lower bound {lo} is not below upper bound {hi}")
        if not np.isfinite(s):
            raise FitError(f"parameter {name!r}: start value {s} is not finite")
        if not lo <= s <= hi:
            raise FitError(f"parameter {name!r}: start value {s:g} lies outside its bounds [{lo:g}, {hi:g}]")


def solve(problem: SeparableProblem, y: np.ndarray, start, lower, upper, *,
          tol: float = 1e-10, max_nfev: int | None = None) -> Outcome:
    """One local variable-projection solve (trust-region reflective, bounds honoured)."""
    start = np.asarray(start, float)
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    check_start_in_box(problem.nonlinear_names, start, lower, upper)
    objective = _Objective(problem, y)
    # least_squares needs the start strictly inside finite bounds
    span = np.where(np.isfinite(upper - lower), upper - lower, 1.0)
    x0 = np.clip(start, lower + 1e-10 * span, upper - 1e-10 * span)
    # the bound box is the natural scale of each parameter (a1 ~ 100 next to a_star ~ 0.2);
    # Jacobian-based rescaling was tried and lost MGH09 and MGH17 from NIST start 1
    # the trust-region sub-solver can overflow on a trial step of a badly scaled candidate; it then
    # rejects the step, and what matters reaches the user through status, message and the checks
    # below, not as numpy warnings printed from inside scipy
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        sol = least_squares(objective.residual, x0, jac=objective.jacobian, bounds=(lower, upper),
                            method="trf", x_scale=span, ftol=tol, xtol=tol, gtol=tol,
                            max_nfev=max_nfev if max_nfev is not None else DEFAULT_MAX_NFEV)
    reduced = objective._at(sol.x)[0]
    if reduced is None:
        raise FitError("the solver stopped where the regression matrix is not finite: theta = "
                       + _fmt(problem.nonlinear_names, sol.x))
    return Outcome(start=start, theta=sol.x, coef=reduced.coef,
                   cost=float(0.5 * reduced.residual @ reduced.residual),
                   nfev=int(sol.nfev), njev=int(sol.njev or 0), status=int(sol.status),
                   message=str(sol.message), success=bool(sol.status > 0))


def _solve_or_record(problem, y, start, lower, upper, tol, max_nfev) -> Outcome:
    try:
        return solve(problem, y, start, lower, upper, tol=tol, max_nfev=max_nfev)
    except (FitError, np.linalg.LinAlgError, FloatingPointError) as exc:
        nan = np.full(len(start), np.nan)
        return Outcome(np.asarray(start, float), nan, np.full(len(problem.linear_names), np.nan),
                       np.inf, 0, 0, -1, str(exc), False, error=str(exc))


def start_points(start, lower, upper, n_starts: int, seed: int) -> np.ndarray:
    """The given start followed by n_starts - 1 scrambled Sobol points inside the bounds."""
    start = np.asarray(start, float)
    if n_starts <= 1:
        return start[None, :]
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
        raise FitError("multistart needs finite bounds on every nonlinear parameter")
    # scipy.stats (0.5 s to import) only when there are quasi-random starts to draw
    from scipy.stats import qmc
    sampler = qmc.Sobol(d=len(start), scramble=True, seed=seed)
    # Sobol balance properties want a power of two; draw that many and keep the first ones
    m = int(np.ceil(np.log2(max(n_starts - 1, 1))))
    unit = sampler.random_base2(m)[: n_starts - 1]
    return np.vstack([start, qmc.scale(unit, lower, upper)])


@dataclass(frozen=True)
class MultistartOutcome:
    best: Outcome
    outcomes: tuple[Outcome, ...]
    n_reached_best: int


def reached(outcomes, best_cost: float, scale: float, rtol: float = 1e-6) -> int:
    return int(sum(o.cost <= best_cost + rtol * best_cost + 1e-14 * scale for o in outcomes))


def start_list(problem: SeparableProblem, start, lower, upper, *, n_starts: int = 1, seed: int = 0,
               also=()) -> np.ndarray:
    """The starts of a multistart, in the order it tries them: ``start``, the points in ``also`` (inside the
    bounds) and ``n_starts`` - 1 scrambled Sobol points. Each is checked inside the box."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    check_start_in_box(problem.nonlinear_names, np.asarray(start, float), lower, upper)
    for point in also:
        check_start_in_box(problem.nonlinear_names, np.asarray(point, float), lower, upper)
    points = start_points(start, lower, upper, n_starts, seed)
    if len(also):
        points = np.vstack([points[:1], np.asarray(also, float).reshape(-1, len(points[0])), points[1:]])
    return points


def best_of(outcomes, y: np.ndarray) -> MultistartOutcome:
    """The lowest-cost outcome of solves from several starts (given in start order)."""
    finite = [o for o in outcomes if np.isfinite(o.cost)]
    if not finite:
        raise FitError("no start produced a fit: " + outcomes[0].message)
    # starts that reach the same optimum differ in cost by rounding: the first of them (start order) wins
    best = first_of_lowest(finite, lambda o: o.cost)
    return MultistartOutcome(best, tuple(outcomes), reached(finite, best.cost, float(y @ y)))


def solve_recorded(problem: SeparableProblem, y: np.ndarray, start, lower, upper, *, tol: float = 1e-10,
                   max_nfev: int | None = None) -> Outcome:
    """One local solve whose failure is recorded in its outcome (infinite cost, the reason), never raised: one
    start of a multistart, which may run as a task of its own."""
    return _solve_or_record(problem, y, start, lower, upper, tol, max_nfev)


def multistart(problem: SeparableProblem, y: np.ndarray, start, lower, upper, *, n_starts: int = 1,
               seed: int = 0, n_jobs: int = 1, tol: float = 1e-10,
               max_nfev: int | None = None, also=()) -> MultistartOutcome:
    """Solve from several starts (in parallel with joblib); keep the lowest cost. The starts are ``start``,
    the points in ``also`` (inside the bounds) and ``n_starts`` - 1 scrambled Sobol points."""
    points = start_list(problem, start, lower, upper, n_starts=n_starts, seed=seed, also=also)
    if n_jobs == 1 or len(points) == 1:
        outcomes = [_solve_or_record(problem, y, p, lower, upper, tol, max_nfev) for p in points]
    else:
        from joblib import Parallel, delayed
        outcomes = Parallel(n_jobs=n_jobs)(
            delayed(_solve_or_record)(problem, y, p, lower, upper, tol, max_nfev) for p in points)
    return best_of(outcomes, y)
