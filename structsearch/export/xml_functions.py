"""A regressor of the expression grammar (:mod:`structsearch.engine.expressions`) as JSBSim function XML.

The regressor is parsed by the same parser the fits use (helpers expanded: ``K_L(X)`` is
``((1 + sqrt(X))/2)**2*alpha``), and its sympy tree is written node by node: a sum as ``<sum>``, a product as
``<product>``, a power as ``<pow>`` (``<sqrt>`` for 1/2, ``<quotient>`` for -1), ``Abs`` as ``<abs>``,
``sin``/``cos``/``tan``/``exp`` as themselves, ``log`` as ``<ln>``, ``tanh(x)`` as ``1 - 2/(1 + exp(2x))``
(JSBSim has no tanh); a number as ``<value>`` written with all 17 digits; a data column as the property of the
structsearch namespace that carries it (:data:`INPUTS`); an aircraft constant as its value; a separation state
as its property, clipped to [X_FLOOR, 1] as the fits clip it. Anything else (a column JSBSim has no source for,
a complex number) is one :class:`DeclarationError` naming the term.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Callable, Mapping

import sympy as sp

from ..data.coefficients import COEFFICIENTS
from ..data.errors import DeclarationError
from ..engine.regressors import X_FLOOR, parse

NAMESPACE = "structsearch"
FT = 0.3048          # m per ft
INCH = 0.0254        # m per in


def element(tag: str, *children: ET.Element, text: str | None = None, **attributes: str) -> ET.Element:
    """An XML element with ``children`` (and ``text``, ``attributes``)."""
    e = ET.Element(tag, {k.rstrip("_"): v for k, v in attributes.items()})
    e.extend(children)
    if text is not None:
        e.text = text
    return e


def value(x: float) -> ET.Element:
    """``<value>`` with every digit a double needs (repr), so that JSBSim reads back the same number."""
    return element("value", text=repr(float(x)))


def prop(name: str) -> ET.Element:
    return element("property", text=name)


@dataclass(frozen=True)
class Input:
    """A data column as JSBSim sees it: the namespace property that carries it (SI units, as the campaign's
    column) and how the states' system fills it from JSBSim's own properties (ft, slug, psf)."""

    column: str
    property: str
    unit: str
    source: Callable[[], ET.Element]     # the JSBSim expression, in the column's SI unit
    source_text: str                      # the same in words (documentation)


def _scaled(name: str, factor: float) -> Callable[[], ET.Element]:
    return lambda: element("product", prop(name), value(factor))


def _thrust_coefficient() -> ET.Element:
    # C_T = thrust / (qbar S): the propulsive body-x force over the dynamic pressure times the wing area (0 at rest)
    ratio = element("quotient", prop("forces/fbx-prop-lbs"), element("product", prop("aero/qbar-psf"),
                                                                       prop("metrics/Sw-sqft")))
    return element("ifthen", element("gt", prop("aero/qbar-psf"), value(0.0)), ratio, value(0.0))


def _input(column: str, suffix: str, unit: str, source: Callable[[], ET.Element], text: str) -> Input:
    return Input(column, f"{NAMESPACE}/{suffix}", unit, source, text)


# The campaign's columns (docs/interfaces.md section 1) a regressor or a state may read, and their JSBSim sources.
INPUTS: Mapping[str, Input] = {i.column: i for i in (
    _input("alpha", "alpha-rad", "rad", lambda: prop("aero/alpha-rad"), "aero/alpha-rad"),
    _input("alpha_dot", "alpha-dot-rad_sec", "rad/s", lambda: prop("aero/alphadot-rad_sec"),
           "aero/alphadot-rad_sec"),
    _input("q", "q-rad_sec", "rad/s", lambda: prop("velocities/q-rad_sec"), "velocities/q-rad_sec"),
    _input("V", "V-mps", "m/s", _scaled("velocities/vt-fps", FT), "velocities/vt-fps * 0.3048"),
    _input("de", "de-rad", "rad", lambda: prop("fcs/elevator-pos-rad"), "fcs/elevator-pos-rad"),
    _input("CT", "CT", "-", _thrust_coefficient, "forces/fbx-prop-lbs / (aero/qbar-psf * metrics/Sw-sqft)"),
    _input("x_cg", "x-cg-m", "m", _scaled("inertia/cg-x-in", INCH), "inertia/cg-x-in * 0.0254"),
    _input("theta", "theta-rad", "rad", lambda: prop("attitude/theta-rad"), "attitude/theta-rad"),
    _input("h", "h-m", "m", _scaled("position/h-sl-ft", FT), "position/h-sl-ft * 0.3048"),
    _input("beta", "beta-rad", "rad", lambda: prop("aero/beta-rad"), "aero/beta-rad"),
    _input("p", "p-rad_sec", "rad/s", lambda: prop("velocities/p-rad_sec"), "velocities/p-rad_sec"),
    _input("r", "r-rad_sec", "rad/s", lambda: prop("velocities/r-rad_sec"), "velocities/r-rad_sec"),
    _input("da", "da-rad", "rad", lambda: prop("fcs/left-aileron-pos-rad"), "fcs/left-aileron-pos-rad"),
    _input("dr", "dr-rad", "rad", lambda: prop("fcs/rudder-pos-rad"), "fcs/rudder-pos-rad"),
    _input("Mach", "Mach", "-", lambda: prop("velocities/mach"), "velocities/mach"),
)}


def output_property(coefficient: str) -> str:
    """The property holding a modelled coefficient (``structsearch/CL``)."""
    return f"{NAMESPACE}/{coefficient}"


def state_property(symbol: str) -> str:
    """The property holding a separation state (``structsearch/X_ss``)."""
    return f"{NAMESPACE}/{symbol}"


def term_property(parameter: str) -> str:
    """The property holding one term's contribution to its coefficient (``structsearch/terms/CL_KL_ss``)."""
    return f"{NAMESPACE}/terms/{parameter}"


@dataclass(frozen=True)
class Symbols:
    """What the names of a regressor stand for in JSBSim: ``outputs`` coefficient -> property (C_L read by drag
    and pitch is the lift model's output), ``states`` state symbol -> property, ``constants`` the aircraft's."""

    states: Mapping[str, str]
    constants: Mapping[str, float]
    outputs: Mapping[str, str]


def regressor_xml(text: str, symbols: Symbols, where: str) -> ET.Element:
    """The JSBSim function body of regressor ``text``; ``where`` names the term in an error."""
    try:
        expr = parse(text, known=())
    except DeclarationError as exc:
        raise DeclarationError(f"{where}: {exc}") from None
    return _node(expr, symbols, f"{where} = {text!r}")


_UNARY = {sp.sin: "sin", sp.cos: "cos", sp.tan: "tan", sp.exp: "exp", sp.log: "ln", sp.Abs: "abs"}


def _node(expr: sp.Expr, symbols: Symbols, where: str) -> ET.Element:
    def fail(why: str):
        raise DeclarationError(f"{where}: cannot be written as a JSBSim function: {why}")

    if expr.is_Number or (not expr.args and expr.is_number):      # 2, 1/2, pi, E, the imaginary unit
        number = complex(expr)
        if number.imag != 0 or not math.isfinite(number.real):
            fail(f"the number {expr} is not a finite real number")
        return value(number.real)
    if expr.is_Symbol:
        return _symbol(expr.name, symbols, fail)
    args = [_node(a, symbols, where) for a in expr.args]
    if expr.is_Add:
        return element("sum", *args)
    if expr.is_Mul:
        return element("product", *args)
    if expr.is_Pow:
        base, exponent = args
        if expr.exp == sp.Rational(1, 2):
            return element("sqrt", base)
        if expr.exp == -1:
            return element("quotient", value(1.0), base)
        return element("pow", base, exponent)
    if expr.func in _UNARY:
        return element(_UNARY[expr.func], *args)
    if expr.func == sp.tanh:   # tanh x = 1 - 2/(1 + exp(2x)): no overflow to inf/inf at large |x|
        twice = element("product", value(2.0), args[0])
        return element("difference", value(1.0),
                       element("quotient", value(2.0), element("sum", value(1.0), element("exp", twice))))
    fail(f"JSBSim has no function for {expr.func.__name__}")


def _symbol(name: str, symbols: Symbols, fail) -> ET.Element:
    if name in symbols.states:
        # the fits read a state clipped to [X_FLOOR, 1] (sqrt(X) stays differentiable)
        return element("min", element("max", prop(symbols.states[name]), value(X_FLOOR)), value(1.0))
    if name in symbols.outputs:
        return prop(symbols.outputs[name])
    if name in symbols.constants:
        return value(symbols.constants[name])
    if name in INPUTS:
        return prop(INPUTS[name].property)
    if name in COEFFICIENTS:
        fail(f"it reads the measured {name}, which a simulator does not have (only the lift model's C_L is "
             "exported as an input of drag and pitch)")
    if name in ("cbar", "S", "b"):
        fail(f"the aircraft constant {name!r} is not in the campaign's [aircraft] table")
    fail(f"JSBSim has no source for the column {name!r} (the inputs it fills: {', '.join(INPUTS)})")


def columns_read(text: str) -> set[str]:
    """The data columns (of :data:`INPUTS`) a regressor reads."""
    return {s.name for s in parse(text, known=()).free_symbols if s.name in INPUTS}
