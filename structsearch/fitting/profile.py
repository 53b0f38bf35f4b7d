"""Profile intervals of a fitted candidate's nonlinear (separation) parameters (:mod:`structsearch.engine.profile`
does the work and says which statistic and why).

The candidate's model is bound to the training maneuvers as its fit saw them (a drag or pitch candidate: with
C_L replaced by its lift model's output, the lift model's separation parameters held), so the profile's
S_min is the fit's own residual sum of squares and its box the fit's. A drag or pitch candidate whose states
all come from its lift model has no nonlinear parameter of its own: its profile is empty.
"""
from __future__ import annotations

from typing import Sequence

from ..data.flightdata import FlightData
from ..engine.profile import LEVELS, Profiles, profile
from .candidate_result import CandidateResult
from .candidates import Candidate
from .lift_fit import LiftFit
from .models import build_model, with_lift_prediction


def profile_candidate(c: Candidate, result: CandidateResult, train: FlightData, lift: LiftFit | None = None,
                      names: Sequence[str] | None = None, levels: Sequence[float] = LEVELS) -> Profiles:
    """Profile intervals at ``levels`` of the nonlinear parameters ``names`` (default: all) of ``c`` fitted as
    ``result`` on ``train``; ``lift`` is the fitted lift model a drag or pitch candidate names."""
    if result.failed or result.estimates is None:
        raise ValueError(f"{c.name}: a failed fit has no profile ({result.error})")
    model = build_model(c, lift)
    seen = with_lift_prediction(train, lift.params, lift.candidate) if c.lift and lift is not None else train
    return profile(model.bind(seen), model.target(seen), result.estimates, names, levels=levels)
