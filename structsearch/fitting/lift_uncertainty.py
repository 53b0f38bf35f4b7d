"""Standard errors of drag and pitch candidates that include the lift model's estimation error.

A drag or pitch candidate is fitted with the lift model's separation parameters
held fixed and with C_L replaced by the lift model's output (:mod:`.candidate_fit`). Its
one-step covariance is therefore conditional on the lift estimates. This module
replaces it by the two-step covariance of :mod:`structsearch.engine.twostep`,
which needs three things at the estimates: the lift model's Jacobian and residual
on the training maneuvers, the candidate's own Jacobian, and the sensitivity of
the candidate's output to every lift parameter. The sensitivity is analytic (the
chain rule through the shared separation states and through the C_L column, see
:func:`lift_sensitivity`); a test checks it against central differences.
"""
from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Mapping

import numpy as np

from ..data.flightdata import FlightData
from ..engine.identifiability import covariance_basis
from ..engine.results import FitResult
from ..engine.snls import model_jacobian
from ..engine.stallmodel import StallModel
from ..engine.statistics import Covariances, covariance_kind, flight_count
from ..engine.twostep import generated_regressor_covariance, influence_covariance

if TYPE_CHECKING:
    from .lift_context import LiftContext
    from .lift_fit import LiftFit


def lift_sensitivity(model: StallModel, params: dict, predicted: FlightData, lift_jacobian: np.ndarray,
                     lift_names, lift_params: dict, names, aliases: Mapping[str, str] | None = None) -> np.ndarray:
    """d (candidate output) / d (lift parameter), one column per name in ``names``.

    ``model`` is the candidate with the lift model's separation parameters fixed, ``predicted`` the data
    it was fitted on (column CL is the lift model's output) and ``lift_jacobian`` the lift model's
    Jacobian on it, one column per name in ``lift_names``. The lift model reaches the candidate two ways,
    so by the chain rule the sensitivity is the candidate's derivative in the shared separation
    parameters (its regressors' state derivatives, with the states' own sensitivities) plus its
    derivative in the C_L column times the lift model's Jacobian. ``aliases``: a parameter of ``model`` -> the
    lift model's it copies under another name (a wing state's: :func:`.models.wing_aliases`).
    """
    m = predicted.n_samples
    coef = np.array([params[n] for n in model.linear_names], float)
    free = dataclasses.replace(model, fixed={})  # the shared separation parameters, now with derivatives
    problem = free.bind(predicted)
    # a wing state's parameters are the lift model's wing state's: each moves with the parameter it copies
    lift_name = dict(aliases or {})
    theta = np.array([lift_params[lift_name.get(n, n)] for n in free.nonlinear_names], float)
    through_states = model_jacobian(problem.evaluate(theta), coef, len(theta))[:, :len(theta)]
    x_values = {sym: v[1] for sym, v in problem.state_values(theta, False).items()}
    d_output_d_cl = sum((c * reg.column_derivative("CL", predicted, x_values, m)
                         for c, reg in zip(coef, model.regressors)), np.zeros(m))
    if model.offset is not None:   # a known term that reads the lift model's C_L (the moment transfer) moves too
        d_output_d_cl = d_output_d_cl + model.offset.column_derivative("CL", predicted, {}, m)
    lift_names = list(lift_names)
    cols = []
    for name in names:
        col = d_output_d_cl * lift_jacobian[:, lift_names.index(name)]
        for j, own in enumerate(free.nonlinear_names):
            if lift_name.get(own, own) == name:
                col = col + through_states[:, j]
        cols.append(col)
    return np.column_stack(cols)


def with_lift_uncertainty(result: FitResult, model: StallModel, train: FlightData, lift: "LiftFit",
                          context: "LiftContext", kind: str | None = None,
                          predicted: FlightData | None = None, aliases: Mapping[str, str] | None = None) -> FitResult:
    """``result`` of ``model`` (a drag or pitch candidate with the lift states fixed) with the two-step
    covariance of ``kind`` (default: the one ``result`` has). ``train`` is the training data as measured;
    ``context`` the lift model's :class:`~structsearch.fitting.lift_context.LiftContext` (its Jacobian,
    residual and covariance basis on ``train``, and the training data with C_L replaced by its output, as
    the fit saw it). The two-step covariance replaces the fit's own, so the fit may as well have
    computed the white one only (which is kept). ``predicted``: the data the fit saw when they differ from the
    context's training data (the same with the flight-effect codes added, :mod:`.flight_effects`).
    """
    kind = result.covariance_kind if kind is None else kind
    predicted = context.train if predicted is None else predicted
    jac1, residual1, basis1 = context.jacobian, context.residual, context.basis
    jac2, _ = model.jacobian(predicted, result.params)
    # the fit's own basis and factor when it kept them (the same Jacobian: it was fitted on ``predicted``)
    basis2, r2_inv = result.covariance_basis, result.jacobian_inverse_factor
    if basis2 is None:
        basis2 = covariance_basis(jac2, result.names, dict(result.unidentifiable), len(result.nonlinear_names))
        r2_inv = None
    sensitivity = lift_sensitivity(model, result.params, predicted, jac1, context.names, lift.params,
                                   [n for n, keep in zip(context.names, basis1) if keep], aliases)
    cov = np.full((result.n_params, result.n_params), np.nan)
    if context.influence is None:
        block, lags, bandwidth, effective_block = generated_regressor_covariance(
            jac2[:, basis2], result.residuals, jac1[:, basis1], residual1, sensitivity, train.bounds,
            kind, a1_inv=context.jacobian_inverse_factor, r2_inv=r2_inv, flights=train.flights)
        first = "two-step, Murphy-Topel"
    else:  # a joint lift: the joint fit is the first step, given by its influence series
        block, lags, bandwidth, effective_block = influence_covariance(
            jac2[:, basis2], result.residuals, context.influence, sensitivity, train.bounds, kind, r2_inv=r2_inv,
            flights=train.flights)
        first = "the joint fit's influence, Murphy-Topel"
    cov[np.ix_(basis2, basis2)] = block
    effective = np.full(result.n_params, np.nan)
    effective[basis2] = effective_block
    estimate = Covariances(cov, result.white_covariance, lags, bandwidth, effective).without(
        [i for i, n in enumerate(result.names) if n in result.unidentifiable])
    return dataclasses.replace(
        result, covariance=estimate.covariance, covariance_kind=kind, max_lag=estimate.max_lag,
        bandwidth=estimate.bandwidth,
        effective_maneuvers=estimate.effective_maneuvers,
        n_flights=(flight_count(train.flights, train.n_segments)
                   if covariance_kind(kind).by_flight and train.flights is not None else None),
        generated_regressors=f"includes the estimation error of the lift model {lift.name} ({first})")
