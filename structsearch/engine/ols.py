"""Ordinary least squares for candidates without nonlinear parameters."""
from __future__ import annotations

import numpy as np

from .snls import Outcome, Projection, SeparableProblem, project


def ols(problem: SeparableProblem, y: np.ndarray) -> Outcome:
    """c = Phi^+ y by pivoted QR (a dependent regressor gets 0; the fit names it as not identifiable)."""
    return solved(project(problem.evaluate(np.zeros(0)).phi, y))


def solved(proj: Projection) -> Outcome:
    """The outcome of ordinary least squares from the projection of y on the regressors."""
    return Outcome(start=np.zeros(0), theta=np.zeros(0), coef=proj.coef,
                   cost=float(0.5 * proj.residual @ proj.residual), nfev=1, njev=0, status=1,
                   message="ordinary least squares", success=True)


def held_out_residuals(phi: np.ndarray, y: np.ndarray, bounds: np.ndarray, folds) -> np.ndarray:
    """y - Phi c_fold on every maneuver of every fold, c_fold the least-squares fit on the other maneuvers.

    One thin QR per maneuver (R_i, Q_i^T y_i) serves every fold: the fit on a set of maneuvers is the
    least-squares solution of their stacked R_i c = Q_i^T y_i (the same normal equations, without
    squaring the condition number), so the folds cost a few n x n problems instead of refits on the data.
    The rank tolerance is the one a fit on the fold's samples would use.
    """
    n = phi.shape[1]
    blocks = []
    for s, e in zip(bounds[:-1], bounds[1:]):
        q, r = np.linalg.qr(phi[s:e])
        blocks.append((r, q.T @ y[s:e], e - s))
    residual = np.full_like(y, np.nan)
    for held in folds:
        rest = [i for i in range(len(blocks)) if i not in set(held)]
        m_rest = sum(blocks[i][2] for i in rest)
        proj = project(np.vstack([blocks[i][0] for i in rest]), np.concatenate([blocks[i][1] for i in rest]),
                       rtol=max(m_rest, n) * np.finfo(float).eps)
        for i in held:
            s, e = bounds[i], bounds[i + 1]
            residual[s:e] = y[s:e] - phi[s:e] @ proj.coef
    return residual
