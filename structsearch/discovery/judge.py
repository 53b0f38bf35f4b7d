"""Admissibility as the ranking judges it, for the structures a search adopts (search.admissibility)."""
from __future__ import annotations

from typing import Callable, Sequence

from ..data.campaign import Campaign
from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
from ..grid_search.admissibility import MAX_CORRELATION, reasons
from ..grid_search.pipeline import rules_for


def judge_for(campaign: Campaign, max_correlation: float = MAX_CORRELATION
              ) -> Callable[[CandidateResult, Candidate], Sequence[str]]:
    """The reasons a fitted structure is not admissible on ``campaign`` (empty when it is)."""
    rules = rules_for(campaign, max_correlation)
    return lambda result, candidate: reasons(result, candidate, rules)
