"""Units of a model's parameters, derived from its regressors' sympy expressions.

A linear parameter multiplies its regressor to give a dimensionless aerodynamic coefficient, so its unit is
the inverse of the regressor's: ``C_L alpha`` is per rad, ``C_L q*`` (q* = q cbar / V, in rad) per rad,
``C_D C_T`` dimensionless. The separation parameters have fixed units: tau1 and tau2 in s, a1 per rad and
a_star in rad. A unit is a mapping from base unit (rad, s, m) to exponent; a regressor over a column whose
unit is not known (a user's extra column) or whose expression mixes units has no unit (None), shown as
"unknown" rather than guessed.
"""
from __future__ import annotations

from fractions import Fraction
from typing import Mapping

import sympy as sp

from .static_forms import FORMS

Unit = dict  # base unit -> exponent (Fraction); {} is dimensionless

# docs/interfaces.md section 1: the campaign's columns (SI, angles in rad) and the aircraft constants
COLUMN_UNITS: Mapping[str, Mapping[str, int]] = {
    "t": {"s": 1}, "alpha": {"rad": 1}, "q": {"rad": 1, "s": -1}, "V": {"m": 1, "s": -1}, "de": {"rad": 1},
    "CL": {}, "CD": {}, "Cm": {}, "alpha_dot": {"rad": 1, "s": -1}, "CT": {}, "x_cg": {"m": 1},
    "theta": {"rad": 1}, "h": {"m": 1}, "CX": {}, "CZ": {}, "beta": {"rad": 1}, "p": {"rad": 1, "s": -1},
    "r": {"rad": 1, "s": -1}, "da": {"rad": 1}, "dr": {"rad": 1}, "phi": {"rad": 1}, "CY": {}, "Cl": {}, "Cn": {},
    "cbar": {"m": 1}, "S": {"m": 2}, "b": {"m": 1},
}
# the separation parameters of every state (their names carry the state's suffix: tau1_ss, a_star_w): the time
# constants in s, then every static curve's (its record in static_forms)
SEPARATION_UNITS: Mapping[str, Mapping[str, int]] = {
    "tau1": {"s": 1}, "tau2": {"s": 1}, "tau_v": {"s": 1},
    **{p: unit for form in FORMS.values() for p, unit in form.units.items()}}
_ORDER = ("rad", "s", "m")
# a pure number: it takes the unit of whatever it is added to (alpha - 6 deg is an angle)
_NUMBER = "number"


def _combine(a: Unit, b: Unit, sign: int = 1) -> Unit:
    out = dict(a)
    for key, power in b.items():
        out[key] = out.get(key, Fraction(0)) + sign * Fraction(power)
        if out[key] == 0:
            del out[key]
    return out


def _same(units):
    """The unit shared by ``units`` (numbers adapt to it); None when they disagree or one is unknown."""
    if any(u is None for u in units):
        return None
    dimensional = [u for u in units if u is not _NUMBER]
    if not dimensional:
        return _NUMBER
    first = dimensional[0]
    return first if all(u == first for u in dimensional[1:]) else None


def expression_unit(expr, states: tuple[str, ...] = ()):
    """The unit of a regressor expression; ``_NUMBER`` for a pure number, None when it cannot be told."""
    if expr.is_Number or expr.is_NumberSymbol:
        return _NUMBER
    if expr.is_Symbol:
        if expr.name in states:
            return {}  # a separation state is a fraction of attached flow
        unit = COLUMN_UNITS.get(expr.name)
        return {k: Fraction(v) for k, v in unit.items()} if unit is not None else None
    args = [expression_unit(a, states) for a in expr.args]
    if expr.is_Mul:
        if any(u is None for u in args):
            return None
        out = {}
        for u in args:
            if u is not _NUMBER:
                out = _combine(out, u)
        return out if any(u is not _NUMBER for u in args) else _NUMBER
    if expr.is_Add or isinstance(expr, (sp.Max, sp.Min, sp.Abs)):
        return _same(args)
    if expr.is_Pow:
        base, exponent = args
        if base is None or not expr.exp.is_Rational:
            return {} if base in ({}, _NUMBER) and exponent in ({}, _NUMBER) else None
        if base is _NUMBER:
            return _NUMBER
        power = Fraction(int(expr.exp.p), int(expr.exp.q))
        return {k: v * power for k, v in base.items()}
    # any other function (sin, tanh, exp, ...) gives a pure number; it may take an angle (rad is a ratio)
    return {} if all(u is _NUMBER or (u is not None and set(u) <= {"rad"}) for u in args) else None


def format_unit(unit) -> str:
    """"rad", "1/rad", "s", "rad/s", "-" (dimensionless) or "unknown"."""
    if unit is None:
        return "unknown"
    if unit is _NUMBER or not unit:
        return "-"

    def part(key, power):
        power = abs(power)
        return key if power == 1 else f"{key}^{power}" if power.denominator == 1 else f"{key}^({power})"
    keys = sorted(unit, key=lambda k: (_ORDER.index(k) if k in _ORDER else len(_ORDER), k))
    numerator = [part(k, unit[k]) for k in keys if unit[k] > 0]
    denominator = [part(k, unit[k]) for k in keys if unit[k] < 0]
    top = " ".join(numerator) or "1"
    if not denominator:
        return top
    return top + "/" + (denominator[0] if len(denominator) == 1 else "(" + " ".join(denominator) + ")")


def coefficient_unit(regressor_expr, states: tuple[str, ...] = ()) -> str:
    """The unit of the linear parameter that multiplies ``regressor_expr`` in a dimensionless coefficient."""
    unit = expression_unit(regressor_expr, states)
    if unit is None:
        return format_unit(None)
    if unit is _NUMBER:
        return "-"
    return format_unit({k: -v for k, v in unit.items()})


def separation_unit(parameter: str) -> str:
    """The unit of a separation parameter named ``tau1``, ``a_star_ss``, ... (None-unit: "unknown")."""
    for base in sorted(SEPARATION_UNITS, key=len, reverse=True):
        if parameter == base or parameter.startswith(base + "_"):
            return format_unit({k: Fraction(v) for k, v in SEPARATION_UNITS[base].items()})
    return format_unit(None)
