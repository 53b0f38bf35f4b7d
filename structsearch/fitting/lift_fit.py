"""A fitted lift model as its drag and pitch candidates use it.

Drag and pitch candidates take the separation states of the lift model they name (its separation
parameters held fixed) and its output as their C_L regressor. :class:`LiftFit` is that lift model:
its candidate and its result.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

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
        return self.result.params

    @property
    def failed(self) -> bool:
        return self.result.failed



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
