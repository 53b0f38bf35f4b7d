"""Ordinary least squares for candidates without nonlinear parameters."""
from __future__ import annotations

import numpy as np

from .snls import Outcome, SeparableProblem, check_full_rank, project


def ols(problem: SeparableProblem, y: np.ndarray, where: str = "model") -> Outcome:
    """c = Phi^+ y by pivoted QR; a rank-deficient Phi is an error naming the dependent regressors."""
    ev = problem.evaluate(np.zeros(0))
    proj = project(ev.phi, y)
    check_full_rank(proj, problem.linear_names, where)
    return Outcome(start=np.zeros(0), theta=np.zeros(0), coef=proj.coef,
                   cost=float(0.5 * proj.residual @ proj.residual), nfev=1, njev=0, status=1,
                   message="ordinary least squares", success=True)
