"""One candidate fitted as every command fits it: on the training maneuvers, scored on both splits
(and by cross-validation), drag and pitch candidates on their lift model with the two-step covariance.
"""
from __future__ import annotations

import time
from typing import Mapping

import numpy as np

from ..data.errors import StructSearchError
from ..data.flightdata import FlightData
from ..engine.scores import ManeuverScores
from .candidate_result import CandidateResult, SplitScores
from .candidates import Candidate
from .centred_correlation import centred_correlation
from .cross_validation import cross_validate
from .folds import plan_folds
from .lift_context import lift_context
from .lift_fit import LiftFit
from .lift_uncertainty import with_lift_uncertainty
from .models import build_model
from .options import FitOptions
from .specs import load_grid
from .staging import nested_start, STAGE_STARTS, WARM_STARTS, stages


def body_axis_errors(coef: str, predicted: np.ndarray, data: FlightData,
                     other: np.ndarray | None) -> tuple[float, float] | None:
    """MSE of the body-axis C_X and C_Z derived from a lift or drag prediction and the other coefficient
    (predicted, or measured when ``other`` is None); None for a pitch prediction, and where the data lack the
    measured coefficients they need (a wind-tunnel record of C_L alone: a fit needs only what it models)."""
    needed = ("CD",) if coef == "CL" else ("CL", "CD")
    if any(c not in data for c in needed):
        return None
    alpha = data["alpha"]
    if coef == "CL":
        cl, cd = predicted, (other if other is not None else data["CD"])
    elif coef == "CD":
        cd, cl = predicted, (other if other is not None else data["CL"])
    else:
        return None
    cx = -cd * np.cos(alpha) + cl * np.sin(alpha)
    cz = -cl * np.cos(alpha) - cd * np.sin(alpha)
    cl_meas = data["CL_measured"] if "CL_measured" in data else data["CL"]
    mx = data["CX"] if "CX" in data else -data["CD"] * np.cos(alpha) + cl_meas * np.sin(alpha)
    mz = data["CZ"] if "CZ" in data else -cl_meas * np.cos(alpha) - data["CD"] * np.sin(alpha)
    return float(np.mean((cx - mx) ** 2)), float(np.mean((cz - mz) ** 2))


def fit_candidate(c: Candidate, train: FlightData, validation: FlightData, lift: LiftFit | None,
                  options: FitOptions, start: Mapping[str, float] | None = None, n_starts: int | None = None,
                  declared_too: bool = False, nested: Mapping[str, float] | None = None) -> CandidateResult:
    """Fit one candidate on the training maneuvers and score it on both splits; ``start`` (a warm start)
    is the first of ``n_starts`` starts (default ``options.n_starts``), followed by the declared start
    with ``declared_too``, and by ``nested`` (a contained structure's optimum, :func:`.staging.best_contained`).
    ``lift`` is the fitted lift model a drag or pitch candidate names. A failure
    that follows from the data or the declaration is returned as a failed result with its reason."""
    t0 = time.perf_counter()
    c = c.with_bounds(options.parameter_boxes)
    try:
        model = build_model(c, lift)
        missing = [col for col in model.required_columns if col not in train and col not in train.constants]
        if missing:  # e.g. a pitch candidate with x_cg terms on a campaign without x_cg
            return CandidateResult.failure(
                name=c.name, grid=c.grid, coefficient=c.coefficient, lift=c.lift, seconds=time.perf_counter() - t0,
                error=f"not applicable: the campaign has no column {', '.join(missing)}")
        measured, context = train, None
        if c.lift and lift is not None:
            context = lift_context(train, validation, lift)
            train, validation = context.train, context.validation
        warm = model.inside(train, start or {})  # a donor's or baseline's estimates, inside the bounds
        starts = options.n_starts if n_starts is None else n_starts
        # with a lift model the two-step covariance replaces the fit's own: the fit computes the white one
        result = model.fit(train, start=warm or None, n_starts=starts if model.nonlinear_names else 1,
                           seed=options.seed,
                           covariance="white" if context is not None or options.scores_only else options.covariance,
                           declared_too=declared_too,
                           more_starts=[model.inside(train, nested)] if nested and model.nonlinear_names else ())
        if context is not None and not options.scores_only:
            result = with_lift_uncertainty(result, model, measured, lift, context, options.covariance)
        scores = {}
        plan = plan_folds(train, options.cv_folds, options.cv_fold_size, options.cv_block_convective_times)
        if plan.folds:   # scored per unit held out: per maneuver, or per block of a record
            y = train[c.coefficient]
            scores["cv"] = SplitScores.of(ManeuverScores.of(y, cross_validate(model, train, result, plan,
                                                                              options.cv_method),
                                                            plan.slices()), None)
        for split, data in (("train", train), ("validation", validation)):
            y = data[c.coefficient]
            pred = model.predict(data, result.params)
            other = data["CL"] if c.lift and c.coefficient == "CD" else None  # the lift model's output
            scores[split] = SplitScores.of(ManeuverScores.of(y, y - pred, data.segment_slices()),
                                           body_axis_errors(c.coefficient, pred, data, other))
        return CandidateResult.from_fit(name=c.name, grid=c.grid, coefficient=c.coefficient, lift=c.lift,
                                        result=result, train=scores["train"], validation=scores["validation"],
                                        cv=scores.get("cv"), cv_folds=plan.n_folds,
                                        # a linear candidate's folds are exact fits whichever method is asked
                                        cv_method=options.cv_method if model.nonlinear_names and plan.folds
                                        else "refit", cv_scheme=plan.scheme, cv_note=plan.note,
                                        seconds=time.perf_counter() - t0,
                                        centred_correlation=None if options.scores_only else
                                        centred_correlation(c, model, train, result))
    except (StructSearchError, np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
        return CandidateResult.failure(name=c.name, grid=c.grid, coefficient=c.coefficient, lift=c.lift,
                                       error=f"{type(exc).__name__}: {exc}", seconds=time.perf_counter() - t0)


def fit_staged(c: Candidate, train: FlightData, validation: FlightData, lift: LiftFit | None,
               options: FitOptions, start: Mapping[str, float] | None = None, *,
               stage_starts: int = STAGE_STARTS, declared_too: bool = True,
               nested: Mapping[str, float] | None = None) -> CandidateResult:
    """:func:`fit_candidate` from a warm start (a donor's estimates) and the declared start when a warm
    start is given. Else from ``options.n_starts`` starts (declared and quasi-random) plus, for a
    candidate with unsteady states, the estimates of its quasi-steady stage (:func:`.staging.stages`,
    fitted from ``stage_starts`` starts: :data:`.staging.STAGE_STARTS` unless a caller asks for fewer).
    Without ``declared_too`` the declared start does not follow a warm start or the stage's estimates
    (a single fit that trusts its stage; the search always keeps it); nor does it follow a warm start in a
    screening (``options.scores_only``: the structure search's first look at a child of a fitted parent).
    ``nested``: a contained structure's optimum (its time constants at their nesting values), one more start, so
    that the fit never ends above that structure's; a stage is contained in ``c``, so its estimates give one too."""
    if start is not None:
        if options.scores_only:
            # a screening trusts one start: the contained structure's optimum when there is one (never worse than
            # that structure), else the warm start; the full fit of a structure worth it adds the others
            return fit_candidate(c, train, validation, lift, options, start=nested or start, n_starts=WARM_STARTS)
        return fit_candidate(c, train, validation, lift, options, start=start, n_starts=WARM_STARTS,
                             declared_too=declared_too, nested=nested)
    for stage in stages(c):
        model = build_model(stage.with_bounds(options.parameter_boxes))
        try:
            params = model.estimate(train, n_starts=stage_starts, seed=options.seed)
        except (StructSearchError, np.linalg.LinAlgError, FloatingPointError):
            break  # a stage the data cannot fit gives no start: c keeps its usual starts
        start = {k: params[k] for k in model.nonlinear_names}
        # the stage is c with its unsteady states quasi-steady: its optimum with tau1 at its nesting value is
        # c's point as good as the stage (the stage's tau2 alone, tau1 declared, may start c in another basin)
        if nested is None:
            nested = nested_start(c, params)
    return fit_candidate(c, train, validation, lift, options, start=start,
                         declared_too=declared_too and start is not None, nested=nested)


def fit_lift_model(c: Candidate, train: FlightData, validation: FlightData, options: FitOptions) -> LiftFit | None:
    """The fitted lift model a drag or pitch candidate names (None for a candidate without one)."""
    if not c.lift:
        return None
    lift_candidate = load_grid("lift")[c.lift]
    lift = fit_staged(lift_candidate, train, validation, None, options)
    if lift.failed:
        raise StructSearchError(f"fitting the lift model {c.lift} that {c.name} needs failed: {lift.error}")
    return LiftFit(lift_candidate, lift)
