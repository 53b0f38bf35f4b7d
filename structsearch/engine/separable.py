"""Generic separable models y = sum_i c_i * phi_i(x; theta), declared with sympy text.

>>> model = SeparableModel({"b1": "exp(-b2*x)", "b3": "exp(-b4*x)"}, variables=["x"])
>>> result = model.fit({"x": x}, y, start={"b2": 1.0, "b4": 3.0})   # doctest: +SKIP

Keys are the linear coefficients; values are basis expressions (``"1"`` is a
constant column). Every free symbol that is not a data variable is a nonlinear
parameter, differentiated symbolically.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import sympy as sp

from ..data.errors import DataError, DeclarationError
from .defaults import SEPARABLE_DEFAULTS
from .fit import fit_problem
from .regressors import compile_expression, parse
from .results import FitResult
from .snls import BoundProblem, Evaluation


@dataclass(frozen=True, eq=False)
class _BasisProblem(BoundProblem):
    """A SeparableModel bound to data: evaluates Phi(theta) and its non-zero derivatives."""

    model: "SeparableModel"
    values: tuple[np.ndarray, ...]
    n_samples: int

    def _call(self, expr, theta):
        fn = compile_expression(expr, self.model.argnames)
        out = fn(*self.values, *theta)
        return np.broadcast_to(np.asarray(out, dtype=float), (self.n_samples,))

    def extended_residual(self, theta: np.ndarray, coef: np.ndarray, y: np.ndarray) -> np.ndarray:
        """y - Phi(theta) c evaluated in extended precision (where the platform has it).

        At the optimum the RSS is insensitive to first order to rounding of theta
        and c, so this gives the RSS to nearly full precision even when the
        residuals are ~1e-13 of the data (NIST Lanczos1).
        """
        wide = tuple(v.astype(np.longdouble) for v in self.values)
        theta_wide = tuple(np.longdouble(t) for t in theta)
        fitted = np.zeros(self.n_samples, dtype=np.longdouble)
        for c, expr in zip(coef, self.model.expressions):
            fn = compile_expression(expr, self.model.argnames)
            fitted += np.longdouble(c) * np.asarray(fn(*wide, *theta_wide), dtype=np.longdouble)
        return (y.astype(np.longdouble) - fitted).astype(float)

    def evaluate(self, theta: np.ndarray) -> Evaluation:
        phi = np.column_stack([self._call(e, theta) for e in self.model.expressions])
        cols = [self._call(d, theta) for _, _, d in self.model.derivatives]
        dphi = np.column_stack(cols) if cols else np.zeros((self.n_samples, 0))
        rows = np.array([i for i, _, _ in self.model.derivatives], dtype=int)
        params = np.array([j for _, j, _ in self.model.derivatives], dtype=int)
        return Evaluation(phi, dphi, rows, params)


class SeparableModel:
    """A model linear in some coefficients and nonlinear in the rest (docs/interfaces.md section 4)."""

    def __init__(self, basis: Mapping[str, str], variables: Sequence[str], name: str = "separable",
                 bounds: Mapping[str, tuple[float, float]] | None = None):
        """``bounds``: the box of nonlinear parameters, ``{"b2": (lo, hi)}``; ``fit(bounds=...)`` may give it
        instead, and a parameter's box given there wins over the declared one."""
        if not basis:
            raise DeclarationError("a separable model needs at least one basis function")
        self.name = name
        self.variables = tuple(variables)
        self.linear_names = tuple(basis)
        for v in self.variables:
            if v in self.linear_names:
                raise DeclarationError(f"{v!r} is both a data variable and a linear coefficient")
        exprs = []
        for coef, text in basis.items():
            if not str(coef).isidentifier():
                raise DeclarationError(f"linear coefficient name {coef!r} is not an identifier")
            expr = parse(str(text), known=self.variables, context=f"basis of {coef!r}")
            clash = [s.name for s in expr.free_symbols if s.name in self.linear_names]
            if clash:
                raise DeclarationError(f"basis of {coef!r} uses linear coefficient {clash[0]!r}; a basis "
                                       "may depend on data variables and nonlinear parameters only")
            exprs.append(expr)
        self.expressions = tuple(exprs)
        used = {s.name for e in exprs for s in e.free_symbols}
        unused = [v for v in self.variables if v not in used]
        if unused:
            raise DeclarationError(f"data variable {unused[0]!r} is declared but no basis function uses it")
        self.nonlinear_names = tuple(sorted(used - set(self.variables), key=_natural_key))
        self.argnames = self.variables + self.nonlinear_names
        # bookkeeping: only the (basis, parameter) pairs with a non-zero derivative
        derivs = []
        for i, e in enumerate(exprs):
            for j, p in enumerate(self.nonlinear_names):
                sym = sp.Symbol(p, real=True)
                if sym in e.free_symbols:
                    derivs.append((i, j, sp.diff(e, sym)))
        self.derivatives = tuple(derivs)
        self.bounds = self._checked_bounds(bounds)

    def _checked_bounds(self, bounds) -> dict[str, tuple[float, float]]:
        bounds = {k: (float(lo), float(hi)) for k, (lo, hi) in dict(bounds or {}).items()}
        for key in bounds:
            if key not in self.nonlinear_names:
                raise DeclarationError(f"{key!r} is not a nonlinear parameter of this model "
                                       f"(nonlinear parameters: {', '.join(self.nonlinear_names) or 'none'})")
        return bounds

    def __repr__(self):
        body = ", ".join(f"{c}: {e}" for c, e in zip(self.linear_names, self.expressions))
        return f"SeparableModel({{{body}}}, variables={list(self.variables)})"

    def bind(self, data: Mapping[str, np.ndarray]) -> _BasisProblem:
        values, n = [], None
        for v in self.variables:
            if v not in data:
                raise DataError("data variable is missing", column=v)
            arr = np.asarray(data[v], dtype=float)
            if arr.ndim != 1:
                raise DataError(f"must be one-dimensional, has shape {arr.shape}", column=v)
            n = len(arr) if n is None else n
            if len(arr) != n:
                raise DataError(f"has {len(arr)} samples, other variables have {n}", column=v)
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise DataError("value is NaN or infinite", column=v, row=int(bad[0]))
            values.append(arr)
        return _BasisProblem(self, tuple(values), int(n))

    def fit(self, data: Mapping[str, np.ndarray], y, start: Mapping[str, float] | None = None,
            bounds: Mapping[str, tuple[float, float]] | None = None, *,
            covariance: str = SEPARABLE_DEFAULTS.covariance, n_starts: int = 1, seed: int = 0, n_jobs: int = 1,
            max_lag=None, tol: float = SEPARABLE_DEFAULTS.tol,
            max_nfev: int | None = None, segments: Sequence[int] | None = None,
            flights: Sequence[str | None] | None = None) -> FitResult:
        """Fit by variable projection.

        The defaults (:data:`~.defaults.SEPARABLE_DEFAULTS`: covariance ``colored``, tolerance 1e-15) suit
        a generic problem without maneuvers; the tolerance drives small problems to the last digit (NIST
        Lanczos1/3 and MGH09 need it); it costs a few iterations at most. ``bounds`` is the box of nonlinear
        parameters; a parameter's box given here wins over the one given at declaration.

        ``segments`` optionally gives the first sample index of every independent
        record after the first (residual autocorrelations never cross them); ``flights`` optionally names each
        record's flight (``covariance="hac-flight"`` groups the records of one flight).
        """
        start = dict(start or {})
        bounds = {**self.bounds, **self._checked_bounds(bounds)}
        for key in start:
            if key not in self.nonlinear_names:
                raise DeclarationError(f"{key!r} is not a nonlinear parameter of this model "
                                       f"(nonlinear parameters: {', '.join(self.nonlinear_names) or 'none'})")
        missing = [p for p in self.nonlinear_names if p not in start]
        if missing:
            raise DeclarationError(f"no start value for nonlinear parameter {missing[0]!r}")
        problem = self.bind(data)
        y = np.asarray(y, dtype=float)
        seg_bounds = np.concatenate([[0], np.asarray(segments or [], dtype=int), [problem.n_samples]])
        if np.any(np.diff(seg_bounds) <= 0):
            raise DataError("segment starts must be strictly increasing inside (0, n)")
        names = tuple(f"segment{i}" for i in range(len(seg_bounds) - 1))
        lower = np.array([bounds.get(p, (-np.inf, np.inf))[0] for p in self.nonlinear_names], float)
        upper = np.array([bounds.get(p, (-np.inf, np.inf))[1] for p in self.nonlinear_names], float)
        return fit_problem(problem, y, boundaries=seg_bounds, segment_names=names,
                           start=np.array([start[p] for p in self.nonlinear_names], float),
                           lower=lower, upper=upper, n_starts=n_starts, seed=seed, n_jobs=n_jobs,
                           covariance=covariance, max_lag=max_lag, tol=tol, max_nfev=max_nfev,
                           model=self.name, coefficient="y", flights=_checked_flights(flights, len(names)))


def _checked_flights(flights, n_records: int):
    """``flights`` as one entry per record (None where not recorded), or None."""
    if flights is None:
        return None
    flights = tuple(flights)
    if len(flights) != n_records:
        raise DataError(f"{len(flights)} flights for {n_records} records (segments)", column="flights")
    return flights


def _natural_key(name: str):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name)]
