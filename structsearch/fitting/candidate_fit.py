"""One candidate fitted as every command fits it: on the training maneuvers, scored on both splits
(and by cross-validation), drag and pitch candidates on their lift model with the two-step covariance.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..data.errors import StructSearchError
from ..data.flightdata import FlightData
from ..data.moment_transfer import REFERENCE_KEY
from ..engine.scores import ManeuverScores
from .candidate_result import NOT_APPLICABLE, CandidateResult, FailureKind, SplitScores
from .candidates import Candidate
from .centred_correlation import centred_correlation
from .cross_validation import cross_validate, refit_fold
from .flight_effects import missing_effects_warning
from .flight_effects_fit import EffectFit, effects_of, prepare
from .flight_effects_fit import cross_validate as cross_validate_effects
from .flight_effects_fit import split as split_effects
from .folds import UNITS_BELOW_MANEUVERS, FoldPlan, plan_folds, score_units
from .lift_context import lift_context
from .lift_fit import LiftFit
from .lift_uncertainty import with_lift_uncertainty
from .models import build_model, wing_aliases
from .options import FitOptions
from .specs import lift_candidate as named_lift
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


@dataclass(frozen=True)
class StartSpec:
    """Where a candidate's fit starts: ``start`` (a warm start: a donor's or a stage's estimates, None: the
    declared start), ``n_starts`` (None: the options'), ``declared_too`` (the declared start follows a warm
    start) and ``nested`` (a contained structure's optimum, one more start)."""

    start: Mapping[str, float] | None = None
    n_starts: int | None = None
    declared_too: bool = False
    nested: Mapping[str, float] | None = None


@dataclass(frozen=True)
class _Setup:
    """A candidate's model and the data it is fitted on (a drag or pitch candidate's: its lift model's context)."""

    model: object
    measured: FlightData
    train: FlightData
    validation: FlightData
    context: object | None


def _setup(c: Candidate, train: FlightData, validation: FlightData, lift: LiftFit | None) -> _Setup | str:
    """The model of ``c`` (bounded already) on its data, or why it does not apply to them."""
    model = build_model(c, lift)
    missing = [col for col in model.required_columns if col not in train and col not in train.constants]
    if REFERENCE_KEY in missing:  # a pitch candidate about the fixed point on a campaign without one
        return (f"{NOT_APPLICABLE}C_m about the fixed reference point needs [aircraft] {REFERENCE_KEY} in "
                "campaign.toml (or --reference-point)")
    if missing:  # e.g. a pitch candidate with x_cg terms on a campaign without x_cg
        return f"{NOT_APPLICABLE}the campaign has no column {', '.join(missing)}"
    context = None
    if c.lift and lift is not None:
        context = lift_context(train, validation, lift)
        return _Setup(model, train, context.train, context.validation, context)
    return _Setup(model, train, train, validation, None)


def _model_starts(model, train: FlightData, options: FitOptions, spec: StartSpec) -> dict:
    """The start arguments of ``model.fit`` (and ``model.start_points``) for ``spec``."""
    warm = model.inside(train, spec.start or {})  # a donor's or baseline's estimates, inside the bounds
    starts = options.n_starts if spec.n_starts is None else spec.n_starts
    return {"start": warm or None, "n_starts": starts if model.nonlinear_names else 1,
            "seed": options.seed, "declared_too": spec.declared_too,
            "more_starts": [model.inside(train, spec.nested)] if spec.nested and model.nonlinear_names else ()}


def fit_candidate(c: Candidate, train: FlightData, validation: FlightData, lift: LiftFit | None,
                  options: FitOptions, start: Mapping[str, float] | None = None, n_starts: int | None = None,
                  declared_too: bool = False, nested: Mapping[str, float] | None = None) -> CandidateResult:
    """Fit one candidate on the training maneuvers and score it on both splits; ``start`` (a warm start)
    is the first of ``n_starts`` starts (default ``options.n_starts``), followed by the declared start
    with ``declared_too``, and by ``nested`` (a contained structure's optimum, :func:`.staging.best_contained`).
    ``lift`` is the fitted lift model a drag or pitch candidate names. A failure
    that follows from the data or the declaration is returned as a failed result with its reason."""
    return fit_from(c, train, validation, lift, options, StartSpec(start, n_starts, declared_too, nested))[0]


def fit_from(c: Candidate, train: FlightData, validation: FlightData, lift: LiftFit | None, options: FitOptions,
             spec: StartSpec, solved=None, folds_apart: bool = False) -> tuple[CandidateResult, FoldPlan | None]:
    """:func:`fit_candidate` from ``spec``. ``solved``: the solves from every start of :func:`start_points`,
    run as tasks of their own (only the statistics and scores are computed here). With ``folds_apart`` a
    nonlinear candidate's refitted cross-validation folds are left to the caller (:func:`fold_residual`, a task
    each; :func:`with_folds` adds them): the result comes without them, with the plan they follow."""
    t0 = time.perf_counter()
    c = c.with_bounds(options.parameter_boxes)
    try:
        setup = _setup(c, train, validation, lift)
        if isinstance(setup, str):
            return CandidateResult.failure(name=c.name, grid=c.grid, coefficient=c.coefficient, lift=c.lift,
                                           seconds=time.perf_counter() - t0, error=setup,
                                           kind=FailureKind.NOT_APPLICABLE), None
        effects = prepare(c, options, setup.model, setup.train, setup.validation)
        if effects is not None:   # the effect columns on coded data; its starts and folds solved here
            setup = dataclasses.replace(setup, model=effects.model, train=effects.train,
                                        validation=effects.validation)
            solved, folds_apart = None, False
        model, train = setup.model, setup.train
        # with a lift model the two-step covariance replaces the fit's own: the fit computes the white one
        white = setup.context is not None or options.scores_only
        result = model.fit(train, **_model_starts(model, train, options, spec), solved=solved,
                           covariance="white" if white else options.covariance)
        if setup.context is not None and not options.scores_only:
            result = with_lift_uncertainty(result, model, setup.measured, lift, setup.context, options.covariance,
                                           predicted=train if effects is not None else None,
                                           aliases=wing_aliases(c))
        plan = plan_folds(train, options.cv_folds, options.cv_fold_size, options.cv_block_convective_times)
        apart = folds_apart and bool(plan.folds) and bool(model.nonlinear_names) and options.cv_method == "refit"
        cv = None
        if plan.folds and not apart:   # scored per unit held out: per maneuver, or per block of a record
            cv = (cross_validate(model, train, result, plan, options.cv_method) if effects is None
                  else cross_validate_effects(effects, result, plan))
        scored = _scored(c, setup, result, plan, options, cv, t0, effects)
        return scored, plan if apart else None
    except (StructSearchError, np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
        # the data or the declaration: kept in the cache; a bare ValueError may be the code's: fitted again
        from_question = isinstance(exc, (StructSearchError, np.linalg.LinAlgError, FloatingPointError))
        return CandidateResult.failure(name=c.name, grid=c.grid, coefficient=c.coefficient, lift=c.lift,
                                       error=f"{type(exc).__name__}: {exc}", seconds=time.perf_counter() - t0,
                                       kind=FailureKind.DATA if from_question else FailureKind.RETRIED), None


def _scored(c: Candidate, setup: _Setup, result, plan: FoldPlan, options: FitOptions, cv: np.ndarray | None,
            t0: float, effects: EffectFit | None = None) -> CandidateResult:
    """The candidate's record: its fit scored on both splits, and by its cross-validation's held-out residuals;
    with flight effects, its estimates apart from the flights' offsets."""
    model, train = setup.model, setup.train
    estimates, flight_effects, correlation_model = result.estimates, None, model
    if effects is not None:
        estimates, flight_effects = split_effects(effects, result.estimates, train.n_segments)
        correlation_model = effects.base_model
    warning = missing_effects_warning(c.regressors, c.coefficient, train, effects_of(c, options),
                                      fixed=c.moment_reference == "fixed")
    scores = {}
    if cv is not None:
        scores["cv"] = SplitScores.of(ManeuverScores.of(train[c.coefficient], cv, plan.slices()), None,
                                      _unit_scores(train, train[c.coefficient], cv, options, len(plan.units)))
    for split, data in (("train", train), ("validation", setup.validation)):
        y = data[c.coefficient]
        pred = model.predict(data, result.params)
        other = data["CL"] if c.lift and c.coefficient == "CD" else None  # the lift model's output
        units = _unit_scores(data, y, y - pred, options, data.n_segments) if split == "validation" else None
        scores[split] = SplitScores.of(ManeuverScores.of(y, y - pred, data.segment_slices()),
                                       body_axis_errors(c.coefficient, pred, data, other), units)
    record = CandidateResult.from_fit(name=c.name, grid=c.grid, coefficient=c.coefficient, lift=c.lift,
                                      result=result, train=scores["train"], validation=scores["validation"],
                                      cv=scores.get("cv"), cv_folds=plan.n_folds,
                                      # a linear candidate's folds are exact fits whichever method is asked
                                      cv_method=options.cv_method if model.nonlinear_names and plan.folds
                                      and effects is None else "refit", cv_scheme=plan.scheme, cv_note=plan.note,
                                      seconds=time.perf_counter() - t0,
                                      centred_correlation=None if options.scores_only else
                                      centred_correlation(c, correlation_model, train, estimates))
    return dataclasses.replace(record, estimates=estimates, flight_effects=flight_effects,
                               warnings=(warning,) if warning else ())


def _unit_scores(data: FlightData, y: np.ndarray, residual: np.ndarray, options: FitOptions,
                 n_units: int) -> tuple[ManeuverScores, str] | None:
    """The scores per unit smaller than a maneuver of a split whose held-out units are fewer than
    UNITS_BELOW_MANEUVERS (:func:`.folds.score_units`), and what the units are; None otherwise (or when no
    maneuver can be cut)."""
    if n_units >= UNITS_BELOW_MANEUVERS:
        return None
    rows, label = score_units(data, options.cv_block_convective_times)
    if not rows:
        return None
    return ManeuverScores.of(y, residual, [slice(a, b) for a, b in rows]), label


def start_points(c: Candidate, train: FlightData, options: FitOptions, spec: StartSpec) -> np.ndarray:
    """The starts the fit of ``c`` (without a lift model) from ``spec`` tries, in its order, one per row."""
    model = build_model(c.with_bounds(options.parameter_boxes))
    return model.start_points(train, **_model_starts(model, train, options, spec))


def solve_start(c: Candidate, train: FlightData, options: FitOptions, point: np.ndarray):
    """One start of ``c``'s fit (a row of :func:`start_points`): its local solve's outcome."""
    return build_model(c.with_bounds(options.parameter_boxes)).solve_from(train, point)


def fold_residual(c: Candidate, train: FlightData, options: FitOptions, params: Mapping[str, float],
                  plan: FoldPlan, fold: int) -> tuple[np.ndarray, np.ndarray]:
    """The held-out rows of fold ``fold`` and their residuals (the fold refitted from ``params``, the fit of
    every training maneuver): one fold of :func:`.cross_validation.cross_validate`, as a task of its own."""
    return refit_fold(build_model(c.with_bounds(options.parameter_boxes)), train, params, plan, fold)


def with_folds(result: CandidateResult, train: FlightData, plan: FoldPlan,
               parts: Sequence[tuple[np.ndarray, np.ndarray]], seconds: float,
               options: FitOptions) -> CandidateResult:
    """``result`` (fitted with ``folds_apart``) with its cross-validation scores from the folds' ``parts``."""
    y = train[result.coefficient]
    residual = np.full_like(y, np.nan)
    for rows, values in parts:
        residual[rows] = values
    cv = SplitScores.of(ManeuverScores.of(y, residual, plan.slices()), None,
                        _unit_scores(train, y, residual, options, len(plan.units)))
    return dataclasses.replace(result, cv=cv, seconds=result.seconds + seconds)


def stage_of(c: Candidate, options: FitOptions) -> tuple[Candidate, object] | None:
    """The quasi-steady stage a fit of ``c`` without a warm start climbs first, and its model (None: none)."""
    for stage in stages(c):
        return stage, build_model(stage.with_bounds(options.parameter_boxes))
    return None


def staged_spec(c: Candidate, options: FitOptions, start: Mapping[str, float] | None, *,
                declared_too: bool = True, nested: Mapping[str, float] | None = None,
                stage_params: Mapping[str, float] | None = None, stage_model=None) -> StartSpec:
    """Where :func:`fit_staged` starts ``c``: from a warm ``start`` (a donor's), else from its stage's estimates
    (``stage_params`` of ``stage_model``; None: no stage, or one the data could not fit)."""
    if start is not None:
        if options.scores_only:
            # a screening trusts one start: the contained structure's optimum when there is one (never worse than
            # that structure), else the warm start; the full fit of a structure worth it adds the others
            return StartSpec(nested or start, WARM_STARTS)
        return StartSpec(start, WARM_STARTS, declared_too, nested)
    if stage_params is not None:
        start = {k: stage_params[k] for k in stage_model.nonlinear_names}
        # the stage is c with its unsteady states quasi-steady: its optimum with tau1 at its nesting value is
        # c's point as good as the stage (the stage's tau2 alone, tau1 declared, may start c in another basin)
        if nested is None:
            nested = nested_start(c, stage_params)
    return StartSpec(start, None, declared_too and start is not None, nested)


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
    that the fit never ends above that structure's; a stage is contained in ``c``, so its estimates give one too.
    (:mod:`.candidate_job` runs the same fit as tasks: each start, each fold.)"""
    params, stage = None, stage_of(c, options) if start is None else None
    if stage is not None:
        try:
            params = stage[1].estimate(train, n_starts=stage_starts, seed=options.seed)
        except (StructSearchError, np.linalg.LinAlgError, FloatingPointError):
            params = None  # a stage the data cannot fit gives no start: c keeps its usual starts
    spec = staged_spec(c, options, start, declared_too=declared_too, nested=nested, stage_params=params,
                       stage_model=stage[1] if stage else None)
    return fit_from(c, train, validation, lift, options, spec)[0]


def fit_lift_model(c: Candidate, train: FlightData, validation: FlightData, options: FitOptions) -> LiftFit | None:
    """The fitted lift model a drag or pitch candidate names (None for a candidate without one)."""
    if not c.lift:
        return None
    lift_candidate = named_lift(c.lift)
    lift = fit_staged(lift_candidate, train, validation, None, options)
    if lift.failed:
        raise StructSearchError(f"fitting the lift model {c.lift} that {c.name} needs failed: {lift.error}")
    return LiftFit(lift_candidate, lift)
