"""structsearch: model-structure search for aircraft stall aerodynamics.

Attributes are imported on first use, so that ``structsearch.cli`` can set up
the numeric libraries (one BLAS thread per process) before numpy loads.
"""
from importlib import import_module

__version__ = "0.1.0"

_EXPORTS = {
    "SeparableModel": "engine.separable",
    "StallModel": "engine.stallmodel",
    "FitResult": "engine.results",
    "fit_report": "report.fit_report",
    "FlightData": "data.flightdata",
    "read_campaign": "data.campaign",
    "write_campaign": "data.campaign",
    "Campaign": "data.campaign",
    "StructSearchError": "data.errors",
    "DataError": "data.errors",
    "DeclarationError": "data.errors",
    "FitError": "data.errors",
}
__all__ = sorted(_EXPORTS) + ["__version__"]


def __getattr__(name):
    if name in _EXPORTS:
        value = getattr(import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'structsearch' has no attribute {name!r}")
