"""Cross-validation of a fitted candidate over its training maneuvers: maneuver-grouped folds, or blocked folds
of contiguous time within one or two long records (how the folds are formed: :mod:`.folds`)."""
from __future__ import annotations

import numpy as np

from ..data.flightdata import FlightData
from ..engine.ols import held_out_residuals
from .folds import FoldPlan, maneuver_plan
from .options import CV_MIN_MANEUVERS


def maneuver_folds(n_maneuvers: int, folds: int, fold_size: int = CV_MIN_MANEUVERS) -> list[list[int]]:
    """Maneuver-grouped folds, round robin over the maneuvers in campaign order (which groups the
    kinds, so every fold sees every kind); [] when fewer than two folds of ``fold_size`` maneuvers fit."""
    k = min(folds, n_maneuvers // max(fold_size, 1))
    if k < 2:
        return []
    return [list(range(i, n_maneuvers, k)) for i in range(k)]


def cross_validate(model, train: FlightData, result, folds: FoldPlan | list[list[int]],
                   method: str = "refit") -> np.ndarray:
    """Held-out residuals of every training sample: each fold refitted on the rest and predicted on what it holds
    out. ``folds``: a :class:`~.folds.FoldPlan` (maneuvers or blocks of records), or lists of maneuver indices.
    A linear model's folds share one factorisation of its regressors (:func:`held_out_residuals`). A nonlinear
    model's fold is, with ``method`` "refit", one solve warm started from the full training fit (a blocked fold:
    on the outputs of the kept blocks, its states flown over the whole record); with "one-step", one
    Gauss-Newton step from it: the same least-squares problem on the full fit's Jacobian [dPhi/dtheta c, Phi]
    and residual, so that the folds share its factorisation too (for a linear model the step lands on the
    fold's exact fit);
    parameters on a bound or not identifiable are held at the full fit's values.
    Folds need estimates only: no statistics are computed for them.

    Drag and pitch candidates keep the separation states and C_L of the lift model fitted on all
    training maneuvers (held-out ones included): their comparison is conditional on that lift model,
    as their fits are; it is the same for every candidate of a grid, so it does not favour one."""
    plan = folds if isinstance(folds, FoldPlan) else maneuver_plan(train, folds)
    y = model.target(train)   # a model with a known offset: its regressors fit the coefficient less the offset
    # a linear model's rows (and a one-step fold's Jacobian rows) depend on no refitted state: holding out a
    # block of rows is exactly holding out those samples
    if not model.nonlinear_names:
        return held_out_residuals(model.bind(train).regression_matrix(np.zeros(0)), y, plan.bounds, plan.folds)
    if method == "one-step":
        jac, output = model.jacobian(train, result.params)
        # a parameter on a bound or not identifiable stays where the full fit left it (an approximation: a
        # fold's refit could move it inward, never past the bound; a step along a null direction is arbitrary)
        free = [i for i, n in enumerate(result.names) if n not in result.at_bound and n not in result.unidentifiable]
        # the output holds the offset too: the residual is the coefficient's
        return held_out_residuals(jac[:, free], train[model.coefficient] - output, plan.bounds, plan.folds)
    residual = np.full_like(y, np.nan)
    for fold in range(plan.n_folds):
        rows, values = refit_fold(model, train, result.params, plan, fold)
        residual[rows] = values
    return residual


def refit_fold(model, train: FlightData, params, plan: FoldPlan, fold: int) -> tuple[np.ndarray, np.ndarray]:
    """Fold ``fold`` of a refitted cross-validation: the rows it holds out and their residuals. It is one solve
    warm started from ``params`` (the fit of every training maneuver): on the maneuvers it keeps, or (blocked
    folds) on the outputs of the blocks it keeps, its states flown over the whole record (a block's inputs are not
    held out, only its outputs: no state restarts at a block's edge), the held-out blocks predicted by the same
    flight with the fold's estimates."""
    y = train[model.coefficient]
    warm = {k: params[k] for k in model.nonlinear_names}
    held = plan.folds[fold]
    if plan.scheme == "blocks":
        keep = np.ones(len(y), bool)
        for i in held:
            keep[slice(*plan.units[i])] = False
        start = model.inside(train, warm)
        predicted = model.predict(train, model.estimate(train, start=start, rows=np.flatnonzero(keep)))
        rows = np.flatnonzero(~keep)
        return rows, y[rows] - predicted[rows]
    slices = train.segment_slices()
    subset = train.select([i for i in range(len(slices)) if i not in held])
    # the subset's default box may be narrower (alpha range flown): start inside it
    predicted = model.predict(train.select(list(held)), model.estimate(subset, start=model.inside(subset, warm)))
    rows = np.concatenate([np.arange(slices[i].start, slices[i].stop) for i in held])
    return rows, y[rows] - predicted
