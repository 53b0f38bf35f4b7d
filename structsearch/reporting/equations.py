"""A candidate structure written as equations: its coefficient as the sum of its parameters times their regressors,
each separation state's equation, and what the helper functions in its regressors stand for.

The regressors are written as they are declared (the text a grid or spec file gives, parsed and checked by
:mod:`structsearch.engine.expressions`); a separation state ``X_n`` of kind S, Q or U follows
:mod:`structsearch.engine.separation`:

    S:  X = X0(alpha)
    Q:  X = X0(alpha - tau2 * alpha_dot)
    U:  tau1 * dX/dt + X = X0(alpha - tau2 * alpha_dot)
    X0(a) = 0.5 * (1 - tanh(a1 * (a - a_star)))
"""
from __future__ import annotations

import re
from typing import Mapping

from ..engine.separation import SeparationState
from ..fitting.candidates import Candidate

# What each helper of the regressor language stands for (engine.regressors.HELPERS), in words a reader checks.
HELPER_MEANINGS = {
    "K_L": "K_L(X) = ((1 + sqrt(X))/2)^2 * alpha (Kirchhoff's lift)",
    "K_D": "K_D(X) = ((1 - sqrt(X))/2)^2 * alpha^2 (separation drag)",
    "K2": "K2(X, m) = sin(pi * X^m) * CL (centre-of-pressure shift)",
    "KS": "KS(X) = (5*(1 - sqrt(X))^2 + 4*sqrt(X))/16 * CL (centre-of-pressure shift)",
    "max_half": "max_half(X) = max(1/2, X) (Van Ingen's elevator effectiveness)",
    "pos": "pos(x) = max(x, 0)",
}
# Regressor texts that are the constant 1: the parameter alone.
_ONE = {"1", "1.0"}


def _term(name: str, text: str) -> str:
    text = text.strip()
    if text in _ONE:
        return name
    # a sum or difference at the regressor's top level is bracketed so that the product reads as declared
    return f"{name}*({text})" if _has_top_level_sum(text) else f"{name}*{text}"


def _has_top_level_sum(text: str) -> bool:
    depth = 0
    for i, ch in enumerate(text):
        depth += (ch == "(") - (ch == ")")
        if depth == 0 and ch in "+-" and i > 0 and text[i - 1] not in "eE*/(^":
            return True
    return False


def model_equation(c: Candidate) -> str:
    """``c``'s coefficient as the sum of its parameters times their regressors."""
    terms = [_term(name, text) for name, text in c.regressors]
    return f"{c.coefficient} = " + (" + ".join(terms) if terms else "0")


def state_equation(name: str, kind: str) -> str:
    """The equation of separation state ``X_name`` of ``kind`` (S, Q or U) in its own parameters' names."""
    s = SeparationState(name, kind)
    p = s.parameter_name
    x = s.symbol
    shift = f" - {p('tau2')}*alpha_dot" if kind in ("Q", "U") else ""
    static = f"0.5*(1 - tanh({p('a1')}*(alpha{shift} - {p('a_star')})))"
    return f"{p('tau1')}*d{x}/dt + {x} = {static}" if kind == "U" else f"{x} = {static}"


def helpers_used(c: Candidate) -> list[str]:
    """The meaning of every helper function ``c``'s regressors call, in the order of :data:`HELPER_MEANINGS`."""
    texts = " ".join(text for _, text in c.regressors)
    return [meaning for helper, meaning in HELPER_MEANINGS.items() if re.search(rf"\b{helper}\(", texts)]


def equations(c: Candidate, values: Mapping[str, float] | None = None) -> list[str]:
    """Every line that states ``c``: its model equation, its states' equations (a drag or pitch candidate's are
    its lift model's, with that model's fitted parameters) and the helpers it calls. With ``values`` (estimates
    by parameter name), each parameter that has one is written as its value (4 significant digits; a text value, such
    as "(0.12 ± 0.01)", as it is)."""
    lines = [model_equation(c)]
    source = f"  (a state of the lift model {c.lift}, its parameters fixed at that model's fit)" if c.lift else ""
    lines += [state_equation(n, k) + source for n, k in c.states]
    if values:
        lines = [_with_values(line, values) for line in lines]
    return lines + [f"where {m}" for m in helpers_used(c)]


def _with_values(line: str, values: Mapping[str, float | str]) -> str:
    """``line`` with each parameter written as its value: a number at 4 significant digits, a text (an estimate
    with its uncertainty, as the report writes it) as it is."""
    for name in sorted(values, key=len, reverse=True):   # a1_ss before a1
        value = values[name]
        text = value if isinstance(value, str) else f"{float(value):.4g}"
        line = re.sub(rf"(?<![\w.]){re.escape(name)}(?![\w(])", lambda _m, t=text: t, line)
    return line.replace("+ -", "- ").replace("- -", "+ ")
