"""The diagnosis at the state level: the validation maneuvers replayed through the simulator with the model
before and after the first adopted effect, and the RMS state errors of both.

A replay that diverges (a state not finite, or alpha more than
:data:`structsearch.flight.replay.DIVERGED_ALPHA` from the measurement) is not a state error to average: the
maneuver is named, with where and in which state it left, and left out of both RMS (the same maneuvers before
and after).
(Issue 31: the story printed "replayed alpha RMS 0.78 rad" for a replay that had diverged.)"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..data.campaign import Campaign
from ..data.coefficients import COEFFICIENTS, LIFT, LONGITUDINAL
from ..data.errors import DeclarationError
from ..engine.regressors import declare, symbol_names
from ..fitting.candidate_fit import fit_candidate
from ..fitting.lift_fit import LiftFit
from ..fitting.models import build_model
from ..fitting.options import FitOptions
from ..fitting.specs import find_candidate
from ..flight.reference import FINAL_MODEL_NAMES
from .fitted import Fitted
from .results import STATES, Divergence, StateLevel, StateRms

def divergence(run) -> Divergence | None:
    """Where and why a replay diverged (None when it did not): :func:`structsearch.flight.replay.divergence`."""
    from ..flight.replay import divergence as where
    found = where(run)
    return None if found is None else Divergence(run.name, *found)


def _other_coefficient(campaign: Campaign, other: str, lift_fit: LiftFit, options: FitOptions):
    """The thesis' final structure of ``other`` on ``lift_fit``'s states, refitted on the training maneuvers: its
    model and its linear estimates. Terms on states this lift model does not have, or on columns the campaign
    lacks (x_cg), are left out (before and after alike)."""
    lift_cand = lift_fit.candidate
    structure = find_candidate(FINAL_MODEL_NAMES[other])
    symbols = [f"X_{n}" if n else "X" for n, _ in lift_cand.states]
    have = set(campaign.data.columns) | set(campaign.data.constants) | set(symbols)
    kept = []
    for name, text in structure.regressors:
        try:
            declare(name, text, states=symbols)
        except DeclarationError:
            continue
        if set(symbol_names(text)) <= have | {"CL"}:
            kept.append((name, text))
    structure = dataclasses.replace(structure, regressors=tuple(kept), states=lift_cand.states,
                                    lift=lift_cand.name, bounds=lift_cand.bounds)
    s = fit_candidate(structure, campaign.split("train"), campaign.split("validation"), lift_fit, options)
    if s.failed:
        raise DeclarationError(f"state-level comparison: {s.error}")
    linear = {k: v for k, v in s.estimates.params.items() if k not in lift_fit.result.estimates.nonlinear_names}
    return build_model(structure, lift_fit), linear


def _simulator(campaign: Campaign, fitted: Fitted, lift, options: FitOptions):
    """The simulator of the three coefficients with ``fitted`` as the diagnosed one: its lift model is the
    diagnosed one, or the lift model the drag or pitch candidate names (``lift``)."""
    from ..flight.aero import AeroModel
    coef = fitted.candidate.coefficient
    lift_fit = LiftFit(fitted.candidate, fitted.summary) if COEFFICIENTS[coef].owns_states else lift
    models, params = {LIFT.name: build_model(lift_fit.candidate)}, dict(lift_fit.params)
    for other in (c for c in LONGITUDINAL if not COEFFICIENTS[c].owns_states):
        if other == coef:
            models[other] = build_model(fitted.candidate, lift)
            params.update(fitted.summary.estimates.params)
        else:
            models[other], linear = _other_coefficient(campaign, other, lift_fit, options)
            params.update(linear)
    # the simulator takes lift, drag and pitch in the registry's order
    return AeroModel(*(models[c] for c in LONGITUDINAL), params, name=fitted.candidate.name)


def state_level(campaign: Campaign, before: Fitted, after: Fitted, lift, options: FitOptions,
                window_s: float = 5.0, lift_after=None) -> StateLevel:
    """Forward-simulated state error on the validation maneuvers with the model before and after.

    The diagnosed coefficient uses the baseline (before) or improved (after) fit; the other two use
    the final structures of the thesis refitted on the training maneuvers with the same separation
    states, so that the three form one simulator. ``lift`` is the lift model the baseline reads; ``lift_after``
    the one the model after the effect reads, when the effect changed it (a drag model fed another lift model).
    """
    from ..flight.replay import replay
    val = campaign.split("validation")
    runs, diverged = {}, {}
    for label, fitted, read in (("before", before, lift), ("after", after, lift_after or lift)):
        with np.errstate(all="ignore"):   # a diverging replay overflows; it is named below, not warned about
            runs[label] = replay(val, _simulator(campaign, fitted, read, options), window_s=window_s)
        diverged[label] = tuple(d for d in map(divergence, runs[label]) if d is not None)
    # both RMS over the same maneuvers: those neither model diverged on (a model that diverges on the hardest one
    # must not look better for it)
    gone = {d.maneuver for ds in diverged.values() for d in ds}
    rms = {}
    for label, label_runs in runs.items():
        kept = [r for r in label_runs if r.name not in gone]
        n = sum(len(r.t) for r in kept)
        rms[label] = StateRms(*(float(np.sqrt(sum(r.rms[s] ** 2 * len(r.t) for r in kept) / n)) if n
                                else float("nan") for s in STATES))
    b, a = rms["before"], rms["after"]
    reduction = StateRms(*(1 - a[s] / b[s] if b[s] > 0 else float("nan") for s in STATES))
    return StateLevel(b, a, window_s, reduction, diverged_before=diverged["before"],
                      diverged_after=diverged["after"])
