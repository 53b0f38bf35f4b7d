"""Pointwise aerodynamic models for the simulator: C_L, C_D, C_m from the instantaneous state.

An :class:`AeroModel` is built from identified (or truth) lift, drag and pitch
:class:`~structsearch.stallmodel.StallModel` structures and their parameters.
Each coefficient is compiled into one numpy function of the data columns, the
aircraft constants and the separation states; the simulator integrates the
unsteady states and evaluates the steady and quasi-steady ones algebraically.
"""
from __future__ import annotations

import dataclasses

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np
import sympy as sp

from ..data.errors import DeclarationError
from .names import WITHHOLDABLE  # noqa: F401  (re-exported: truth_model's effects)
from .reference import FINAL_DRAG, FINAL_LIFT, FINAL_PITCH, final_drag_model, final_lift_model, final_pitch_model
from ..engine.regressors import compile_expression, parse
from ..engine.separation import SeparationState, is_lagged, is_vortex
from ..engine.static_forms import static_value
from ..engine.stallmodel import StallModel
from .transport import (TRANSPORT_DRAG, TRANSPORT_LIFT, TRANSPORT_PITCH, TRANSPORT_ZEROED, transport_drag_model,
                        transport_lift_model, transport_pitch_model)

# the names live in .names, importable without numpy or sympy (the command line's choices)
_ZEROED = {
    "pitch_rate": ("CL_qstar",),
    "elevator": ("CL_de", "CD_de"),
    "elevator_effectiveness_loss": ("Cm_Xde_ss",),
    "thrust": ("CD_CT", "Cm_CT"),
    "induced_drag": ("CD_CL2",),
    "separation_drag": ("CD_1mX_ss", "CD_1mX_w"),
    "cp_shift": ("Cm_1mX_ssCL", "Cm_1mX_wCL"),
}


@dataclass(frozen=True)
class StateSpec:
    """One flown separation state: its time constants and its static curve (``form`` with the values of its
    parameters ``shape``, base name -> value; a1 and a_star are the tanh's, NaN for a form without them)."""

    symbol: str
    kind: str
    tau1: float
    tau2: float
    a1: float
    a_star: float
    form: str = "tanh"
    shape: tuple[tuple[str, float], ...] = ()

    def static(self, alpha, a_star=None) -> np.ndarray:
        """X0(alpha) of its form; ``a_star`` (an array of the samples' alpha*, a tanh or goman state) in place of
        its own."""
        values = dict(self.shape) or {"a1": self.a1, "a_star": self.a_star}
        if a_star is None:
            return static_value(self.form, alpha, values)
        alpha, a_star = np.broadcast_arrays(np.asarray(alpha, float), np.asarray(a_star, float))
        values["a_star"] = a_star.ravel()   # elementwise with the samples
        return static_value(self.form, alpha.ravel(), values).reshape(alpha.shape)


def steady_target(spec: StateSpec, alpha, alpha_dot) -> np.ndarray:
    """X0(alpha - tau2 alpha_dot) of one state (tau2 ignored for a steady state): what it relaxes to."""
    return spec.static(alpha - (spec.tau2 if spec.kind != "S" else 0.0) * alpha_dot)


class AeroModel:
    """C_L, C_D and C_m as compiled functions; drag and pitch take C_L from the lift model.

    ``anomaly`` (optional, see :mod:`.anomalies`) puts aerodynamics outside the model library into
    the truth: its ``factors`` (pairs parameter name, expression text in the data columns) multiply
    the terms of those parameters, and its ``separation_target(spec, alpha, alpha_dot, h)`` replaces
    :func:`steady_target` as the value every separation state relaxes to.
    """

    def __init__(self, lift: StallModel, drag: StallModel, pitch: StallModel, params: Mapping[str, float],
                 constant_states: Mapping[str, float] | None = None, name: str = "aero", anomaly=None):
        self.name = name
        self.models = {"CL": lift, "CD": drag, "Cm": pitch}
        self.params = dict(params)
        self.constant_states = dict(constant_states or {})
        self.anomaly = anomaly
        self._factors = {k: parse(text, known=(), context=f"{name}: factor of {k}")
                         for k, text in (getattr(anomaly, "factors", ()) or ())}
        unknown = [k for k in self._factors if not any(k in m.linear_names for m in self.models.values())]
        if unknown:
            raise DeclarationError(f"{name}: anomaly {getattr(anomaly, 'name', anomaly)!r} scales "
                                   f"{unknown[0]!r}, which no coefficient of this model has")
        specs: dict[str, StateSpec] = {}
        for model in self.models.values():
            values = dict(model.fixed)
            values.update({k: v for k, v in self.params.items()})
            for s in model.states:
                if s.symbol in self.constant_states:
                    continue
                get = {p: values.get(s.parameter_name(p)) for p in s.base_parameters}
                missing = [s.parameter_name(p) for p, v in get.items() if v is None]
                if missing:
                    raise DeclarationError(f"{name}: no value for separation parameter {missing[0]!r}")
                if is_vortex(s.kind):
                    raise DeclarationError(f"{name}: separation state {s.symbol} is a dynamic-stall vortex (kind V), "
                                           "which the flight simulator does not fly: fit and diagnose it on "
                                           "records, or fly a structure without it")
                shape = tuple((p, float(get[p])) for p in s.base_parameters if p not in ("tau1", "tau2"))
                spec = StateSpec(s.symbol, s.kind, get.get("tau1", 0.0), get.get("tau2", 0.0),
                                 float(get.get("a1", np.nan)), float(get.get("a_star", np.nan)), s.form, shape)
                if s.symbol in specs and specs[s.symbol] != spec:
                    raise DeclarationError(f"{name}: separation state {s.symbol} differs between models")
                specs[s.symbol] = spec
        self.states = tuple(specs.values())
        absent = [x for x in (getattr(anomaly, "states", ()) or ()) if x not in specs]
        if absent:
            raise DeclarationError(f"{name}: anomaly {getattr(anomaly, 'name', anomaly)!r} acts on separation "
                                   f"state {absent[0]}, which this model does not have")
        self._compiled = {}
        for coef, model in self.models.items():
            missing = [p for p in model.linear_names if p not in self.params]
            if missing:
                raise DeclarationError(f"{name}: no value for {coef} coefficient {missing[0]!r}")
            expr = sum(self._term(r) for r in model.regressors)
            expr = expr.subs({sp.Symbol(k, real=True): v for k, v in self.constant_states.items()})
            args = tuple(sorted(s.name for s in expr.free_symbols))
            self._compiled[coef] = (expr, args)
        self._terms: dict[str, tuple] = {}

    def _term(self, r) -> sp.Expr:
        """The term of regressor ``r``: its value times its expression (times the anomaly's factor)."""
        if r.name in self._factors:
            return sp.Float(self.params[r.name]) * self._factors[r.name] * r.expr
        return sp.Float(self.params[r.name]) * r.expr

    def with_quasi_steady(self, specs) -> "AeroModel":
        """This model with the unsteady states ``specs`` flown quasi-steady (their tau1 -> 0 limit)."""
        import copy
        out = copy.copy(self)
        symbols = {s.symbol for s in specs}
        out.states = tuple(dataclasses.replace(s, kind="Q") if s.symbol in symbols else s for s in self.states)
        return out

    @property
    def columns(self) -> frozenset[str]:
        """Every name the three coefficients read (data columns, constants, states, C_L)."""
        return frozenset(a for _, args in self._compiled.values() for a in args)

    @property
    def unsteady(self) -> tuple[StateSpec, ...]:
        return tuple(s for s in self.states if is_lagged(s.kind))

    def separation_targets(self, alpha, alpha_dot, h=None, states=None) -> dict[str, np.ndarray]:
        """X0(alpha - tau2 alpha_dot) of every state (the value a lagged state relaxes to), or of the
        StateSpecs ``states``; an anomaly's targets may depend on the altitude ``h`` too."""
        states = self.states if states is None else states
        if self.anomaly is None:
            return {s.symbol: steady_target(s, alpha, alpha_dot) for s in states}
        return {s.symbol: self.anomaly.separation_target(s, alpha, alpha_dot, h) for s in states}

    def _evaluate(self, expr: sp.Expr, args: tuple[str, ...], values: Mapping[str, np.ndarray], what: str):
        try:
            return compile_expression(expr, args)(*(values[a] for a in args))
        except KeyError as exc:
            raise DeclarationError(f"{self.name}: {what} needs {exc.args[0]!r}") from None

    def coefficient(self, coef: str, values: Mapping[str, np.ndarray]) -> np.ndarray:
        expr, args = self._compiled[coef]
        return self._evaluate(expr, args, values, coef)

    def terms(self, coef: str, values: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Each term of ``coef`` (parameter name -> value times regressor) at ``values``, broadcast to the
        shape of ``values["alpha"]``; their sum is :meth:`coefficient` up to rounding."""
        if coef not in self._terms:
            subs = {sp.Symbol(k, real=True): v for k, v in self.constant_states.items()}
            compiled = []
            for r in self.models[coef].regressors:
                expr = self._term(r).subs(subs)
                compiled.append((r.name, expr, tuple(sorted(s.name for s in expr.free_symbols))))
            self._terms[coef] = tuple(compiled)
        shape = np.shape(values["alpha"])
        return {name: np.broadcast_to(np.asarray(self._evaluate(expr, args, values, f"{coef} term {name}"), float),
                                      shape).copy()
                for name, expr, args in self._terms[coef]}

    def partial(self, coef: str, wrt: str, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """d coef / d ``wrt`` (a column such as C_L or delta_e) at ``values``, differentiated symbolically."""
        derivative = sp.diff(self._compiled[coef][0], sp.Symbol(wrt, real=True))
        args = tuple(sorted(s.name for s in derivative.free_symbols))
        out = self._evaluate(derivative, args, values, f"d{coef}/d{wrt}")
        return np.broadcast_to(np.asarray(out, float), np.shape(values["alpha"])).copy()

    def coefficients(self, values: Mapping[str, np.ndarray]):
        """(C_L, C_D, C_m); ``values`` holds columns, constants and separation states."""
        cl = self.coefficient("CL", values)
        with_cl = dict(values, CL=cl)
        cd = self.coefficient("CD", with_cl)
        # C_m may read C_D: a truth whose cg term is the moment transfer (C_N, :func:`cg_transfer_pitch`)
        return cl, cd, self.coefficient("Cm", dict(with_cl, CD=cd))


@dataclass(frozen=True)
class Truth:
    """An aircraft's truth aerodynamics: structures, values, and what withholding an effect zeroes."""

    lift: Callable[[], StallModel]
    drag: Callable[[Mapping[str, float]], StallModel]
    pitch: Callable[[Mapping[str, float]], StallModel]
    lift_params: Mapping[str, float]
    other_params: Mapping[str, float]
    zeroed: Mapping[str, tuple[str, ...]]
    lagged_state: str             # name of the unsteady state ("ss": X_ss, "": X)
    second_state: str | None      # name of the steady second state, if any


TRUTHS = {
    "citation": Truth(final_lift_model, final_drag_model, final_pitch_model, FINAL_LIFT,
                      {**FINAL_DRAG, **FINAL_PITCH}, _ZEROED, "ss", "w"),
    "transport": Truth(transport_lift_model, transport_drag_model, transport_pitch_model, TRANSPORT_LIFT,
                       {**TRANSPORT_DRAG, **TRANSPORT_PITCH}, TRANSPORT_ZEROED, "", None),
}


# How the truth's pitching moment depends on the centre of gravity: "thesis", the identified Cm-XXXIIIr term
# Cm_xcgCL x_cg/cbar C_L (-0.96, where the moment transfer of a rigid aircraft is +1 times C_N); "transfer", the
# same model about the Citation's reference point, moved to the flown cg by the transfer alone.
CG_MOMENTS = ("thesis", "transfer")
TRANSFER_REGRESSOR = "(x_cg - {x_ref!r})/cbar*(CL*cos(alpha) + CD*sin(alpha))"


def cg_transfer_pitch(pitch: StallModel, params: Mapping[str, float], x_ref: float, cbar: float):
    """The thesis' pitch model ``pitch`` (with ``params``) about the station ``x_ref``: its cg terms frozen at
    x_cg = x_ref (Cm_CL + Cm_xcgCL x_ref/cbar), the moment moved to the flown cg by
    C_N (x_cg - x_ref)/cbar, C_N = C_L cos(alpha) + C_D sin(alpha). At x_cg = x_ref it is the thesis' model."""
    regressors = {r.name: (TRANSFER_REGRESSOR.format(x_ref=x_ref) if r.name == "Cm_xcgCL" else r.text or sp.sstr(r.expr))
                  for r in pitch.regressors}
    moved = StallModel.declare(pitch.name, pitch.coefficient, regressors,
                               states={s.name: s.kind for s in pitch.states}, fixed=pitch.fixed)
    values = dict(params, Cm_CL=params["Cm_CL"] + params["Cm_xcgCL"] * x_ref / cbar, Cm_xcgCL=1.0)
    return moved, values


def truth_model(withhold=(), aircraft: str = "citation", anomaly=None, envelope: bool = False,
                cg_moment: str = "thesis") -> AeroModel:
    """The truth of ``aircraft``: for the Citation II the final model of the thesis (CL-VI, CD-IXr,
    Cm-XXXIIIr), for the transport its one-state model (:mod:`.transport`); named effects removed,
    an ``anomaly`` of :mod:`.anomalies` (the object, not its name) added. ``envelope``: with the
    attached-flow terms of the wider envelope the nominal maneuvers fly (:mod:`.envelope`; Citation II only).
    ``cg_moment`` (:data:`CG_MOMENTS`, Citation only): "transfer" flies the pitch model about the reference
    point, moved to the cg (:func:`cg_transfer_pitch`)."""
    if aircraft not in TRUTHS:
        raise DeclarationError(f"no aircraft {aircraft!r}: the simulator flies {', '.join(TRUTHS)}")
    if envelope and aircraft != "citation":
        raise DeclarationError(f"nominal maneuvers are declared for the Citation II only, not the {aircraft}")
    if cg_moment not in CG_MOMENTS:
        raise DeclarationError(f"cg moment {cg_moment!r}: one of {', '.join(CG_MOMENTS)}")
    if cg_moment != "thesis" and (aircraft != "citation" or anomaly is not None):
        raise DeclarationError(f"cg moment {cg_moment!r}: for the Citation II's truth without an anomaly (the "
                               "transport records no cg)")
    truth = TRUTHS[aircraft]
    withhold = tuple(dict.fromkeys(withhold))
    unknown = [w for w in withhold if w not in WITHHOLDABLE]
    if unknown:
        raise DeclarationError(f"cannot withhold {unknown[0]!r}: effects of the final model are "
                               f"{', '.join(WITHHOLDABLE)}")
    if "second_separation_state" in withhold and truth.second_state is None:
        raise DeclarationError(f"cannot withhold 'second_separation_state': the {aircraft} has one separation "
                               "state")
    suffix = f"_{truth.lagged_state}" if truth.lagged_state else ""
    lift_params = dict(truth.lift_params)
    params = dict(truth.lift_params, **truth.other_params)
    kind = "U"
    if "unsteady_lag" in withhold:
        kind = "Q"
        lift_params.pop("tau1" + suffix)
        params.pop("tau1" + suffix)
    if "separation_delay" in withhold:
        lift_params["tau2" + suffix] = params["tau2" + suffix] = 0.0
    for effect in withhold:
        for name in truth.zeroed.get(effect, ()):
            params[name] = 0.0
    constant = {f"X_{truth.second_state}": 1.0} if "second_separation_state" in withhold else {}
    models = [_with_kind(m, truth.lagged_state, kind)
              for m in (truth.lift(), truth.drag(lift_params), truth.pitch(lift_params))]
    if cg_moment == "transfer":
        from .aircraft import CITATION
        models[2], params = cg_transfer_pitch(models[2], params, CITATION.reference_point, CITATION.cbar)
    if envelope:
        from .envelope import ENVELOPE_VALUES, with_envelope
        models = [with_envelope(m) for m in models]
        params.update(ENVELOPE_VALUES)
    label = ("truth" if aircraft == "citation" else f"{aircraft} truth") \
        + ("" if not withhold else " without " + ", ".join(withhold)) \
        + ("" if anomaly is None else f" with {anomaly.name}") \
        + ("" if cg_moment == "thesis" else " with the cg moment a transfer") \
        + (" with the nominal envelope" if envelope else "")
    return AeroModel(*models, params, constant, name=label, anomaly=anomaly)


def _with_kind(model: StallModel, state: str, kind: str) -> StallModel:
    """``model`` with its state ``state`` of ``kind`` (U -> Q drops the lag and its fixed value)."""
    if kind == "U":
        return model
    suffix = f"_{state}" if state else ""
    states = tuple(SeparationState(s.name, kind, s.form) if s.name == state else s for s in model.states)
    fixed = {k: v for k, v in model.fixed.items() if k != "tau1" + suffix}
    return StallModel(model.name, model.coefficient, states, model.regressors, model.start, model.bounds, fixed)
