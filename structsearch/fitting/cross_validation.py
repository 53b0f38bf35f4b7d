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
    y = train[model.coefficient]
    # a linear model's rows (and a one-step fold's Jacobian rows) depend on no refitted state: holding out a
    # block of rows is exactly holding out those samples
    if not model.nonlinear_names:
        return held_out_residuals(model.bind(train).regression_matrix(np.zeros(0)), y, plan.bounds, plan.folds)
    if method == "one-step":
        jac, output = model.jacobian(train, result.params)
        # a parameter on a bound or not identifiable stays where the full fit left it (an approximation: a
        # fold's refit could move it inward, never past the bound; a step along a null direction is arbitrary)
        free = [i for i, n in enumerate(result.names) if n not in result.at_bound and n not in result.unidentifiable]
        return held_out_residuals(jac[:, free], y - output, plan.bounds, plan.folds)
    if plan.scheme == "blocks":
        return _blocked_refits(model, train, result, plan, y)
    folds = plan.maneuver_folds()
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


def _blocked_refits(model, train: FlightData, result, plan: FoldPlan, y: np.ndarray) -> np.ndarray:
    """Held-out residuals of blocked folds: each fold fitted on the outputs of the blocks it keeps, its states flown
    over the whole record (a block's inputs are not held out, only its outputs: no state restarts at a block's
    edge), and its held-out blocks predicted by the same flight with the fold's estimates."""
    residual = np.full_like(y, np.nan)
    start = model.inside(train, {k: result.params[k] for k in model.nonlinear_names})
    for held in plan.folds:
        keep = np.ones(len(y), bool)
        for i in held:
            keep[slice(*plan.units[i])] = False
        predicted = model.predict(train, model.estimate(train, start=start, rows=np.flatnonzero(keep)))
        residual[~keep] = y[~keep] - predicted[~keep]
    return residual
