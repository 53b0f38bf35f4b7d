"""The joint fit's covariance with the path through the C_L that drag and pitch read
(:mod:`structsearch.fitting.joint`): the weight iteration holds that C_L fixed within a step, while the residual
also moves with the lift parameters through it."""
from __future__ import annotations

from dataclasses import replace
from typing import Mapping

import numpy as np

from ..data.flightdata import FlightData
from ..engine.joint import JointProblem
from ..engine.results import FitResult
from ..engine.snls import model_jacobian
from .candidates import Candidate
from .models import build_model, with_lift_prediction


def lift_output_jacobian(problem: JointProblem, order, models, train: FlightData, lift_candidate: Candidate,
                         params: Mapping[str, float], jac: np.ndarray) -> np.ndarray:
    """K: the derivative of the joint model's (weighted, interleaved) output with respect to every parameter that
    reaches it through the C_L drag and pitch read, the path the stacked problem's Jacobian ``jac`` holds fixed.
    Block b's rows are sqrt(w_b) d pred_b / d C_L times d C_L / d theta_lift; the second factor is the lift
    block's own rows of ``jac`` (its model Jacobian, unweighted by 1 / sqrt(w_lift)), the first a central
    difference in the C_L column (exact for C_L and C_L^2 terms, which is what drag and pitch hold)."""
    names = tuple(problem.nonlinear_names) + tuple(problem.linear_names)
    lift_model = build_model(lift_candidate)
    lift_names = lift_model.nonlinear_names + lift_model.linear_names
    columns = [names.index(n) for n in lift_names if n in names]
    lift_b = next(b for b, c in enumerate(order) if c.coefficient == "CL")
    n_blocks = problem.n_blocks
    dcl = jac[lift_b::n_blocks, columns] / np.sqrt(problem.weights[lift_b])
    out = np.zeros_like(jac)
    seen = with_lift_prediction(train, {n: params[n] for n in lift_names}, lift_candidate)
    cl = np.asarray(seen["CL"], float)
    step = 1e-6 * max(1.0, float(np.sqrt(np.mean(cl ** 2))))
    for b, (c, m) in enumerate(zip(order, models)):
        if b == lift_b:
            continue
        own = {n: params[n] for n in m.nonlinear_names + m.linear_names}
        up = m.predict(seen.with_columns({**seen.columns, "CL": cl + step}), own)
        down = m.predict(seen.with_columns({**seen.columns, "CL": cl - step}), own)
        slope = (up - down) / (2.0 * step)
        out[b::n_blocks][:, columns] = np.sqrt(problem.weights[b]) * slope[:, None] * dcl
    return out


def through_the_lift_output(result: FitResult, problem: JointProblem, order, models, train: FlightData,
                            lift_candidate: Candidate) -> FitResult:
    """The joint covariance with the C_L path included. The weight iteration solves J^T r = 0 with J the stacked
    problem's Jacobian at a fixed C_L (drag and pitch read the lift block's output as data within a solve), while
    the residual also moves with the lift parameters through that C_L: the estimator's bread is H = J^T (J + K)
    (K: :func:`lift_output_jacobian`), not J^T J. Every covariance computed with the bread (J^T J)^-1 becomes
    T C T^T with T = H^-1 J^T J, whatever its meat. Without it the separation parameters' standard deviations were
    0.56-0.72 of their Monte Carlo spread on the calibration's held-out campaigns: drag and pitch were credited
    with information on the states that the C_L they read already carried. The reference degrees of freedom
    stay those of the uncorrected combination (each parameter's effective maneuvers)."""
    r = result
    names = r.names
    basis = np.asarray(r.covariance_basis, bool) if r.covariance_basis is not None else np.ones(len(names), bool)
    basis = basis & np.isfinite(np.diag(np.asarray(r.estimates.covariance, float)))   # estimable ones only
    k = len(problem.nonlinear_names)
    theta = np.array([r.params[n] for n in problem.nonlinear_names])
    coef = np.array([r.params[n] for n in problem.linear_names])
    jac = model_jacobian(problem.evaluate(theta), coef, k)
    extra = lift_output_jacobian(problem, order, models, train, lift_candidate, r.params, jac)
    j, e = jac[:, basis], extra[:, basis]
    a = j.T @ j
    try:
        t = np.linalg.solve(a + j.T @ e, a)
    except np.linalg.LinAlgError:
        # said, not hidden: the covariance stays the one conditional on the C_L drag and pitch read
        return replace(r, generated_regressors="NOT the C_L drag and pitch read: the bread J^T (J + K) is singular; "
                                               "conditional on that C_L")
    keep = np.ix_(basis, basis)

    def moved(cov):
        if cov is None:
            return None
        out = np.array(cov, float, copy=True)
        out[keep] = t @ out[keep] @ t.T
        return out

    said = "the C_L drag and pitch read, through the lift parameters (bread J^T (J + K))"
    return replace(r, covariance=moved(r.estimates.covariance), white_covariance=moved(r.estimates.white_covariance),
                   generated_regressors=said)
