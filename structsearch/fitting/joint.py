"""C_L, C_D and C_m identified together: one separable problem in which the coefficients share the separation
parameters of their common states (a*, tau1, tau2, ...) and each keeps its own linear block
(:class:`structsearch.engine.joint.JointProblem`).

Weights. Each coefficient's rows are weighted by 1 / s_b^2, its residual variance, re-estimated from the joint
fit until the weights settle (relative change below ``tol``): the relaxation algorithm of output-error
methods with an estimated noise covariance (Jategaonkar, FVSysID), whose fixed point maximises the likelihood
concentrated on a diagonal noise covariance. Each iteration takes one Gauss-Newton step of the problem weighted
and fed (the C_L that drag and pitch read) at the current estimate, instead of solving that problem to its
optimum: one evaluation per iteration, where a solve costs four or five, and the same fixed point
(:func:`_relax_by_gauss_newton`). The iteration has settled when the weights change by less than ``tol`` and the
next step is below ``tol`` of the box. When the steps stop contracting, the fit falls back to solving each
iteration's problem (settled when the weights change by less than ``tol`` and a Gauss-Newton step of the next
iteration's problem is below ``tol`` of the box). The covariance is kept diagonal: the coefficients' noises are
nearly independent here (different sensors and reductions), and off-diagonal terms would couple the blocks'
linear solves (a GLS across coefficients) and lose the block-separable projection.

C_L in drag and pitch. As in the sequential fit, drag and pitch read the lift model's output, not the measured
C_L (buffet noise would bias them as errors in variables). In the joint fit it is the lift block's output at
the current iterate: the weight iteration updates it with the weights, so at the fixed point drag and pitch
see the C_L of the jointly estimated lift model. The drag and pitch blocks treat it as data within one step, so
the estimating equations are J^T r = 0 with J at a fixed C_L; the joint covariance counts the C_L path in the
estimator's bread (:func:`.joint_covariance.through_the_lift_output`). The influence series :func:`joint_lift`
hands a search are still conditional on that C_L (a known omission, which matters where drag or pitch lean on C_L).

Statistics are the stacked problem's, with the options' covariance (``hac-maneuver`` by default: a maneuver's
rows of every coefficient are one record), identifiability, convergence and bound flags as in every fit.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from ..data.errors import DeclarationError
from ..data.flightdata import FlightData
from ..engine.fit import fit_problem
from ..engine.joint import JointProblem
from ..engine.defaults import STALL_DEFAULTS
from ..engine.results import FitResult
from ..engine.scores import ManeuverScores
from ..engine.snls import Outcome, gauss_newton_step, model_jacobian, solve
from ..engine.twostep import influence_series
from .bands import bands_document, curve_bands
from .candidate_fit import fit_staged
from .candidate_result import SplitScores
from .candidates import Candidate
from .lift_fit import JointLift, LiftAt, LiftFit
from .models import build_model, model_with_lift, with_lift_prediction
from .options import FitOptions
from .specs import load_grid
# lift_output_jacobian and joint_structures are imported from here too
from .joint_covariance import lift_output_jacobian, through_the_lift_output  # noqa: F401
from .joint_spec import check_joint, joint_structures  # noqa: F401

MAX_ITERATIONS = 20
WEIGHT_TOLERANCE = 1e-3


@dataclass(frozen=True)
class CoefficientFit:
    """One coefficient of a joint fit: its structure, parameters (shared ones included), their standard
    deviations, MSE and R^2 on both splits."""

    coefficient: str
    model: str
    params: Mapping[str, float]
    stderr: Mapping[str, float]
    train: SplitScores
    validation: SplitScores
    weight: float

    def to_dict(self) -> dict:
        return {"model": self.model, "parameters": dict(self.params), "stderr": dict(self.stderr),
                "mse": {"train": self.train.mse, "validation": self.validation.mse},
                "r2": {"train": self.train.r2.as_dict(), "validation": self.validation.r2.as_dict()},
                "weight": self.weight}


@dataclass(frozen=True)
class JointFit:
    """A joint fit: the stacked problem's result (every parameter's estimate and covariance), the per-coefficient
    view, and how the weight iteration went."""

    candidates: tuple[Candidate, ...]
    result: FitResult
    coefficients: tuple[CoefficientFit, ...]
    shared: tuple[str, ...]                 # the separation parameters the coefficients share
    iterations: int
    weights_settled: bool
    lift: Candidate | None = None           # the lift structure whose output drag and pitch read
    lift_params: Mapping[str, float] = field(default_factory=dict)   # ... at these values (the joint estimate)
    seconds: float = float("nan")
    bands: tuple = ()                       # per coefficient, its static curve's StaticBands (the joint covariance)
    history: tuple[Mapping[str, float], ...] = field(default=(), repr=False)   # weights per iteration
    problem: JointProblem | None = field(default=None, repr=False)           # the settled stacked problem
    replay: object | None = None            # a maneuver's forward replay with its sampled band (flight.replay_bands)
    data: Mapping | None = None             # the campaign it was fitted on (fit.json's ``data``; export reads it)

    @property
    def name(self) -> str:
        return " + ".join(c.name for c in self.candidates)

    def to_dict(self) -> dict:
        """``fit.json`` of a joint fit (docs/interfaces.md 6.3): the single-fit fields for the shared parameters
        and ``coefficients``, one entry per coefficient."""
        r = self.result
        shared = list(self.shared)
        pick = (lambda d: {n: d[n] for n in shared})
        return {"model": self.name, "coefficient": "+".join(c.coefficient for c in self.coefficients),
                "joint": True, "params": pick(r.params), "stderr": pick(r.stderr),
                "p_values": pick(r.p_values), "reference_dof": pick(r.reference_dof),
                "at_bound": {n: v for n, v in r.at_bound.items() if n in shared},
                "high_correlations": [list(p) for p in r.high_correlations],
                "converged": r.converged, "message": r.message, "nfev": r.nfev,
                "identifiable": r.identifiable, "not_identifiable": dict(r.not_identifiable),
                "condition_number": r.condition_number,
                "insignificant": [n for n in shared if not r.significant[n]],
                "n_starts": r.n_starts, "n_reached_best": r.n_reached_best,
                "lift": None if self.lift is None else {"model": self.lift.name, "params": dict(self.lift_params)},
                "covariance": r.estimates.covariance_record(),
                "parameter_covariance": {"names": list(r.estimates.names),
                                         "matrix": np.asarray(r.estimates.covariance, float).tolist()},
                "weights": {c.coefficient: c.weight for c in self.coefficients},
                "weight_iterations": self.iterations, "weights_settled": self.weights_settled,
                "coefficients": {c.coefficient: c.to_dict() for c in self.coefficients},
                **({"bands": {**bands_document(self.bands),
                              **({"replay": self.replay.to_dict()} if self.replay is not None else {})}}
                   if self.bands else {}),
                **({"data": dict(self.data)} if self.data is not None else {}),
                "seconds": self.seconds}


def _scores(y: np.ndarray, pred: np.ndarray, data: FlightData) -> SplitScores:
    return SplitScores.of(ManeuverScores.of(y, y - pred, data.segment_slices()), None)


def _settle(problem_at, order, models, params, weights, lower, upper, max_iterations: int, tol: float):
    """Relax the weights and the estimate together until one more iteration changes neither by more than ``tol``:
    Gauss-Newton steps while they contract, then (they stopped contracting, or their budget ran out) each
    iteration's problem solved from where the steps left off, the slower relaxation that needs no contraction,
    with a budget of its own. (the problem settled on, its observations, the optimum, iterations, settled, history)"""
    relaxed = _relax_by_gauss_newton(problem_at, [c.coefficient for c in order], params, weights, lower, upper,
                                     max_iterations, tol)
    history, iterations, settled, outcome = list(relaxed.history), relaxed.iterations, relaxed.settled, relaxed.outcome
    params, weights = relaxed.params, relaxed.weights
    if settled:
        problem, _, y = problem_at(params, weights)
        return problem, y, outcome, iterations, settled, history
    problem, y, outcome, iterations, settled = _relax_by_solves(problem_at, order, models, params, weights, history,
                                                                lower, upper, iterations, max_iterations, tol)
    return problem, y, outcome, iterations, settled, history


def fit_joint(candidates: Sequence[Candidate], train: FlightData, validation: FlightData,
              options: FitOptions = FitOptions(), *, max_iterations: int = MAX_ITERATIONS,
              tol: float = WEIGHT_TOLERANCE, band_samples: int = 0) -> JointFit:
    """Fit ``candidates`` (two or three of lift, drag, pitch) jointly (module docstring). Each is first fitted
    alone (its estimates start the joint fit, its residual variance gives the first weights)."""
    t0 = time.perf_counter()
    lift_c, others = check_joint(candidates)
    order = ([lift_c] if lift_c is not None else []) + others
    lift_fit, seq = _sequential_fits(lift_c, others, order, train, validation, options)
    # drag and pitch with their (the lift model's) states free: the joint fit estimates them
    models = [build_model(lift_c) if c is lift_c else model_with_lift(c, {}) for c in order]
    params = dict(lift_fit.params)   # the shared separation parameters start at the lift model's estimate
    for c in others:
        params.update(seq[c.coefficient].estimates.params)
    weights = np.array([1.0 / seq[c.coefficient].mse_train for c in order])
    lift_candidate = lift_fit.candidate

    def lift_params_now(current):
        """What drag and pitch read: the joint lift block's estimate, or the sequential lift model's when the
        lift structure is not part of the joint fit."""
        if lift_c is None:
            return dict(lift_fit.params)
        return {n: current[n] for n in lift_fit.params}

    def problem_at(current, w):
        datas = [train if c is lift_c else with_lift_prediction(train, lift_params_now(current), lift_candidate)
                 for c in order]
        problem = JointProblem(tuple(m.bind(d) for m, d in zip(models, datas)), w, train.n_samples)
        # a pitch model about a fixed point fits C_m less its known transfer (the model's target)
        return problem, datas, problem.interleave([m.target(d) for m, d in zip(models, datas)])

    lower, upper = _box(problem_at(params, weights)[0], models, train)
    problem, y, outcome, iterations, settled, history = _settle(problem_at, order, models, params, weights, lower,
                                                                upper, max_iterations, tol)
    # the statistics at the settled estimate, on the problem it settled on (its weights, its C_L): one more
    # iteration would change the weights and the estimate by less than ``tol``
    result = fit_problem(problem, y, boundaries=problem.boundaries(train.bounds), segment_names=train.names,
                         lower=lower, upper=upper, covariance=options.covariance, solution=outcome,
                         model=" + ".join(c.name for c in order), coefficient="joint", source=train.source,
                         flights=train.flights)
    if lift_c is not None and others:
        result = through_the_lift_output(result, problem, order, models, train, lift_candidate)
    params = dict(result.params)
    coefficients = _coefficient_fits(order, models, problem, result, params, train, validation, lift_c,
                                     lift_params_now(params), lift_candidate)
    shared = tuple(n for n in problem.nonlinear_names if sum(n in m.nonlinear_names for m in models) > 1)
    # each coefficient's static curve with the joint covariance: drag and pitch through the shared states too
    read = LiftAt(lift_candidate, lift_params_now(params))   # what drag and pitch read at the settled estimate
    bands = tuple(curve_bands(c, result.estimates, train, None if c is lift_c else read, m, samples=band_samples,
                              seed=options.seed)
                  for c, m in zip(order, models))
    return JointFit(tuple(order), result, tuple(coefficients), shared, iterations, settled, lift=lift_candidate,
                    lift_params=dict(read.params),
                    seconds=time.perf_counter() - t0, bands=bands, history=tuple(history), problem=problem)


def _sequential_fits(lift_c: Candidate | None, others: Sequence[Candidate], order: Sequence[Candidate],
                     train: FlightData, validation: FlightData, options: FitOptions) -> tuple[LiftFit, dict]:
    """The lift model's fit (the joint lift structure's, else the sequential lift model drag and pitch name) and
    each coefficient's sequential fit, by coefficient: the joint fit's starts and first weights."""
    # the sequential fits: starts and first weights (their estimates and residuals only: no cross-validation,
    # no two-step covariance, no centred correlations)
    starting = replace(options, cv_folds=0, scores_only=True)
    if lift_c is not None:
        lone = fit_staged(lift_c, train, validation, None, starting)
    else:
        lift_c_seq = load_grid("lift")[others[0].lift]
        lone = fit_staged(lift_c_seq, train, validation, None, starting)
    if lone.failed:
        raise DeclarationError(f"the lift model {lone.name} could not be fitted: {lone.error}")
    lift_fit = LiftFit(lift_c if lift_c is not None else lift_c_seq, lone)
    seq = {c.coefficient: (lone if c is lift_c else fit_staged(c, train, validation, lift_fit, starting))
           for c in order}
    for coef, r in seq.items():
        if r.failed:
            raise DeclarationError(f"{coef}: the sequential fit that starts the joint one failed: {r.error}")
    return lift_fit, seq


def _relax_by_solves(problem_at, order: Sequence[Candidate], models, params: dict, weights: np.ndarray,
                     history: list, lower: np.ndarray, upper: np.ndarray, iterations: int, max_iterations: int,
                     tol: float):
    """The weight iteration solving each iteration's problem (:func:`fit_joint` falls back to it when the
    Gauss-Newton steps stop contracting), from ``params`` after ``iterations`` iterations, with a budget of
    ``max_iterations`` of its own. Updates ``params`` and ``history`` in place; returns the last problem, its
    observations and the optimum found on it, the iteration count and whether the iteration settled."""
    settled = False
    for iterations in range(iterations + 1, iterations + max_iterations + 1):
        problem, datas, y = problem_at(params, weights)
        theta0 = np.clip([params[n] for n in problem.nonlinear_names], lower, upper)
        outcome = solve(problem, y, theta0, lower, upper, tol=STALL_DEFAULTS.tol)
        params.update(dict(zip(problem.nonlinear_names, outcome.theta)))
        params.update(dict(zip(problem.linear_names, outcome.coef)))
        residual_var = [float(np.mean((d[c.coefficient] - m.predict(d, {n: params[n] for n in
                                                                        m.nonlinear_names + m.linear_names})) ** 2))
                        for c, m, d in zip(order, models, datas)]
        new = 1.0 / np.array(residual_var)
        history.append({c.coefficient: float(w) for c, w in zip(order, new)})
        # settled: the weights, and the C_L that drag and pitch read (it moves with theta), no longer change.
        # Both are needed: with the weights alone (settled after 2 iterations on the default campaign) tau1
        # and tau2 were still drifting by 0.2-0.3 standard deviations as the C_L that drag and pitch read
        # followed.
        moved = float(np.max(np.abs(outcome.theta - theta0) / (upper - lower)))
        if float(np.max(np.abs(new / weights - 1.0))) < tol:
            if moved >= tol:
                # would one more iteration (the new weights, the C_L at this estimate) move the estimate?
                # A Gauss-Newton step of that problem answers to first order for one evaluation
                following, _, y_next = problem_at(params, new)
                step = gauss_newton_step(following, y_next, outcome.theta, lower, upper)
                moved = np.inf if step is None else float(np.max(np.abs(step) / (upper - lower)))
            if moved < tol:
                settled = True
                break
        weights = new
    return problem, y, outcome, iterations, settled


def _coefficient_fits(order: Sequence[Candidate], models, problem: JointProblem, result: FitResult,
                      params: Mapping[str, float], train: FlightData, validation: FlightData,
                      lift_c: Candidate | None, lift_params: Mapping[str, float],
                      lift_candidate: Candidate) -> list[CoefficientFit]:
    """Each coefficient's view of the joint fit: its parameters and their standard deviations, its scores on both
    splits (drag and pitch reading the C_L of ``lift_candidate`` at ``lift_params``) and its weight."""
    coefficients = []
    for c, m, w in zip(order, models, problem.weights):
        own = {n: params[n] for n in m.nonlinear_names + m.linear_names}
        scores = {}
        for split, data in (("train", train), ("validation", validation)):
            seen = data if c is lift_c else with_lift_prediction(data, lift_params, lift_candidate)
            scores[split] = _scores(seen[c.coefficient], m.predict(seen, own), seen)
        coefficients.append(CoefficientFit(c.coefficient, c.name, own, {n: result.stderr[n] for n in own},
                                           scores["train"], scores["validation"], float(w)))
    return coefficients


# A Gauss-Newton step must shrink to this fraction of the one before, or the relaxation falls back to solves.
CONTRACTION = 0.7


@dataclass(frozen=True)
class _Relaxation:
    """Where the weight iteration got to: the estimate (shared, drag and pitch parameters), the weights at it,
    the weights per iteration, whether it settled, and the last evaluation as an optimiser's outcome."""

    params: dict
    weights: np.ndarray
    history: tuple
    iterations: int
    settled: bool
    outcome: Outcome | None


def _relax_by_gauss_newton(problem_at, coefficients: Sequence[str], params, weights, lower, upper,
                           max_iterations: int, tol: float) -> _Relaxation:
    """The weight iteration with one Gauss-Newton step per iteration instead of a solve.

    Each iteration evaluates the reduced problem once at the current estimate, with the C_L that drag and
    pitch read at that estimate. The blocks' projections do not depend on the weights (each has its own
    linear coefficients), so that one evaluation gives both the residual variances (the weights at this
    estimate) and the Jacobian of the Gauss-Newton step of the problem so weighted. The estimate, the weights
    and the C_L are updated together, instead of solving each iteration's problem to its optimum and then
    updating the weights and the C_L. The fixed point is the same: the weights are the residual variances'
    inverses, and the estimate minimises the problem with those weights and that C_L. On the default campaign
    this takes 4 evaluations where three solves and a confirming step took 15.

    It settles when the step and the weights' change are below ``tol`` (of the box, relatively). It stops
    unsettled (and the caller solves from there) when a step fails to shrink to ``CONTRACTION`` of the one
    before, or when an evaluation is not finite; the estimate is then the last one evaluated, not the
    step that failed to contract."""
    params = dict(params)
    history: list[dict] = []
    previous, start, outcome = None, None, None
    span = upper - lower
    for iteration in range(1, max_iterations + 1):
        problem, _, y = problem_at(params, np.ones(len(weights)))
        theta = np.array([params[n] for n in problem.nonlinear_names], float)
        start = theta if start is None else start
        with np.errstate(all="ignore"):
            reduced = problem.reduce(theta, y)
        if reduced is None:
            return _Relaxation(params, weights, tuple(history), iteration - 1, False, outcome)
        blocks = reduced.residual.reshape(problem.n_blocks, problem.n_samples)   # rows come block by block
        new = 1.0 / np.mean(blocks ** 2, axis=1)
        history.append(dict(zip(coefficients, map(float, new))))
        scale = np.repeat(np.sqrt(new), problem.n_samples)
        weighted = reduced.residual * scale
        step = np.linalg.lstsq(reduced.jacobian * scale[:, None], -weighted, rcond=None)[0]
        step = np.clip(theta + step, lower, upper) - theta
        moved = float(np.max(np.abs(step) / span))
        changed = float(np.max(np.abs(new / weights - 1.0)))
        params.update(dict(zip(problem.linear_names, reduced.coef)))
        settled = moved < tol and changed < tol
        outcome = Outcome(start=start, theta=theta, coef=reduced.coef, cost=float(0.5 * weighted @ weighted),
                          nfev=iteration, njev=iteration, status=1 if settled else 0,
                          message=(f"the weights and the estimate settled after {iteration} Gauss-Newton "
                                   f"iterations (the next step {moved:.2g} of the box, the weights' change "
                                   f"{changed:.2g})"), success=settled)
        weights = new
        if settled:
            return _Relaxation(params, weights, tuple(history), iteration, True, outcome)
        if previous is not None and moved > CONTRACTION * previous:
            return _Relaxation(params, weights, tuple(history), iteration, False, outcome)
        if iteration == max_iterations:
            break
        previous = moved
        params.update(dict(zip(problem.nonlinear_names, theta + step)))
    return _Relaxation(params, weights, tuple(history), max_iterations, False, outcome)


def joint_lift(joint: JointFit) -> JointLift:
    """The lift block of ``joint`` as the lift model of drag and pitch candidates (``search --joint-lift``): the
    lift structure at the joint estimate, and the joint estimator's influence series of the lift parameters on
    the training samples, psi_t = H^-1 (sum over sample t's rows of J_r e_r) restricted to them, for the
    candidates' two-step covariance. Parameters the joint fit cannot identify are left out (and named)."""
    lift = next((c for c in joint.candidates if c.coefficient == "CL"), None)
    if lift is None:
        raise DeclarationError(f"{joint.name} has no lift structure: drag and pitch would read a sequential lift "
                               "model, not a joint one")
    r, problem = joint.result, joint.problem
    theta = np.array([r.params[n] for n in problem.nonlinear_names])
    coef = np.array([r.params[n] for n in problem.linear_names])
    jac = model_jacobian(problem.evaluate(theta), coef, len(theta))
    names = r.names
    basis = np.asarray(r.covariance_basis, bool)
    psi = influence_series(jac[:, basis], np.asarray(r.residuals), r.jacobian_inverse_factor, problem.n_blocks)
    kept = [n for n, keep in zip(names, basis) if keep]
    own = [n for n in build_model(lift).nonlinear_names + build_model(lift).linear_names]
    columns = [kept.index(n) for n in own if n in kept]
    return JointLift(lift, {n: r.params[n] for n in own}, tuple(c.name for c in joint.candidates if c is not lift),
                     psi[:, columns], tuple(n for n in own if n in kept),
                     {n: why for n, why in r.not_identifiable.items() if n in own})


def _box(problem: JointProblem, models, train):
    """Each shared parameter's box: that of the first block that has it (the lift model's)."""
    lower, upper = {}, {}
    for m in models:
        lo, hi = m.bound_vectors(train)
        for n, a, b in zip(m.nonlinear_names, lo, hi):
            lower.setdefault(n, a)
            upper.setdefault(n, b)
    names = problem.nonlinear_names
    return np.array([lower[n] for n in names]), np.array([upper[n] for n in names])
