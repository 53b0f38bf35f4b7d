"""Every default of a fit in the engine, in one place, with the reason each differs between the two
separable problems (docs/interfaces.md section 4 fixes :class:`~.separable.SeparableModel`'s).

A generic separable model (:class:`~.separable.SeparableModel`) knows nothing of maneuvers: its data is
usually one record, so the per-maneuver estimates have nothing to count and its covariance default is the
stationary Toeplitz sandwich ``colored``. Its problems are small (NIST StRD, a few hundred samples), and
NIST Lanczos1/3 and MGH09 need the optimizer driven to the last digit: tolerance 1e-15, at the cost of a
few iterations. Its box is given at fit time (``fit(bounds=...)``), or at declaration.

A stall model (:class:`~.stallmodel.StallModel`) is fitted on flight-test maneuvers: its default is the
per-maneuver HAC sandwich ``hac-maneuver``, the one estimate that met the calibration goals on the flight
simulator (``structsearch bench --calibration``). Its problems have 10^5 samples and a scale set by the
measurement noise, so 1e-10 is beyond what the data resolve, and every further iteration costs a pass over
all samples. Its box is part of the model (``StallModel.declare(bounds=...)``), since a search fits the
same declaration many times.
"""
from __future__ import annotations

from dataclasses import dataclass

from .statistics import DEFAULT_COVARIANCE


@dataclass(frozen=True)
class FitDefaults:
    """The defaults of one kind of separable problem (see the module's docstring for why they differ)."""

    covariance: str
    tol: float
    bounds_at: str   # where the parameter box is given: "fit" or "declaration" (both accepted, see the models)


SEPARABLE_DEFAULTS = FitDefaults(covariance="colored", tol=1e-15, bounds_at="fit")
STALL_DEFAULTS = FitDefaults(covariance=DEFAULT_COVARIANCE, tol=1e-10, bounds_at="declaration")
