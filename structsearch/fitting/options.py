"""How a candidate is fitted: starts, seed, covariance, cross-validation, search boxes.

One :class:`FitOptions` value travels with every fit of a command, so a search, the study, the
report and a diagnosis fit a candidate alike (and a cached fit serves them all).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

from ..data.errors import StructSearchError
from ..data.records import MIN_CONVECTIVE_TIMES
from ..engine.statistics import DEFAULT_COVARIANCE

# Cross-validation folds over the training maneuvers (fewer when a fold would hold fewer than
# CV_MIN_MANEUVERS maneuvers; none below two folds; blocked folds of one or two records: .folds).
CV_FOLDS = 5
CV_MIN_MANEUVERS = 3
# How a fold is fitted: "refit" solves it again from the full fit's estimates (exact); "one-step" takes
# one Gauss-Newton step from them on the fold's maneuvers (linearised: exact for a linear candidate,
# an approximation of second order in the fold's change of the estimates for a nonlinear one, and no
# solve at all: the full fit's Jacobian serves every fold).
CV_METHODS = ("refit", "one-step")


@dataclass(frozen=True)
class FitOptions:
    """The options of a candidate fit (``structsearch fit``/``search`` options of the same names)."""

    n_starts: int = 4
    seed: int = 0
    significance: float = 0.05
    covariance: str = DEFAULT_COVARIANCE
    cv_folds: int = CV_FOLDS          # 0: no cross-validation (diagnosis, calibration: they do not rank)
    # --bound NAME=LO:HI: search boxes of separation parameters, over the declared ones
    parameter_boxes: tuple[tuple[str, tuple[float, float]], ...] = ()
    cv_method: str = "refit"          # CV_METHODS
    # least maneuvers a maneuver-grouped fold holds: CV_MIN_MANEUVERS (every fold keeps every kind); 1 when the
    # training maneuvers are cycles of periodic records (.folds.fold_size_for: leave one cycle out)
    cv_fold_size: int = CV_MIN_MANEUVERS
    # the shortest block of a blocked fold, in convective times cbar/V: the campaign's own rule for the shortest
    # maneuver worth fitting (campaign.toml min_convective_times, the least over its training maneuvers' kinds)
    cv_block_convective_times: float = MIN_CONVECTIVE_TIMES
    # A screening fit (a structure search's first look at a move): estimates and scores only. Its covariance is
    # the white one, conditional on the lift model, and it has no centred correlations: no statistic of it is
    # reported or judged; the structures a search keeps are fitted again in full.
    scores_only: bool = False
    # --flight-effects: per-flight nuisance parameters every candidate of the fit estimates (.flight_effects; a
    # candidate's own spec entry may declare them too)
    flight_effects: tuple[str, ...] = ()

    def __post_init__(self):
        if self.cv_method not in CV_METHODS:
            raise StructSearchError(f"cross-validation method must be one of {', '.join(CV_METHODS)}, "
                                    f"not {self.cv_method!r}")

    def key(self, nonlinear: bool = True) -> dict:
        """What a fit's result depends on; the cross-validation method only for a ``nonlinear`` candidate
        (a linear one's folds are exact either way, so its cached fit serves both methods)."""
        key = {"n_starts": self.n_starts, "seed": self.seed, "covariance": self.covariance,
               "cv_folds": self.cv_folds, "bounds": [[k, list(v)] for k, v in self.parameter_boxes]}
        if nonlinear and self.cv_folds:
            key["cv_method"] = self.cv_method
        if self.cv_fold_size != CV_MIN_MANEUVERS:
            key["cv_fold_size"] = self.cv_fold_size
        if self.cv_block_convective_times != MIN_CONVECTIVE_TIMES:
            key["cv_block_convective_times"] = self.cv_block_convective_times
        if self.scores_only:
            key["scores_only"] = True
        if self.flight_effects:
            key["flight_effects"] = list(self.flight_effects)
        return key


# Each command's fit options where they differ from FitOptions' defaults, stated here and nowhere else. A
# structure search (diagnose, discover, the story) cross-validates structures with separation parameters by
# one-step folds (they rank alike, experiments/bench) and fits with two starts (each child also starts from its
# parent's estimates).
COMMAND_OPTIONS: dict[str, dict] = {
    "fit": {}, "search": {}, "study": {}, "report": {}, "demo": {},
    "diagnose": {"n_starts": 2, "cv_method": "one-step"},
    "discover": {"n_starts": 2, "cv_method": "one-step"},
}


def command_options(command: str, **changes) -> FitOptions:
    """``command``'s FitOptions (:data:`COMMAND_OPTIONS`) with ``changes``."""
    return FitOptions(**{**COMMAND_OPTIONS[command], **changes})


def check_box_names(boxes: Iterable[tuple[str, tuple[float, float]]], candidates) -> None:
    """An unknown NAME in ``--bound NAME=LO:HI`` is an error naming the parameters it could have meant."""
    from .specs import lift_candidate
    known = set()
    for c in candidates:
        known.update(c.state_parameters)
        if c.lift:
            known.update(lift_candidate(c.lift).state_parameters)
    unknown = [k for k, _ in boxes if k not in known]
    if unknown:
        raise StructSearchError(f"--bound {unknown[0]}: no candidate has this nonlinear parameter; known: "
                                f"{', '.join(sorted(known)) or '(none: the candidates are linear)'}")
