"""Maneuver-grouped cross-validation of a fitted candidate over the training maneuvers."""
from __future__ import annotations

import numpy as np

from ..data.flightdata import FlightData
from ..engine.ols import held_out_residuals
from .options import CV_MIN_MANEUVERS


def maneuver_folds(n_maneuvers: int, folds: int) -> list[list[int]]:
    """Maneuver-grouped folds, round robin over the maneuvers in campaign order (which groups the
    kinds, so every fold sees every kind); [] when fewer than two folds of CV_MIN_MANEUVERS fit."""
    k = min(folds, n_maneuvers // CV_MIN_MANEUVERS)
    if k < 2:
        return []
    return [list(range(i, n_maneuvers, k)) for i in range(k)]


def cross_validate(model, train: FlightData, result, folds: list[list[int]], method: str = "refit") -> np.ndarray:
    """Held-out residuals of every training maneuver: each fold refitted on the other maneuvers and
    predicted on its own. A linear model's folds share one factorisation of its regressors
    (:func:`held_out_residuals`). A nonlinear model's fold is, with ``method`` "refit", one solve warm
    started from the full training fit; with "one-step", one Gauss-Newton step from it: the same
    least-squares problem on the full fit's Jacobian [dPhi/dtheta c, Phi] and residual, so that the
    folds share its factorisation too (for a linear model the step lands on the fold's exact fit);
    parameters on a bound or not identifiable are held at the full fit's values.
    Folds need estimates only: no statistics are computed for them.

    Drag and pitch candidates keep the separation states and C_L of the lift model fitted on all
    training maneuvers (held-out ones included): their comparison is conditional on that lift model,
    as their fits are; it is the same for every candidate of a grid, so it does not favour one."""
    y = train[model.coefficient]
    if not model.nonlinear_names:
        return held_out_residuals(model.bind(train).regression_matrix(np.zeros(0)), y, train.bounds, folds)
    if method == "one-step":
        jac, output = model.jacobian(train, result.params)
        # a parameter on a bound or not identifiable stays where the full fit left it (an approximation: a
        # fold's refit could move it inward, never past the bound; a step along a null direction is arbitrary)
        free = [i for i, n in enumerate(result.names) if n not in result.at_bound and n not in result.unidentifiable]
        return held_out_residuals(jac[:, free], y - output, train.bounds, folds)
    residual = np.empty_like(y)
    slices = train.segment_slices()
    warm = {k: result.params[k] for k in model.nonlinear_names}
    everything = range(len(slices))
    for held in folds:
        rest = [i for i in everything if i not in held]
        subset = train.select(rest)
        # the subset's default box may be narrower (alpha range flown): start inside it
        start = model.inside(subset, warm)
        predicted = model.predict(train.select(held), model.estimate(subset, start=start))
        at = 0
        for i in held:
            n = slices[i].stop - slices[i].start
            residual[slices[i]] = y[slices[i]] - predicted[at:at + n]
            at += n
    return residual
