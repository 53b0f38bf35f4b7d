"""structsearch: model-structure search for aircraft stall aerodynamics.

The public API (docs/interfaces.md 4 and 6.1) is importable from here: ``structsearch.fit``,
``structsearch.search``, ``structsearch.diagnose``, ... (:mod:`structsearch.api`), the demo
(:func:`structsearch.workflows.demo`), the generic models and the campaign reader. Attributes are
imported on first use, so that ``import structsearch`` stays light and ``structsearch.cli`` can set up
the numeric libraries (one BLAS thread per process) before numpy loads; the ``TYPE_CHECKING`` imports
below show every name to IDEs and type checkers.
"""
from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING

from ._version import __version__

# exported name -> module (relative to this package) that defines it
_EXPORTS = {
    "fit": "api", "fit_joint": "api", "search": "api", "diagnose": "api", "discover": "api", "simulate": "api", "preprocess": "api", "study": "api",
    "report": "api", "compare_outputs": "api", "OutputComparison": "api",
    "FitOutcome": "api", "Ranking": "api", "PreprocessOutcome": "api", "StudyOutcome": "api",
    "ReportOutcome": "api", "Settings": "api", "FlightTestPlan": "api", "export": "api", "ExportOutcome": "api",
    "demo": "workflows", "DemoOutcome": "workflows",
    "SeparableModel": "engine.separable",
    "StallModel": "engine.stallmodel",
    "FitResult": "engine.results",
    "CandidateResult": "fitting.candidate_result",
    "FitOptions": "fitting.options",
    "LiftFit": "fitting.lift_fit",
    "fit_report": "reporting.fit_report",
    "FlightData": "data.flightdata",
    "read_campaign": "data.campaign",
    "write_campaign": "data.campaign",
    "Campaign": "data.campaign",
    "StructSearchError": "data.errors",
    "DataError": "data.errors",
    "DeclarationError": "data.errors",
    "FitError": "data.errors",
}
# a literal list, as type checkers read it (tests/test_api.py checks it against _EXPORTS)
__all__ = ["Campaign", "CandidateResult", "DataError", "DeclarationError", "DemoOutcome", "ExportOutcome", "FitError",
           "FitOptions", "FitOutcome", "FitResult", "FlightData", "FlightTestPlan", "LiftFit", "OutputComparison", "PreprocessOutcome", "Ranking",
           "ReportOutcome", "SeparableModel", "Settings", "StallModel", "StructSearchError", "StudyOutcome", "compare_outputs", "demo",
           "diagnose", "discover", "export", "fit", "fit_joint", "fit_report", "preprocess", "read_campaign", "report", "search", "simulate",
           "study", "write_campaign", "__version__"]

if TYPE_CHECKING:
    from .api import (ExportOutcome, export, FitOutcome, FlightTestPlan, OutputComparison, Settings, PreprocessOutcome, compare_outputs, Ranking, ReportOutcome, StudyOutcome, diagnose, discover, fit,
                      fit_joint, preprocess, report, search, simulate, study)
    from .data.campaign import Campaign, read_campaign, write_campaign
    from .data.errors import DataError, DeclarationError, FitError, StructSearchError
    from .data.flightdata import FlightData
    from .engine.results import FitResult
    from .engine.separable import SeparableModel
    from .engine.stallmodel import StallModel
    from .fitting.candidate_result import CandidateResult
    from .fitting.lift_fit import LiftFit
    from .fitting.options import FitOptions
    from .reporting.fit_report import fit_report
    from .workflows import DemoOutcome, demo


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'structsearch' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
