"""The exported model as a typed record, and its model card ``model.json`` (docs/interfaces.md 7.6).

A model is one to three coefficients (C_L, C_D, C_m), each the sum of its parameters times their regressors,
and the separation states they read, each with its kind (S, Q, U), its static form (``tanh``) and its
parameters' values. Drag and pitch read the lift model's output as ``CL`` and its states, so a drag or pitch
model always travels with the lift model it was fitted on. The card also holds each coefficient's parameter
covariance (null with a reason where the fit did not give one), its residual standard deviation, the alpha,
airspeed and Mach range of the data it was fitted on and which data that was.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from ..data.coefficients import COEFFICIENTS
from ..data.errors import DeclarationError
from ..engine.equations import helpers_used, model_equation, state_equation
from ..engine.separation import SeparationState
from ..engine.static_forms import EXPORTED_FORMS

CARD_FORMAT = "structsearch-model-card/1"
STATIC_FORMS = EXPORTED_FORMS     # the static separation forms an export writes (their records say)
ORDER = tuple(COEFFICIENTS)
GAMMA_AIR, GAS_CONSTANT = 1.4, 287.053


@dataclass(frozen=True)
class StateModel:
    """One separation state: ``name`` ("ss" is X_ss), ``kind`` S, Q or U, its static ``form`` and its
    parameters by their full names (``tau1_ss``...)."""

    name: str
    kind: str
    params: Mapping[str, float]
    form: str = "tanh"

    def __post_init__(self):
        state = SeparationState(self.name, self.kind)     # checks the kind and the name
        if self.form not in STATIC_FORMS:
            raise DeclarationError(f"separation state {state.symbol}: its static form {self.form!r} cannot be "
                                   f"exported (forms written: {', '.join(STATIC_FORMS)})")
        missing = [p for p in state.parameters if p not in self.params]
        if missing:
            raise DeclarationError(f"separation state {state.symbol}: no value for {', '.join(missing)}")

    @property
    def symbol(self) -> str:
        return SeparationState(self.name, self.kind).symbol

    def base(self) -> dict[str, float]:
        """The parameters by their base names (a1, a_star, tau1, tau2), as the engine's evaluate_state reads them."""
        state = SeparationState(self.name, self.kind)
        return {b: float(self.params[state.parameter_name(b)]) for b in state.base_parameters}

    def to_dict(self) -> dict:
        return {"name": self.name, "symbol": self.symbol, "kind": self.kind, "form": self.form,
                "parameters": {k: float(v) for k, v in self.params.items()},
                "equation": state_equation(self.name, self.kind)}


@dataclass(frozen=True)
class CoefficientModel:
    """One coefficient's model: its structure's name, its (parameter, regressor text) terms and their values,
    standard deviations and covariance (``covariance_names`` orders the matrix; None with ``covariance_note``),
    and its residual standard deviation on the training maneuvers."""

    coefficient: str
    model: str
    terms: tuple[tuple[str, str], ...]
    params: Mapping[str, float]
    stderr: Mapping[str, float | None] = field(default_factory=dict)
    covariance_names: tuple[str, ...] = ()
    covariance: tuple[tuple[float, ...], ...] | None = None
    covariance_note: str = ""
    residual_sd: float | None = None
    states: tuple[str, ...] = ()          # the state symbols its terms read

    def __post_init__(self):
        missing = [p for p, _ in self.terms if p not in self.params]
        if missing:
            raise DeclarationError(f"{self.model}: no value for the parameter(s) {', '.join(missing)}")

    @property
    def equation(self) -> str:
        return model_equation(self.coefficient, self.terms)

    def to_dict(self) -> dict:
        return {"coefficient": self.coefficient, "model": self.model, "equation": self.equation,
                "where": helpers_used([t for _, t in self.terms]),
                "terms": [{"parameter": p, "regressor": t, "value": float(self.params[p]),
                           "stderr": self.stderr.get(p)} for p, t in self.terms],
                "states": list(self.states),
                "covariance": (None if self.covariance is None else
                               {"names": list(self.covariance_names), "matrix": [list(r) for r in self.covariance]}),
                **({"covariance_note": self.covariance_note} if self.covariance_note else {}),
                "residual_sd": self.residual_sd}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "CoefficientModel":
        cov = d.get("covariance")
        return cls(d["coefficient"], d["model"], tuple((t["parameter"], t["regressor"]) for t in d["terms"]),
                   {t["parameter"]: float(t["value"]) for t in d["terms"]},
                   {t["parameter"]: t.get("stderr") for t in d["terms"]},
                   tuple(cov["names"]) if cov else (),
                   None if cov is None else tuple(tuple(_number(v) for v in row) for row in cov["matrix"]),
                   d.get("covariance_note", ""), d.get("residual_sd"), tuple(d.get("states", ())))


def _number(v) -> float:
    return float("nan") if v is None else float(v)


@dataclass(frozen=True)
class ExportedModel:
    """What an export writes: the coefficients (C_L first: drag and pitch read it), the states they read, the
    aircraft's reference geometry (S, cbar, b in m^2 and m; mass and Iyy when the campaign has them), the
    validity range and the data the model was fitted on."""

    coefficients: tuple[CoefficientModel, ...]
    states: tuple[StateModel, ...]
    aircraft: Mapping[str, float]
    validity: Mapping[str, Any]
    data: Mapping[str, Any]

    def __post_init__(self):
        names = [c.coefficient for c in self.coefficients]
        if len(set(names)) != len(names):
            raise DeclarationError(f"export: the coefficient {_repeated(names)} is given twice")
        if any(n not in ORDER for n in names):
            raise DeclarationError(f"export: a model of {[n for n in names if n not in ORDER][0]} cannot be "
                                   f"exported (coefficients: {', '.join(ORDER)})")
        reads_cl = [c.model for c in self.coefficients if c.coefficient != "CL"
                    and any("CL" in _names(t) for _, t in c.terms)]
        if reads_cl and "CL" not in names:
            raise DeclarationError(f"export: {reads_cl[0]} reads the lift model's C_L: export it with its lift model")

    def coefficient(self, name: str) -> CoefficientModel:
        return next(c for c in self.coefficients if c.coefficient == name)

    @property
    def equations(self) -> list[str]:
        lines = [c.equation for c in self.coefficients]
        lines += [state_equation(s.name, s.kind) for s in self.states]
        return lines + [f"where {m}" for m in helpers_used([t for c in self.coefficients for _, t in c.terms])]

    def to_dict(self) -> dict:
        """``model.json``."""
        return {"format": CARD_FORMAT, "equations": self.equations,
                "conventions": {"units": "SI, angles in rad, coefficients dimensionless",
                                "X0": "X0(a) = 0.5*(1 - tanh(a1*(a - a_star)))",
                                "initial_state": "every state starts in equilibrium: X(t0) = X0(alpha0 - "
                                                 "tau2*alpha_dot0)",
                                "lift_in_drag_and_pitch": "CL in a drag or pitch regressor is the lift model's "
                                                          "output, not a measurement",
                                "pitch_moment": "C_m about the recorded centre of gravity"},
                "coefficients": [c.to_dict() for c in self.coefficients],
                "states": [s.to_dict() for s in self.states],
                "aircraft": dict(self.aircraft), "validity": dict(self.validity), "data": dict(self.data)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "ExportedModel":
        if d.get("format") != CARD_FORMAT:
            raise DeclarationError(f"not a model card of format {CARD_FORMAT}: {d.get('format')!r}")
        return cls(tuple(CoefficientModel.from_dict(c) for c in d["coefficients"]),
                   tuple(StateModel(s["name"], s["kind"], s["parameters"], s.get("form", "tanh"))
                         for s in d["states"]),
                   d["aircraft"], d["validity"], d["data"])


def _names(text: str) -> set[str]:
    from ..engine.regressors import symbol_names
    return symbol_names(text)


def _repeated(names: Sequence[str]) -> str:
    return next(n for n in names if names.count(n) > 1)


def ordered(coefficients: Sequence[CoefficientModel]) -> tuple[CoefficientModel, ...]:
    """C_L, C_D, C_m in this order (the order JSBSim must compute them in: drag and pitch read C_L)."""
    return tuple(sorted(coefficients, key=lambda c: ORDER.index(c.coefficient) if c.coefficient in ORDER else 9))


def speed_of_sound(h) -> np.ndarray:
    """ISA troposphere speed of sound [m/s] at altitude h [m]."""
    from ..data.reduction import LAPSE, T0
    return np.sqrt(GAMMA_AIR * GAS_CONSTANT * (T0 - LAPSE * np.asarray(h, float)))


def validity(data) -> dict:
    """The range the model was fitted on: alpha, airspeed and Mach (the ``Mach`` column, else V over the ISA
    speed of sound at ``h``; null with a reason without either)."""
    def span(x):
        return [float(np.min(x)), float(np.max(x))]
    out = {"alpha_rad": span(data["alpha"]), "V_mps": span(data["V"])}
    if "Mach" in data:
        out["Mach"], out["Mach_from"] = span(data["Mach"]), "the Mach column"
    elif "h" in data:
        out["Mach"], out["Mach_from"] = span(data["V"] / speed_of_sound(data["h"])), "V / ISA speed of sound at h"
    else:
        out["Mach"], out["Mach_from"] = None, "the campaign records neither Mach nor h"
    return out


def aircraft_record(manifest: Mapping[str, Any], data) -> dict:
    """The example aircraft's data (SI): S, cbar, b from [aircraft]; the mass (the ``mass`` column's median, else
    [aircraft] mass, else the median of C_L qbar S / g), pitch inertia (Iyy, else a guess stated in ``guessed``),
    Ixx and Izz when given, the centre of gravity (x_cg's median, else the middle of x_cg_range, else 0), a trim
    point (the median altitude, the 75th percentile of the airspeed), the elevator's range (1.2 times the
    largest |de| flown, at least 0.35 rad) and a maximum thrust twice the largest C_T qbar S flown."""
    from ..data.reduction import G, isa_density
    out = {k: float(manifest[k]) for k in ("S", "cbar", "b")}
    guessed = []
    h = np.asarray(data["h"], float) if "h" in data else np.full(data.n_samples, 3000.0)
    qbar_s = 0.5 * isa_density(h) * np.asarray(data["V"], float) ** 2 * out["S"]
    if "mass" in data:
        out["mass"] = float(np.median(data["mass"]))
    elif "mass" in manifest:
        out["mass"] = float(manifest["mass"])
    else:
        out["mass"] = float(np.median(np.asarray(data["CL"], float) * qbar_s / G))
        guessed.append("mass (from C_L qbar S / g)")
    for key in ("Iyy", "Ixx", "Izz"):
        if key in manifest:
            out[key] = float(manifest[key])
    if "Iyy" not in out:
        out["Iyy"] = out["mass"] * (0.3 * out["b"]) ** 2 / 4.0
        guessed.append("Iyy (mass * (0.15 b)^2)")
    if "x_cg" in data:
        out["x_cg"] = float(np.median(data["x_cg"]))
    elif "x_cg_range" in manifest:
        out["x_cg"] = float(np.mean(manifest["x_cg_range"]))
    else:
        out["x_cg"] = 0.0
    out["trim_h_m"] = float(np.median(h))
    out["trim_V_mps"] = float(np.quantile(data["V"], 0.75))
    out["de_range_rad"] = max(0.35, 1.2 * float(np.max(np.abs(data["de"])))) if "de" in data else 0.35
    thrust = np.asarray(data["CT"], float) * qbar_s if "CT" in data else np.array([0.1 * out["mass"] * G])
    out["max_thrust_N"] = 2.0 * float(np.max(thrust))
    if guessed:
        out["guessed"] = guessed
    return out
