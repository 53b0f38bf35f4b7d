"""All parameters of a separable problem as one nonlinear least-squares problem: the approach SNLS replaces,
kept as the baseline of the benchmark and as the thesis' legacy per-maneuver estimator (the study's Table 7)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from .snls import model_jacobian, project


@dataclass(frozen=True)
class FullFit:
    theta: np.ndarray      # nonlinear parameters
    coef: np.ndarray       # linear parameters
    rss: float
    nfev: int
    njev: int
    converged: bool


def full_nls(problem, y, theta0, lower, upper, tol=1e-10, max_nfev=1000, jacobian="analytic") -> FullFit:
    """All parameters as one nonlinear least-squares problem (the approach SNLS replaces).

    ``jacobian="analytic"`` hands scipy the exact Jacobian (the strongest baseline);
    ``"2-point"`` is what ``least_squares`` does by default (finite differences).
    """
    k = len(theta0)
    c0 = project(problem.evaluate(theta0).phi, y).coef
    cache = {}

    def at(x):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            ev = problem.evaluate(x[:k])
            cache[key] = (ev, y - ev.phi @ x[k:])
        return cache[key]

    def fun(x):
        return at(x)[1]

    def jac(x):
        ev, _ = at(x)
        return -model_jacobian(ev, x[k:], k)

    n = len(c0)
    lo = np.concatenate([lower, np.full(n, -np.inf)])
    hi = np.concatenate([upper, np.full(n, np.inf)])
    span = np.concatenate([upper - lower, np.ones(n)])
    x0 = np.concatenate([np.clip(theta0, lower + 1e-10 * (upper - lower), upper - 1e-10 * (upper - lower)), c0])
    sol = least_squares(fun, x0, jac=jac if jacobian == "analytic" else "2-point", bounds=(lo, hi),
                        method="trf", x_scale=span, ftol=tol, xtol=tol, gtol=tol, max_nfev=max_nfev)
    return FullFit(sol.x[:k], sol.x[k:], float(2 * sol.cost), int(sol.nfev), int(sol.njev or 0), bool(sol.success))
