"""The candidate fits a diagnosis compares: each candidate fitted on the training maneuvers with its residual on
both splits, and the separation state that defines a model's flight phases."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.errors import DeclarationError
from ..data.flightdata import FlightData
from ..engine.separation import static_separation
from ..engine.static_forms import static_value
from ..fitting.candidate_fit import fit_candidate
from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
from ..fitting.lift_fit import LiftFit
from ..fitting.models import predict_candidate
from ..flight.reference import FINAL_LIFT


@dataclass
class Fitted:
    candidate: Candidate
    summary: CandidateResult
    residual: np.ndarray        # validation residual
    train_residual: np.ndarray  # training residual


def fit(c: Candidate, train: FlightData, val: FlightData, lift, options, start=None) -> Fitted:
    summary = fit_candidate(c, train, val, lift, options, start=start)
    if summary.failed:
        raise DeclarationError(f"fitting {c.name} failed: {summary.error}")
    pred = predict_candidate(c, summary.estimates.params, val, lift)
    pred_train = predict_candidate(c, summary.estimates.params, train, lift)
    return Fitted(c, summary, val[c.coefficient] - pred, train[c.coefficient] - pred_train)


def state_for_phases(c: Candidate, summary: CandidateResult, lift: LiftFit | None,
                     data: FlightData) -> np.ndarray:
    """The separation state that defines flight phases: the model's first state, or a static stall-strip
    curve from the lift fit; without any, the thesis' stall-strip curve."""
    params = summary.estimates.params if not c.lift else (lift.params if lift is not None else {})
    for state in c.separation_states:
        shape = [p for p in state.base_parameters if p not in ("tau1", "tau2")]
        if all(state.parameter_name(p) in params for p in shape):
            return static_value(state.form, data["alpha"], {p: params[state.parameter_name(p)] for p in shape})
    return static_separation(data["alpha"], FINAL_LIFT["a1_ss"], FINAL_LIFT["a_star_ss"])
