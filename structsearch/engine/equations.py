"""A stall model written as equations: its coefficient as the sum of its parameters times their regressors, each
separation state's equation, and what the helper functions of its regressors stand for; as text and as LaTeX.

The regressors are written as they are declared (the text a grid, a spec file or ``StallModel.declare`` gives);
a separation state ``X_n`` of kind S, Q or U follows :mod:`.separation`:

    S:  X = X0(alpha)
    Q:  X = X0(alpha - tau2 * alpha_dot)
    U:  tau1 * dX/dt + X = X0(alpha - tau2 * alpha_dot)
    X0(a) = 0.5 * (1 - tanh(a1 * (a - a_star)))

A state of another static form (:mod:`.static_forms`) writes its X0 as a named function of the effective angle and
its parameters (``X_ss = X0_goman(alpha; a_star_ss, k_e_ss, x_star_ss)``), defined on a "where" line.

Writing a string is not I/O: the engine's summaries carry these lines.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Mapping, Sequence

import sympy as sp

from ..data.coefficients import COEFFICIENTS
from .expressions import parse_expression
from .separation import SeparationState, is_delayed, is_lagged, is_vortex
from .static_forms import DEFAULT_FORM, FORMS, form_parameters, parse_form

# What each helper of the regressor language stands for (regressors.HELPERS), in words a reader checks.
HELPER_MEANINGS = {
    "K_L": "K_L(X) = ((1 + sqrt(X))/2)^2 * alpha (Kirchhoff's lift)",
    "K_D": "K_D(X) = ((1 - sqrt(X))/2)^2 * alpha^2 (separation drag)",
    "K2": "K2(X, m) = sin(pi * X^m) * CL (centre-of-pressure shift)",
    "KS": "KS(X) = (5*(1 - sqrt(X))^2 + 4*sqrt(X))/16 * CL (centre-of-pressure shift)",
    "max_half": "max_half(X) = max(1/2, X) (Van Ingen's elevator effectiveness)",
    "pos": "pos(x) = max(x, 0)",
}
# What each static form other than the tanh stands for (its record's meaning), in the base names of its parameters.
FORM_MEANINGS = {f.name: f.meaning for f in FORMS.values() if f.meaning}
# Regressor texts that are the constant 1: the parameter alone.
_ONE = {"1", "1.0"}
# How the data columns and states read in LaTeX; any other name is set upright with sympy's subscripts.
_LATEX_NAMES = {"alpha": r"\alpha", "alpha_dot": r"\dot{\alpha}", "qstar": r"q^{*}", "de": r"\delta_e",
                "pstar": r"p^{*}", "rstar": r"r^{*}", "beta": r"\beta", "da": r"\delta_a", "dr": r"\delta_r",
                **{c.name: c.latex for c in COEFFICIENTS.values()}, "CT": "C_T", "cbar": r"\bar{c}", "x_cg": r"x_{cg}",
                "V": "V", "q": "q"}


@dataclass(frozen=True)
class Equations:
    """A model's equations: ``text`` lines (the model, its states, then "where ..." lines for the helpers it
    calls) and the same model and states in ``latex`` (one equation a line, no delimiters)."""

    text: tuple[str, ...]
    latex: tuple[str, ...]

    def render(self, fmt: str = "text") -> str:
        """The equations as a block of ``fmt`` (text, markdown, html or latex; csv: nothing)."""
        if fmt == "csv" or not self.text:
            return ""
        if fmt in ("latex", "tex"):
            rows = [re.sub(r"^(.*?) = ", r"\1 &= ", line, count=1) for line in self.latex]
            return "\\begin{align*}\n" + " \\\\\n".join(rows) + "\n\\end{align*}"
        if fmt == "html":
            from html import escape
            return "<pre class=\"equations\">" + escape("\n".join(self.text)) + "</pre>"
        if fmt in ("markdown", "md"):
            return "```text\n" + "\n".join(self.text) + "\n```"
        return "\n".join(self.text)


def term(name: str, text: str) -> str:
    """One term of a model equation: ``name`` times its regressor ``text`` (bracketed where it is a sum)."""
    text = text.strip()
    if text in _ONE:
        return name
    return f"{name}*({text})" if has_top_level_sum(text) else f"{name}*{text}"


def has_top_level_sum(text: str) -> bool:
    """Whether ``text`` is a sum or difference at its top level (so a product with it needs brackets)."""
    depth = 0
    for i, ch in enumerate(text):
        depth += (ch == "(") - (ch == ")")
        if depth == 0 and ch in "+-" and i > 0 and text[i - 1] not in "eE*/(^":
            return True
    return False


def model_equation(coefficient: str, regressors: Sequence[tuple[str, str]]) -> str:
    """``coefficient`` as the sum of its parameters times their regressors ((name, text) pairs)."""
    terms = [term(name, text) for name, text in regressors]
    return f"{coefficient} = " + (" + ".join(terms) if terms else "0")


def _form_key(form: str) -> str:
    return parse_form(form)[0].name


def state_equation(name: str, kind: str, form: str = DEFAULT_FORM) -> str:
    """The equation of separation state ``X_name`` of ``kind`` (S, Q, U, L or V) and static ``form`` in its own
    parameters' names (a vortex state: the separation it follows, then the vortex, ``;`` between them)."""
    s = SeparationState(name, kind, form)
    p, x = s.parameter_name, s.symbol
    shift = f" - {p('tau2')}*alpha_dot" if is_delayed(kind) else ""
    if form == DEFAULT_FORM:
        static = f"0.5*(1 - tanh({p('a1')}*(alpha{shift} - {p('a_star')})))"
    else:
        static = f"X0_{_form_key(form)}(alpha{shift}; {', '.join(p(b) for b in form_parameters(form))})"
    if is_vortex(kind):
        xs, y = f"Xs_{name or 'v'}", f"Y_{name or 'v'}"
        return (f"{p('tau1')}*d{xs}/dt + {xs} = {static}; {p('tau_v')}*d{y}/dt + {y} = {xs}; "
                f"{x} = {y} - {xs}")
    return f"{p('tau1')}*d{x}/dt + {x} = {static}" if is_lagged(kind) else f"{x} = {static}"


def helpers_used(texts: Sequence[str]) -> list[str]:
    """The meaning of every helper function ``texts`` call, in the order of :data:`HELPER_MEANINGS`."""
    joined = " ".join(texts)
    return [meaning for helper, meaning in HELPER_MEANINGS.items() if re.search(rf"\b{helper}\(", joined)]


def with_values(line: str, values: Mapping[str, float | str]) -> str:
    """``line`` with each parameter that has a value in ``values`` written as it: a number at 4 significant
    digits, a text (an estimate with its uncertainty, as the report writes it: "(0.12 ± 0.01)") as it is."""
    for name in sorted(values, key=len, reverse=True):   # a1_ss before a1
        value = values[name]
        text = value if isinstance(value, str) else f"{float(value):.4g}"
        line = re.sub(rf"(?<![\w.]){re.escape(name)}(?![\w(])", lambda _m, t=text: t, line)
    return line.replace("+ -", "- ").replace("- -", "+ ")


# ----- LaTeX ---------------------------------------------------------------------------------------------------
def _latex_name(name: str) -> str:
    if name in _LATEX_NAMES:
        return _LATEX_NAMES[name]
    return sp.latex(sp.Symbol(name))


def parameter_latex(name: str) -> str:
    r"""A parameter set as code (``\mathtt``), so it reads as the name in the parameter table."""
    return r"\mathtt{" + name.replace("_", r"\_") + "}"


def regressor_latex(text: str) -> str:
    """A regressor's text in LaTeX: parsed (never evaluated), the helpers kept as named functions."""
    helpers = {name: sp.Function(name) for name in HELPER_MEANINGS}
    expr = parse_expression(text, sp.Symbol, helpers)
    names = {s: _latex_name(s.name) for s in expr.free_symbols}
    return sp.latex(expr, symbol_names=names)


def latex_model(coefficient: str, regressors: Sequence[tuple[str, str]]) -> str:
    terms = []
    for name, text in regressors:
        if text.strip() in _ONE:
            terms.append(parameter_latex(name))
            continue
        body = regressor_latex(text)
        body = rf"\left({body}\right)" if has_top_level_sum(text) else body
        terms.append(rf"{parameter_latex(name)}\, {body}")
    return f"{_latex_name(coefficient)} = " + (" + ".join(terms) if terms else "0")


def latex_state(name: str, kind: str, form: str = DEFAULT_FORM) -> str:
    s = SeparationState(name, kind, form)
    p, x = (lambda b: parameter_latex(s.parameter_name(b))), _latex_name(s.symbol)
    shift = rf" - {p('tau2')}\,\dot{{\alpha}}" if is_delayed(kind) else ""
    if form == DEFAULT_FORM:
        static = rf"\tfrac{{1}}{{2}}\left(1 - \tanh\left({p('a1')}\left(\alpha{shift} - {p('a_star')}\right)\right)\right)"
    else:
        args = ", ".join(p(b) for b in form_parameters(form))
        label = _form_key(form).replace("_", r"\_")
        static = rf"X_0^{{\mathrm{{{label}}}}}\left(\alpha{shift};\ {args}\right)"
    if is_vortex(kind):
        xs, y = rf"X^{{s}}_{{{name or 'v'}}}", rf"Y_{{{name or 'v'}}}"
        return (rf"{p('tau1')}\,\dot{{{xs}}} + {xs} = {static},\quad {p('tau_v')}\,\dot{{{y}}} + {y} = {xs},"
                rf"\quad {x} = {y} - {xs}")
    return rf"{p('tau1')}\,\dot{{{x}}} + {x} = {static}" if is_lagged(kind) else f"{x} = {static}"


def write_equations(coefficient: str, regressors: Sequence[tuple[str, str]], states: Sequence[tuple[str, str]],
                    *, state_note: str = "", values: Mapping[str, float | str] | None = None,
                    offset: tuple[str, str] | None = None) -> Equations:
    """The :class:`Equations` of a model of ``coefficient`` with ``regressors`` ((name, text) pairs) and
    ``states`` ((name, kind) pairs, or (name, kind, form) for a static form other than the tanh); ``state_note``
    follows each state's text line (where its parameters come from); with ``values`` each parameter that has one
    is written as its value in the text lines. ``offset``: a known term (column name, what it is) added with its
    coefficient fixed at 1, written first."""
    states = [tuple(st) if len(st) == 3 else (st[0], st[1], DEFAULT_FORM) for st in states]
    model = model_equation(coefficient, regressors)
    latex_line = latex_model(coefficient, regressors)
    if offset is not None:
        model = model.replace(" = ", f" = {offset[0]} + ", 1)
        latex_line = latex_line.replace(" = ", r" = \mathrm{" + offset[0].replace("_", r"\_") + "} + ", 1)
    text = [model] + [state_equation(*st) + state_note for st in states]
    if values:
        text = [with_values(line, values) for line in text]
    text += [f"where {m}" for m in helpers_used([t for _, t in regressors])]
    forms = dict.fromkeys(_form_key(f) for _, _, f in states if f != DEFAULT_FORM)
    text += [f"where {FORM_MEANINGS[f]}" for f in forms]
    if offset is not None:
        text.append(f"where {offset[0]} = {offset[1] or 'a data column'} (known, coefficient fixed at 1)")
    latex = [latex_line] + [latex_state(*st) for st in states]
    return Equations(tuple(text), tuple(latex))
