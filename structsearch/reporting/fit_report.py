"""Human-readable summaries of a fit, kept apart from the numerics (like lmfit's fit_report)."""
from __future__ import annotations

from ..engine.results import FitResult
from ..fitting.candidate_result import CandidateResult
from .tables import FORMATS, correlation_table, parameter_table

__all__ = ["fit_report", "parameter_table", "correlation_table", "FORMATS"]


def fit_report(result: FitResult | CandidateResult, fmt: str = "text") -> str:
    """One summary of a fit or of a search's candidate: goodness of fit, parameters with tests and flags,
    strong correlations (``result.summary()`` rendered as ``fmt``: text, markdown, latex, html or csv)."""
    return result.summary().render(fmt)
