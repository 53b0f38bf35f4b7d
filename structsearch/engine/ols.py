"""Ordinary least squares for candidates without nonlinear parameters."""
from __future__ import annotations

import numpy as np

from .snls import Outcome, SeparableProblem, project


def ols(problem: SeparableProblem, y: np.ndarray) -> Outcome:
    """c = Phi^+ y by pivoted QR (a dependent regressor gets 0; the fit names it as not identifiable)."""
    ev = problem.evaluate(np.zeros(0))
    proj = project(ev.phi, y)
    return Outcome(start=np.zeros(0), theta=np.zeros(0), coef=proj.coef,
                   cost=float(0.5 * proj.residual @ proj.residual), nfev=1, njev=0, status=1,
                   message="ordinary least squares", success=True)
