"""The exported model as JSBSim XML: ``aerodynamics.xml`` and ``systems/structsearch_states.xml``.

The system (run by JSBSim's flight-control model, before the aerodynamics in every frame) has two channels:

- ``structsearch inputs`` (executed while ``structsearch/fill-inputs`` is 1, its default) fills the namespace's
  input properties from JSBSim's own, in the campaign's SI units (:data:`.xml_functions.INPUTS`), and
  ``structsearch/dt-sec`` from ``simulation/dt``. A program that drives the model with recorded inputs sets
  ``structsearch/fill-inputs`` to 0 and writes them itself (``export --check`` does).
- ``structsearch separation states`` integrates each state. S: X = X0(alpha); Q: X = X0(alpha -
  tau2*alpha_dot); U: tau1*dX/dt + X = X0(alpha - tau2*alpha_dot) by the exact recursion for an input linear
  between frames (first-order hold), the one the fits use (:mod:`structsearch.engine.separation`):
  X_k = a X_{k-1} + (g - a) u_{k-1} + (1 - g) u_k, a = exp(-dt/tau1), g = (1 - a)/(dt/tau1); a frame with
  dt = 0 (JSBSim's trim and initialisation, the first sample of a recorded maneuver) sets the state to its
  equilibrium X = u, as every maneuver starts in the fits. JSBSim's ``<lag_filter>`` would integrate the same
  lag with the bilinear (Tustin) rule instead; ``export --check`` states the difference.

The aerodynamics compute each term's contribution (parameter times regressor) as a property
``structsearch/terms/<parameter>``, each coefficient as ``structsearch/<coefficient>`` (C_L first: drag and
pitch read it), and one function per axis and term named after its parameter: LIFT and DRAG forces
qbar*S*C applied at the centre of gravity, the PITCH moment qbar*S*cbar*C (so C_m is about the centre of
gravity, as the campaign records it).
"""
from __future__ import annotations

import xml.etree.ElementTree as ET

from ..data.coefficients import coefficient as coefficient_record
from ..data.errors import DeclarationError
from ..engine.separation import INSTANT_LAG, SeparationState, is_delayed, is_lagged, is_vortex
from .card import ExportedModel, StateModel
from .xml_functions import (INPUTS, NAMESPACE, Symbols, element, output_property, prop, regressor_xml,
                            state_property, term_property, value)
from ..engine.regressors import symbol_names

SYSTEM_NAME = "structsearch_states"
FILL_INPUTS = f"{NAMESPACE}/fill-inputs"
DT = f"{NAMESPACE}/dt-sec"
FORCE_FACTORS = ("aero/qbar-psf", "metrics/Sw-sqft")
# a moment coefficient's reference length (Coefficient.length) as JSBSim's property
LENGTH_PROPERTY = {"cbar": "metrics/cbarw-ft", "b": "metrics/bw-ft"}


def symbols_of(model: ExportedModel) -> Symbols:
    return Symbols(states={s.symbol: state_property(s.symbol) for s in model.states},
                   constants={k: float(v) for k, v in model.aircraft.items() if k in ("cbar", "S", "b")},
                   outputs={"CL": output_property("CL")} if any(c.coefficient == "CL" for c in model.coefficients)
                   else {})


def inputs_used(model: ExportedModel) -> list[str]:
    """The input columns the model reads (its regressors' and its states'), in :data:`INPUTS` order."""
    names = {n for c in model.coefficients for _, t in c.terms for n in symbol_names(t)}
    if model.states:
        names |= {"alpha"}
    if any(s.kind != "S" for s in model.states):
        names |= {"alpha_dot"}
    return [c for c in INPUTS if c in names]


def _document(root: ET.Element, comment: str) -> str:
    root.insert(0, ET.Comment(comment))
    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _comment_text(lines) -> str:
    # "--" may not appear inside an XML comment
    return "\n  " + "\n  ".join(line.replace("--", "- -") for line in lines) + "\n"


# ----- aerodynamics ----------------------------------------------------------------------------------------------
def aerodynamics_xml(model: ExportedModel) -> str:
    """``aerodynamics.xml``: an ``<aerodynamics>`` element (module docstring)."""
    symbols = symbols_of(model)
    root = element("aerodynamics")
    for c in model.coefficients:
        for parameter, text in c.terms:
            where = f"{c.model}: term {parameter}"
            body = element("product", value(c.params[parameter]), regressor_xml(text, symbols, where))
            root.append(element("function", element("description", text=f"{parameter} * ({text}) of {c.equation}"),
                                body, name=term_property(parameter)))
        parts = [prop(term_property(p)) for p, _ in c.terms]
        total = parts[0] if len(parts) == 1 else element("sum", *parts)
        root.append(element("function", element("description", text=f"{c.model}: {c.equation}"), total,
                            name=output_property(c.coefficient)))
    for c in model.coefficients:
        record = coefficient_record(c.coefficient)
        axis = record.jsbsim_axis
        factors = FORCE_FACTORS + ((LENGTH_PROPERTY[record.length],) if record.moment else ())
        functions = []
        for parameter, text in c.terms:
            kind = "moment" if record.moment else "force"
            scale = f"qbar*S*{record.length}" if record.moment else "qbar*S"
            attributes = {} if record.moment else {"apply_at_cg": "true"}
            functions.append(element(
                "function", element("description", text=f"{scale} * {parameter} * ({text})"),
                element("product", *[prop(f) for f in factors], prop(term_property(parameter))),
                name=f"aero/{kind}/{parameter}", **attributes))
        root.append(element("axis", *functions, name=axis))
    return _document(root, _comment_text(
        ["Exported by structsearch: " + ", ".join(f"{c.coefficient} {c.model}" for c in model.coefficients) + "."]
        + model.equations
        + ["Inputs: the structsearch/* properties that systems/structsearch_states.xml fills (SI units).",
           "Forces qbar*S*C at the centre of gravity; pitch moment qbar*S*cbar*C about it."]))


# ----- the states' system --------------------------------------------------------------------------------------
def _fcs_function(name: str, body: ET.Element, description: str = "") -> ET.Element:
    children = [element("description", text=description)] if description else []
    return element("fcs_function", *children, element("function", body), element("output", text=name), name=name)


def _static(state: StateModel) -> ET.Element:
    """X0(alpha_eff) = 0.5*(1 - tanh(a1*(alpha_eff - a_star))) = 1/(1 + exp(2*a1*(alpha_eff - a_star)))."""
    p = state.base()
    alpha = prop(INPUTS["alpha"].property)
    if is_delayed(state.kind):
        alpha = element("difference", alpha, element("product", value(p["tau2"]),
                                                     prop(INPUTS["alpha_dot"].property)))
    exponent = element("product", value(2.0 * p["a1"]), element("difference", alpha, value(p["a_star"])))
    return element("quotient", value(1.0), element("sum", value(1.0), element("exp", exponent)))


def _state_components(state: StateModel) -> list[ET.Element]:
    if is_vortex(state.kind):
        raise DeclarationError(f"separation state {state.symbol} is a dynamic-stall vortex (kind V), which the "
                               "JSBSim export does not write: export a structure without it, or --format json")
    x = state_property(state.symbol)
    static = f"{x}-static"
    state_eq = SeparationState(state.name, state.kind)
    parts = [_fcs_function(static, _static(state), "X0 of " + state.symbol)]
    tau1 = state.base().get("tau1")
    if not is_lagged(state.kind) or tau1 < INSTANT_LAG:     # a lag shorter than INSTANT_LAG is X = u in the fits too
        parts.append(_fcs_function(x, prop(static), f"{state.symbol} ({state_eq.kind}) = X0"))
        return parts
    lag = f"{NAMESPACE}/lag/{state.symbol}"
    steps = f"{lag}/steps"            # dt / tau1
    a, g = f"{lag}/a", f"{lag}/g"
    previous, previous_static = f"{lag}/previous", f"{lag}/previous-static"
    parts += [
        _fcs_function(steps, element("quotient", prop(DT), value(tau1)), "dt / tau1"),
        _fcs_function(a, element("exp", element("product", value(-1.0), prop(steps))), "a = exp(-dt/tau1)"),
        _fcs_function(g, element("ifthen", element("gt", prop(steps), value(0.0)),
                                 element("quotient", element("difference", value(1.0), prop(a)), prop(steps)),
                                 value(1.0)), "g = (1 - a)/(dt/tau1)"),
        _fcs_function(x, element(
            "ifthen", element("gt", prop(DT), value(0.0)),
            element("sum", element("product", prop(a), prop(previous)),
                    element("product", element("difference", prop(g), prop(a)), prop(previous_static)),
                    element("product", element("difference", value(1.0), prop(g)), prop(static))),
            prop(static)),
            f"{state.symbol}: tau1*dX/dt + X = X0, exact for X0 linear between frames; dt = 0: equilibrium"),
        _fcs_function(previous, prop(x), "the state, kept for the next frame"),
        _fcs_function(previous_static, prop(static), "X0, kept for the next frame"),
    ]
    return parts


def system_xml(model: ExportedModel) -> str:
    """``systems/structsearch_states.xml`` (module docstring)."""
    root = element("system", name=SYSTEM_NAME)
    root.append(element("property", text=FILL_INPUTS, value="1"))
    root.append(element("property", text=DT, value="0"))
    fill = [_fcs_function(DT, prop("simulation/dt"), "frame step [s]")]
    for column in inputs_used(model):
        i = INPUTS[column]
        fill.append(_fcs_function(i.property, i.source(), f"{column} [{i.unit}] = {i.source_text}"))
    root.append(element("channel", *fill, name="structsearch inputs", execute=FILL_INPUTS))
    states = [part for s in model.states for part in _state_components(s)]
    if states:
        root.append(element("channel", *states, name="structsearch separation states"))
    return _document(root, _comment_text(
        ["Exported by structsearch: the separation states of "
         + ", ".join(c.model for c in model.coefficients) + " and the inputs the aerodynamics read."]
        + [line for line in model.equations if line.startswith("X") or "dX" in line]
        + [f"Set {FILL_INPUTS} to 0 to write the structsearch/* inputs and {DT} yourself.",
           "Inputs: " + ", ".join(f"{INPUTS[c].property} [{INPUTS[c].unit}]" for c in inputs_used(model))]))
