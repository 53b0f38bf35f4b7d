"""Stall-model structures: separation states plus symbolic regressors, bound to flight data.

>>> model = StallModel.declare(
...     "CL-VI", "CL", states={"ss": "U", "w": "S"},
...     regressors={"CL0": "1", "CL_KL_ss": "K_L(X_ss)", "CL_KL_w": "K_L(X_w)",
...                 "CL_qstar": "qstar", "CL_de": "de"})
>>> result = model.fit(data)   # doctest: +SKIP

The model is checked when it is declared: every symbol must be a known data
column, aircraft constant or declared separation state, every declared state
must be used by a regressor (otherwise its parameters are unidentifiable), and
start values and bounds may only name the model's nonlinear parameters.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from typing import Mapping, Sequence

import numpy as np
import sympy as sp

from ..data.flightdata import FlightData
from ..data.errors import DataError, DeclarationError
from .equations import Equations, write_equations
from .fit import fit_problem
from .identifiability import SATURATION, check_parameter_names, collinear_with, join_names
from .regressors import X_FLOOR, Regressor, declare
from .results import FitResult
from ..data.default_boxes import data_bounds
from .separation import SeparationState, common_step, driven_alpha, evaluate_state
from .static_forms import LOCATION_PARAMETERS, SEPARATION_BOUNDS, SEPARATION_STARTS
from .ols import ols
from .snls import BoundProblem, Evaluation, MultistartOutcome, model_jacobian, multistart, solve_recorded, start_list
from .defaults import STALL_DEFAULTS
from .units import coefficient_unit, separation_unit


@dataclass(frozen=True, eq=False)
class StallModel:
    name: str
    coefficient: str
    states: tuple[SeparationState, ...]
    regressors: tuple[Regressor, ...]
    start: Mapping[str, float] = field(default_factory=dict)
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    fixed: Mapping[str, float] = field(default_factory=dict)
    # a known term of the data (coefficient fixed at 1): fitted as coefficient - offset, predicted with it
    offset: Regressor | None = None

    @classmethod
    def declare(cls, name: str, coefficient: str, regressors: Mapping[str, str], *,
                states: Mapping[str, str] | None = None, start: Mapping[str, float] | None = None,
                bounds: Mapping[str, tuple[float, float]] | None = None,
                fixed: Mapping[str, float] | None = None,
                forms: Mapping[str, str] | None = None,
                offset: tuple[str, str] | None = None,
                drives: Mapping[str, float] | None = None) -> "StallModel":
        """``states`` maps a state name ("ss", "w", or "" for plain X) to its kind S, Q or U; ``forms`` a state
        name to its static curve (:mod:`.static_forms`; a state not named has the tanh).

        ``fixed`` holds separation parameters that are not estimated (a drag or pitch model takes its states from
        the identified lift model); a model whose separation parameters are all fixed is fitted by OLS. ``offset``: (name, expression)
        of a known term added to the output with its coefficient fixed at 1 (it reads no separation state).
        ``drives``: a state name to its drive (a wing's state: :class:`~.separation.SeparationState`).
        """
        forms = dict(forms or {})
        stray = [n for n in forms if n not in (states or {})]
        if stray:
            raise DeclarationError(f"model {name!r}: a static separation form for {stray[0]!r}, which is not one of "
                                   f"its states ({', '.join(states or {}) or 'none'})")
        state_objs = tuple(SeparationState(n, k, forms.get(n, "tanh"), (drives or {}).get(n, 0.0))
                           for n, k in (states or {}).items())
        symbols = [s.symbol for s in state_objs]
        if len(set(symbols)) != len(symbols):
            raise DeclarationError(f"model {name!r}: separation state declared twice")
        if not regressors:
            raise DeclarationError(f"model {name!r}: no regressors declared")
        regs = tuple(declare(rname, text, states=symbols, context=f"model {name!r}, regressor {rname!r}",
                             free_columns=True)
                     for rname, text in regressors.items())
        used = {s for r in regs for s in r.states}
        for s in symbols:
            if s not in used:
                raise DeclarationError(f"model {name!r}: separation state {s!r} is declared but no regressor "
                                       "uses it, so its parameters cannot be identified")
        if coefficient in {c for r in regs for c in r.columns}:
            raise DeclarationError(f"model {name!r}: the modelled coefficient {coefficient!r} appears in "
                                   "its own regressors")
        known = offset and declare(*offset, states=[], context=f"model {name!r}, offset", free_columns=True)
        if known and (coefficient in known.columns or known.name in {r.name for r in regs}):
            raise DeclarationError(f"model {name!r}: the offset {known.name!r} reads {coefficient} or is a parameter")
        model = cls(name, coefficient, state_objs, regs, dict(start or {}), dict(bounds or {}),
                    dict(fixed or {}), known)
        check_parameter_names(name, tuple(p for s in state_objs for p in s.parameters), model.nonlinear_names,
                              model.fixed, model.start, model.bounds)
        return model

    @property
    def nonlinear_names(self) -> tuple[str, ...]:
        """Separation parameters that are estimated (all but the fixed ones)."""
        return tuple(p for s in self.states for p in s.parameters if p not in self.fixed)

    @property
    def linear_names(self) -> tuple[str, ...]:
        return tuple(r.name for r in self.regressors)

    @property
    def units(self) -> dict[str, str]:
        """Each parameter's unit (:mod:`.units`): tau in s, a1 per rad, a_star in rad; a linear coefficient's
        is the inverse of its regressor's (the coefficient it builds is dimensionless)."""
        symbols = tuple(s.symbol for s in self.states)
        return {**{p: separation_unit(p) for p in self.nonlinear_names},
                **{r.name: coefficient_unit(r.expr, symbols) for r in self.regressors}}

    @property
    def state_inputs(self) -> tuple[str, ...]:
        """The data columns the separation states read (a wing's state its roll rate and airspeed too)."""
        wing = ("p", "V") if any(s.drive for s in self.states) else ()
        return ("alpha", "alpha_dot", "t") + wing if self.states else ()

    @property
    def required_columns(self) -> tuple[str, ...]:
        offset = set(self.offset.columns) if self.offset else set()
        return tuple(sorted({c for r in self.regressors for c in r.columns} | set(self.state_inputs) | offset))

    def offset_value(self, data: FlightData) -> np.ndarray:
        """The known term on ``data`` (zeros without one)."""
        return np.zeros(data.n_samples) if self.offset is None else self.offset.value(data, {}, data.n_samples)

    def target(self, data: FlightData) -> np.ndarray:
        """What the regressors fit: the coefficient column, less the known term when the model has one."""
        return data[self.coefficient] if self.offset is None else data[self.coefficient] - self.offset_value(data)

    def _with_offset(self, data: FlightData, output: np.ndarray) -> np.ndarray:
        return output if self.offset is None else output + self.offset_value(data)

    def _free(self):
        return [(s, p) for s in self.states for p in s.base_parameters if s.parameter_name(p) not in self.fixed]

    def start_vector(self) -> np.ndarray:
        """Declared starts; else the middle of declared bounds (two states with their own ranges must not
        start identical, their regressors would coincide); else the default start of the parameter kind."""
        out = []
        for s, p in self._free():
            name = s.parameter_name(p)
            if name in self.start:
                out.append(self.start[name])
            elif name in self.bounds:
                out.append(0.5 * (self.bounds[name][0] + self.bounds[name][1]))
            else:
                out.append(SEPARATION_STARTS[p])
        return np.array(out, float)

    def bound_vectors(self, data: FlightData | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Declared bounds, else the default box of the parameter kind (derived from ``data`` when given)."""
        defaults = (data_bounds(data, SEPARATION_BOUNDS, LOCATION_PARAMETERS) if data is not None
                    else SEPARATION_BOUNDS)
        pairs = [self.bounds.get(s.parameter_name(p), defaults[p]) for s, p in self._free()]
        return np.array([p[0] for p in pairs], float), np.array([p[1] for p in pairs], float)

    def inside(self, data: FlightData, start: Mapping[str, float]) -> dict[str, float]:
        """The values of ``start`` that are this model's nonlinear parameters, moved into its box on
        ``data`` (a warm start from another model or another subset of the maneuvers)."""
        lower, upper = self.bound_vectors(data)
        return {name: float(np.clip(start[name], lo, hi))
                for name, lo, hi in zip(self.nonlinear_names, lower, upper) if name in start}

    def bind(self, data: FlightData) -> "StallProblem":
        for col in self.required_columns:
            if col not in data and col not in data.constants:
                raise DataError(f"model {self.name!r} needs this column (the campaign has "
                                f"{', '.join(sorted(data.columns))})", source=data.source, column=col)
        return StallProblem(self, data)

    def _prepared(self, data: FlightData, start: Mapping[str, float] | None, declared_too: bool = False,
                  more: Sequence[Mapping[str, float]] = ()):
        """The bound problem, observations, start vector, bounds and further starts of a fit on ``data``:
        with ``declared_too``, the declared start follows a given ``start`` (a warm start); each of ``more``
        (values of some nonlinear parameters, the others declared; moved into the box) follows too."""
        problem = self.bind(data)
        lower, upper = self.bound_vectors(data)
        # a default start outside the data's box (alpha* of a low-alpha campaign) begins on its nearest
        # face; a start the user gives outside the box stays an error (fit_problem names it)
        declared = np.clip(self.start_vector(), lower, upper)
        theta0 = declared.copy()
        for key, value in (start or {}).items():
            if key not in self.nonlinear_names:
                raise DeclarationError(f"model {self.name!r}: {key!r} is not one of its nonlinear parameters")
            theta0[self.nonlinear_names.index(key)] = value
        also = [declared] if declared_too and not np.array_equal(declared, theta0) else []
        for point in more:
            theta = declared.copy()
            for key, value in point.items():
                if key in self.nonlinear_names:
                    theta[self.nonlinear_names.index(key)] = value
            theta = np.clip(theta, lower, upper)
            if not any(np.array_equal(theta, a) for a in [theta0] + also):
                also.append(theta)
        return problem, self.target(data), theta0, lower, upper, also

    def fit(self, data: FlightData, *, start: Mapping[str, float] | None = None, n_starts: int = 1,
            seed: int = 0, n_jobs: int = 1, covariance: str = STALL_DEFAULTS.covariance, max_lag=None,
            tol: float = STALL_DEFAULTS.tol, max_nfev: int | None = None, declared_too: bool = False,
            more_starts: Sequence[Mapping[str, float]] = (), solved: MultistartOutcome | None = None) -> FitResult:
        """Fit the coefficient column of ``data``: SNLS when there are separation states, else OLS.
        The covariance defaults to the project's best-calibrated one (per-maneuver HAC), the tolerance to
        1e-10 (:data:`~.defaults.STALL_DEFAULTS`, which says why they differ from a SeparableModel's). The box
        is the declared one (``declare(bounds=...)``), else the default box of each parameter kind. With
        ``declared_too`` the declared start is tried after a given ``start``, and so is each of ``more_starts``.
        ``solved``: the solves from every start of :meth:`start_points` (with the same arguments), run
        elsewhere (:meth:`solve_from`, one task each): only the statistics are computed here."""
        problem, y, theta0, lower, upper, also = self._prepared(data, start, declared_too, more_starts)
        result = fit_problem(problem, y, boundaries=data.bounds, segment_names=data.names, start=theta0,
                             lower=lower, upper=upper, n_starts=n_starts, seed=seed, n_jobs=n_jobs,
                             covariance=covariance, max_lag=max_lag, tol=tol, max_nfev=max_nfev, also=also,
                             model=self.name, coefficient=self.coefficient, source=data.source,
                             flights=data.flights, starts=solved)
        return dataclasses.replace(result, equations=self.equations())

    def equations(self) -> Equations:
        """The model as equations (:mod:`.equations`): the coefficient as its parameters times their regressors,
        each state's equation (a state whose parameters are all fixed says so), the helpers it calls."""
        regressors = [(r.name, r.text or sp.sstr(r.expr)) for r in self.regressors]
        states = [(s.name, s.kind, s.form) for s in self.states]
        fixed = all(p in self.fixed for s in self.states for p in s.parameters) and bool(self.states)
        return write_equations(self.coefficient, regressors, states,
                               state_note="  (its parameters fixed, not estimated here)" if fixed else "",
                               offset=None if self.offset is None else (self.offset.name, self.offset.text))

    def start_points(self, data: FlightData, *, start: Mapping[str, float] | None = None, n_starts: int = 1,
                     seed: int = 0, declared_too: bool = False,
                     more_starts: Sequence[Mapping[str, float]] = ()) -> np.ndarray:
        """The starts :meth:`fit` (or :meth:`estimate`) tries with these arguments, in its order, one per row."""
        problem, _, theta0, lower, upper, also = self._prepared(data, start, declared_too, more_starts)
        return start_list(problem, theta0, lower, upper, n_starts=n_starts, seed=seed, also=also)

    def solve_from(self, data: FlightData, point: np.ndarray, tol: float = STALL_DEFAULTS.tol):
        """One local solve from ``point`` (a row of :meth:`start_points`), its failure recorded in the outcome."""
        lower, upper = self.bound_vectors(data)
        return solve_recorded(self.bind(data), self.target(data), point, lower, upper, tol=tol)

    def estimate(self, data: FlightData, *, start: Mapping[str, float] | None = None, n_starts: int = 1,
                 seed: int = 0, tol: float = STALL_DEFAULTS.tol, declared_too: bool = False,
                 rows: np.ndarray | None = None) -> dict[str, float]:
        """The parameter estimates alone, without statistics (what a cross-validation fold needs). ``rows``: only
        these samples enter the least squares, while the states still run over every sample of ``data`` (a
        blocked fold holds out a block's outputs, not its inputs: no state restarts after the block)."""
        problem, y, theta0, lower, upper, also = self._prepared(data, start, declared_too)
        if rows is not None:
            problem, y = RowsOf(problem, np.asarray(rows)), y[rows]
        if self.nonlinear_names:
            outcome = multistart(problem, y, theta0, lower, upper, n_starts=n_starts, seed=seed, tol=tol,
                                 also=also).best
        else:
            outcome = ols(problem, y)
        return dict(zip(self.nonlinear_names + self.linear_names, np.concatenate([outcome.theta, outcome.coef])))

    def jacobian(self, data: FlightData, params: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """The model's Jacobian in every parameter, nonlinear then linear ([dPhi/dtheta c, Phi]), at ``params``
        on ``data``, and the model output Phi c (plus the offset column, when the model has one)."""
        theta = np.array([params[p] for p in self.nonlinear_names], float)
        coef = np.array([params[p] for p in self.linear_names], float)
        ev = self.bind(data).evaluate(theta)
        return model_jacobian(ev, coef, len(theta)), self._with_offset(data, ev.phi @ coef)

    def predict(self, data: FlightData, params: Mapping[str, float]) -> np.ndarray:
        """Model output for given parameter values (nonlinear and linear), the offset column included."""
        missing = [p for p in self.nonlinear_names + self.linear_names if p not in params]
        if missing:
            raise DeclarationError(f"model {self.name!r}: no value for parameter {missing[0]!r}")
        phi = self.bind(data).regression_matrix(np.array([params[p] for p in self.nonlinear_names], float))
        return self._with_offset(data, phi @ np.array([params[p] for p in self.linear_names], float))


@dataclass(frozen=True, eq=False)
class RowsOf(BoundProblem):
    """A bound problem whose least squares see only ``rows`` of its samples (its states run over all of them)."""

    inner: BoundProblem
    rows: np.ndarray

    @property
    def model(self):
        return self.inner.model

    def evaluate(self, theta: np.ndarray) -> Evaluation:
        ev = self.inner.evaluate(theta)
        return Evaluation(ev.phi[self.rows], ev.dphi[self.rows], ev.rows, ev.params)


# Separation states for fixed parameters kept per data set (each one array of the samples): the lift
# model's states, shared by a grid's drag and pitch candidates, with room for a few lift models
FIXED_STATES_KEPT = 8


@dataclass(frozen=True, eq=False)
class StallProblem(BoundProblem):
    """A StallModel bound to FlightData: Phi(theta) and its non-zero derivative columns."""

    model: StallModel
    data: FlightData

    @property
    def units(self) -> dict[str, str]:
        return self.model.units

    @cached_property
    def _step(self) -> float | None:
        return common_step(self.data["t"], self.data.bounds) if self.model.states else None

    def regressor_inputs(self, index: int, row: int) -> str:
        """The data values regressor ``index`` reads at stacked sample ``row`` (for error messages)."""
        reg = self.model.regressors[index]
        return ", ".join(f"{c} = {self.data[c][row]:.6g}" for c in reg.columns if c in self.data)

    def state_values(self, theta: np.ndarray, sensitivities: bool = True):
        """Each separation state: (index of each parameter's column in theta or -1 if fixed, X, dX/dparams);
        dX/dparams is None without ``sensitivities``. The last result is kept: a fit evaluates the
        solution again for its statistics, its identifiability and its predictions."""
        key = np.asarray(theta, float).tobytes()
        last = self.__dict__.get("_last_states")
        if last is not None and last[0] == key and (last[1] or not sensitivities):
            return last[2]
        out = {}
        d = self.data
        names = self.model.nonlinear_names
        given = dict(zip(names, theta))
        for s in self.model.states:
            values = {p: given.get(s.parameter_name(p), self.model.fixed.get(s.parameter_name(p)))
                      for p in s.base_parameters}
            index = np.array([names.index(s.parameter_name(p)) if s.parameter_name(p) in given else -1
                              for p in s.base_parameters])
            if not np.any(index >= 0):
                # a state whose parameters are all fixed (a drag or pitch model's, the lift model's) needs
                # no sensitivities, and every candidate bound to this data computes the same one
                fixed = d.memo("fixed separation states")
                memo_key = (s, tuple(sorted(values.items())))
                x = fixed.get(memo_key)
                if x is None:
                    if len(fixed) >= FIXED_STATES_KEPT:  # a loop over fixed values must not hoard samples
                        fixed.pop(next(iter(fixed)), None)
                    x = evaluate_state(s, values, *driven_alpha(d, s.drive), d["t"], d.bounds, self._step,
                                       False, d.period_array)[0]
                    x.setflags(write=False)  # shared by every model bound to this data
                    fixed[memo_key] = x
                out[s.symbol] = (index, x, None)
                continue
            x, dx = evaluate_state(s, values, *driven_alpha(d, s.drive), d["t"], d.bounds, self._step,
                                   sensitivities, d.period_array)
            out[s.symbol] = (index, x, dx)
        self.__dict__["_last_states"] = (key, sensitivities, out)  # frozen dataclass: a cache, not a field
        return out

    def __getstate__(self):
        # the memo of the last states is large (X and dX on every sample): never pickled to a worker
        state = dict(self.__dict__)
        state.pop("_last_states", None)
        return state

    def regression_matrix(self, theta: np.ndarray, data: FlightData | None = None,
                          changed: tuple[np.ndarray, set[str]] | None = None) -> np.ndarray:
        """Phi(theta) alone, without derivatives (a prediction). ``data`` may replace columns that are
        not state inputs (a centred regressor column); the states come from the bound data. ``changed``,
        (Phi on the bound data, the names of the columns ``data`` replaces): only the regressors that read
        one of them are evaluated again."""
        m = self.data.n_samples
        x_values = {sym: v[1] for sym, v in self.state_values(np.asarray(theta, float), False).items()}
        data = self.data if data is None else data
        if changed is None:
            phi = np.empty((m, len(self.model.regressors)), order="F")
        else:
            phi = changed[0].copy(order="F")
        for i, reg in enumerate(self.model.regressors):
            if changed is None or set(reg.columns) & changed[1]:
                phi[:, i] = reg.value(data, x_values, m)
        return phi

    def evaluate(self, theta: np.ndarray) -> Evaluation:
        m = self.data.n_samples
        states = self.state_values(np.asarray(theta, float))
        x_values = {sym: v[1] for sym, v in states.items()}
        phi = np.empty((m, len(self.model.regressors)), order="F")
        # derivative columns only for (regressor, estimated parameter) pairs
        pairs = [(i, sym, j) for i, reg in enumerate(self.model.regressors) for sym in reg.states
                 for j in np.flatnonzero(states[sym][0] >= 0)]
        dphi = np.empty((m, len(pairs)), order="F")
        rows = np.array([p[0] for p in pairs], int)
        params = np.array([states[p[1]][0][p[2]] for p in pairs], int)
        col = 0
        for i, reg in enumerate(self.model.regressors):
            phi[:, i] = reg.value(self.data, x_values, m)
            for sym in reg.states:
                index, _, dx = states[sym]
                free = np.flatnonzero(index >= 0)
                if free.size:
                    d_reg = reg.derivative(sym, self.data, x_values, m)
                    np.multiply(dx[:, free], d_reg[:, None], out=dphi[:, col:col + free.size])
                    col += free.size
        return Evaluation(phi, dphi, rows, params)

    def identifiability(self, theta: np.ndarray) -> dict[str, str]:
        """Parameters a saturated separation state leaves unidentifiable, with the reason.

        A state above 1 - SATURATION (attached) or below SATURATION (separated) on every
        sample carries no information on its own parameters; a regressor of it is then
        (nearly) a function of the data alone and may coincide with other regressors.
        """
        states = self.state_values(np.asarray(theta, float), False)
        names = self.model.nonlinear_names
        reasons: dict[str, str] = {}
        saturated: dict[str, tuple[float, str]] = {}
        for s in self.model.states:
            index, x, _ = states[s.symbol]
            if float(np.min(x)) > 1.0 - SATURATION:
                saturated[s.symbol] = (1.0, f"{s.symbol} stays above {1.0 - SATURATION:g} on every sample "
                                            "(attached flow throughout)")
            elif float(np.max(x)) < SATURATION:
                saturated[s.symbol] = (X_FLOOR, f"{s.symbol} stays below {SATURATION:g} on every sample "
                                                "(separated flow throughout)")
            else:
                continue
            free = [names[i] for i in index if i >= 0]
            if free:
                why = saturated[s.symbol][1]
                for p in free:
                    reasons[p] = f"{why}: {join_names(free)} cannot be identified from this data"
        if not saturated:
            return reasons
        m = self.data.n_samples
        frozen = {sym: (np.full(m, saturated[sym][0]) if sym in saturated else v[1]) for sym, v in states.items()}
        regs = self.model.regressors
        phi = np.column_stack([r.value(self.data, frozen, m) for r in regs])
        for i, reg in enumerate(regs):
            hit = [sym for sym in reg.states if sym in saturated]
            if not hit:
                continue
            others = [j for j in range(len(regs)) if j != i]
            partners = collinear_with(phi[:, i], phi[:, others])
            if partners is None:
                continue
            group = [reg.name] + [regs[others[j]].name for j in partners]
            why = saturated[hit[0]][1]
            text = (f"{why}, so regressor {reg.name!r} is zero on every sample" if len(group) == 1 else
                    f"{why}, so regressor {reg.name!r} is collinear with the others: {join_names(group)} "
                    "cannot be separated")
            for p in group:
                reasons.setdefault(p, text)
        return reasons
