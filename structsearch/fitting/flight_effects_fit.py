"""A candidate's fit with flight effects (:mod:`.flight_effects`): the effect columns on its data, the
cross-validation that codes each fold's own training flights, and the estimates split into the aerodynamic
parameters and the flight offsets."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..data.flightdata import FlightData
from .candidates import Candidate
from .flight_effects import (EffectDesign, FlightCoding, FlightEffects, design, design_warnings, maneuver_flights,
                             split_estimates)
from .folds import FoldPlan
from .options import FitOptions


def effects_of(c: Candidate, options: FitOptions) -> tuple[str, ...]:
    """The effects a fit of ``c`` estimates: those its spec entry declares, then those the options add."""
    return tuple(dict.fromkeys(tuple(c.flight_effects) + tuple(options.flight_effects)))


@dataclass(frozen=True)
class EffectFit:
    """What a fit with flight effects works on: the design, the model without and with the effect columns, and
    the training and validation data without and with the flights' codes."""

    design: EffectDesign
    base_model: object
    model: object
    train: FlightData        # coded
    validation: FlightData   # coded
    plain_train: FlightData  # without the codes (what each cross-validation fold codes again)


def prepare(c: Candidate, options: FitOptions, model, train: FlightData, validation: FlightData) -> EffectFit | None:
    """The :class:`EffectFit` of ``c`` (None: no effect is asked for; an effect asked for the whole grid that
    does not apply to ``c`` leaves an :class:`EffectFit` without columns, which records why)."""
    effects = effects_of(c, options)
    if not effects:
        return None
    d = design(effects, c.regressors, train, fixed=c.moment_reference == "fixed")
    if not d.effects:
        return EffectFit(d, model, model, train, validation, train)
    return EffectFit(d, model, d.model(model), d.coding.coded(train), d.coding.coded(validation), train)


def cross_validate(fit: EffectFit, result, plan: FoldPlan) -> np.ndarray:
    """Held-out residuals of every training sample, each fold refitted with the effects of its own training
    flights: a held-out maneuver of a flight the fold trains on takes that flight's offset, one of a flight it
    does not (every maneuver of that flight held out) zero offset. Blocked folds (within records) keep every
    flight, so the full fit's coding serves them."""
    from .cross_validation import cross_validate as plain
    if plan.scheme == "blocks" or not fit.design.effects:
        return plain(fit.model, fit.train, result, plan, "refit")
    train = fit.plain_train
    y = train[fit.model.coefficient]
    slices = train.segment_slices()
    warm = {k: result.params[k] for k in fit.model.nonlinear_names}
    residual = np.full_like(y, np.nan)
    for held in plan.folds:
        kept = train.select([i for i in range(len(slices)) if i not in held])
        out = train.select(list(held))
        if kept.flights is not None and len(dict.fromkeys(maneuver_flights(kept))) >= 2:
            coding = FlightCoding.of(kept)
            d = dataclasses.replace(fit.design, coding=coding)
            model, kept, out = d.model(fit.base_model), coding.coded(kept), coding.coded(out)
        else:   # a fold that trains on one flight: its offset is the model's own intercept
            model = fit.base_model
        params = model.estimate(kept, start=model.inside(kept, warm))
        rows = np.concatenate([np.arange(slices[i].start, slices[i].stop) for i in held])
        residual[rows] = y[rows] - model.predict(out, params)
    return residual


def split(fit: EffectFit, estimates, n_maneuvers: int):
    """The aerodynamic estimates and the :class:`.flight_effects.FlightEffects` of a fit's estimates."""
    d = fit.design
    warnings = design_warnings(d, len(fit.base_model.nonlinear_names) + len(fit.base_model.linear_names),
                               n_maneuvers) if d.effects else ()
    if not d.effects:
        return estimates, FlightEffects(d.coding.labels, (), d.skipped, warnings, reference=d.coding.labels[-1])
    return split_estimates(estimates, d, warnings)
