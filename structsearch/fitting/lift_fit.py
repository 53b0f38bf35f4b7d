"""A fitted lift model as its drag and pitch candidates use it.

Drag and pitch candidates take the separation states of the lift model they name (its separation
parameters held fixed) and its output as their C_L regressor. :class:`LiftFit` is that lift model:
its candidate and its result.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from .candidate_result import CandidateResult
from .candidates import Candidate


@dataclass(frozen=True)
class LiftFit:
    """A lift candidate and its fit, the lift model of drag and pitch candidates."""

    candidate: Candidate
    result: CandidateResult

    @property
    def name(self) -> str:
        return self.candidate.name

    @property
    def params(self) -> dict[str, float]:
        return self.result.estimates.params

    @property
    def failed(self) -> bool:
        return self.result.failed

    @property
    def not_identifiable(self) -> Mapping[str, str]:
        return self.result.estimates.not_identifiable

    @property
    def cache_key(self) -> dict:
        """What the fits of drag and pitch candidates on this lift model depend on (their cache key)."""
        return dict(self.params)

    influence = None   # the two-step covariance uses the lift model's own Jacobian and residual


@dataclass(frozen=True)
class LiftAt:
    """A lift structure at given parameter values (the simulator's truth, a joint fit's estimate): what drag and
    pitch read, in the shape of a :class:`LiftFit` (``candidate``, ``params``, ``name``, ``failed``)."""

    candidate: Candidate
    params: Mapping[str, float]
    failed: bool = False

    @property
    def name(self) -> str:
        return self.candidate.name


@dataclass(frozen=True, eq=False)
class JointLift:
    """The lift block of a joint fit as drag and pitch candidates read it (``search --joint-lift``): the lift
    structure at the joint estimate, in the shape of a :class:`LiftFit`, with the joint estimator's influence
    series for the two-step covariance of the candidates (the joint fit is their first step:
    :func:`structsearch.engine.twostep.influence_covariance`)."""

    candidate: Candidate
    params: Mapping[str, float]
    partners: tuple[str, ...]               # the structures fitted jointly with it
    influence: np.ndarray                   # (training samples, len(influence_names))
    influence_names: tuple[str, ...]        # the lift parameters the joint fit identifies
    not_identifiable: Mapping[str, str]
    failed: bool = False

    @property
    def name(self) -> str:
        return self.candidate.name

    @property
    def cache_key(self) -> dict:
        return {**self.params, "joint with": " + ".join(self.partners)}
