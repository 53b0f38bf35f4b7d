"""The thesis' legacy estimator (chapter 8.1) against SNLS on the same data (the study's Table 7).

Legacy: each training maneuver on its own, every parameter (separation and aerodynamic) by bounded nonlinear
least squares from several quasi-random starts, the best start kept; the separation parameters averaged over
the maneuvers; then the aerodynamic (linear) parameters re-estimated by ordinary least squares on all training
maneuvers at those averages. SNLS: the whole training set at once, the linear parameters projected out, from
the same number of starts. Both run to the same tolerances; wall time is measured around each.

The drag and pitch structures are then fitted by OLS on each lift fit's separation states, so C_D, C_X, C_Z and
C_m compare the two lift estimates through everything that depends on them.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..data.campaign import Campaign
from ..data.errors import FitError
from ..data.flightdata import FlightData
from ..engine.fullnls import full_nls
from ..engine.snls import multistart, project, start_points
from ..engine.stallmodel import StallModel
from ..fitting.models import build_model, model_with_lift, with_lift_prediction
from ..fitting.specs import find_candidate
from .comparison import CoefficientScores, score_set

LEGACY = "legacy (per maneuver, averaged)"
SNLS = "SNLS"


@dataclass(frozen=True)
class LegacyFit:
    model: str
    params: dict[str, float]
    per_maneuver: tuple[dict[str, float], ...]   # the best start of each maneuver that any start fitted
    n_starts: int
    seconds: float

    def to_dict(self) -> dict:
        return {"model": self.model, "params": dict(self.params), "per_maneuver": [dict(p) for p in self.per_maneuver],
                "n_starts": self.n_starts, "seconds": self.seconds}


@dataclass(frozen=True)
class EstimatorComparison:
    """Table 7's counterpart: the same structures estimated both ways."""

    names: dict[str, str]                 # coefficient -> structure
    legacy: LegacyFit
    snls_params: dict[str, float]
    snls_seconds: float
    n_starts: int
    scores: tuple[CoefficientScores, ...]

    def to_dict(self) -> dict:
        return {"names": dict(self.names), "legacy": self.legacy.to_dict(), "snls_params": dict(self.snls_params),
                "snls_seconds": self.snls_seconds, "n_starts": self.n_starts,
                "scores": [s.to_dict() for s in self.scores]}


def legacy_fit(model: StallModel, data: FlightData, n_starts: int = 8, seed: int = 0) -> LegacyFit:
    """The legacy estimate of ``model`` on ``data`` (see the module docstring), from SNLS's start points (the
    declared start and scrambled Sobol points) in every maneuver."""
    t0 = time.perf_counter()
    lower, upper = model.bound_vectors(data)
    starts = start_points(model.start_vector(), lower, upper, n_starts, seed)
    per_maneuver = []
    for i in range(data.n_segments):
        sub = data.select([i])
        problem, y = model.bind(sub), sub[model.coefficient]
        best = None
        for start in starts:
            try:
                fit = full_nls(problem, y, start, lower, upper)
            except (ValueError, np.linalg.LinAlgError, FloatingPointError):
                continue   # a start the maneuver's data cannot evaluate; the others stand
            if np.isfinite(fit.rss) and (best is None or fit.rss < best.rss):
                best = fit
        if best is not None:
            per_maneuver.append({**dict(zip(model.nonlinear_names, map(float, best.theta))),
                                 **dict(zip(model.linear_names, map(float, best.coef)))})
    if not per_maneuver:
        raise FitError(f"legacy estimator of {model.name}: no start produced a fit on any maneuver")
    theta = np.array([np.mean([p[n] for p in per_maneuver]) for n in model.nonlinear_names])
    y = data[model.coefficient]
    coef = project(model.bind(data).evaluate(theta).phi, y).coef
    params = {**dict(zip(model.nonlinear_names, map(float, theta))), **dict(zip(model.linear_names, map(float, coef)))}
    return LegacyFit(model.name, params, tuple(per_maneuver), n_starts, time.perf_counter() - t0)


def compare_estimators(campaign: Campaign, names: dict[str, str], n_starts: int = 8, seed: int = 0,
                       progress: Callable[[str], None] | None = None) -> EstimatorComparison:
    """Legacy against SNLS for the lift structure ``names["CL"]``; drag and pitch by OLS on each one's states."""
    say = progress or (lambda m: None)
    train = campaign.split("train")
    lift_candidate = find_candidate(names["CL"])
    lift_model = build_model(lift_candidate)
    say(f"study: legacy estimator of {names['CL']} ({train.n_segments} maneuvers x {n_starts} starts)")
    legacy = legacy_fit(lift_model, train, n_starts, seed)
    say(f"study: SNLS of {names['CL']} ({n_starts} starts)")
    # the solver alone from the same start points, as the legacy estimator has no covariance to compute either
    t0 = time.perf_counter()
    lower, upper = lift_model.bound_vectors(train)
    best = multistart(lift_model.bind(train), train[lift_model.coefficient], lift_model.start_vector(), lower,
                      upper, n_starts=n_starts, seed=seed).best
    snls_seconds = time.perf_counter() - t0
    snls_params = {**dict(zip(lift_model.nonlinear_names, map(float, best.theta))),
                   **dict(zip(lift_model.linear_names, map(float, best.coef)))}
    scores = []
    for label, params in ((LEGACY, legacy.params), (SNLS, snls_params)):
        fitted = {}
        for coefficient in ("CD", "Cm"):
            c = find_candidate(names[coefficient])
            model = model_with_lift(c, params)
            data = with_lift_prediction(train, params, lift_candidate)
            if any(col not in data and col not in data.constants for col in model.required_columns):
                continue   # e.g. an x_cg term on a campaign without x_cg
            fitted[coefficient] = (c, model, model.fit(data).params)

        def predict(coefficient, data, params=params, fitted=fitted):
            if coefficient == "CL":
                return lift_model.predict(data, params)
            if coefficient not in fitted:
                return None
            _, model, p = fitted[coefficient]
            return model.predict(with_lift_prediction(data, params, lift_candidate), p)

        scores += score_set(label, predict, campaign)
    return EstimatorComparison(dict(names), legacy, snls_params, snls_seconds, n_starts, tuple(scores))
