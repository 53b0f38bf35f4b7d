"""A model written as equations (engine.equations): the text states what the model computes, summary() opens with
it in every format, and a search's cached result keeps it."""
import math

import numpy as np
import pytest
import sympy as sp

from structsearch.engine.equations import Equations, write_equations
from structsearch.engine.expressions import parse_expression
from structsearch.engine.regressors import HELPERS
from structsearch.engine.stallmodel import StallModel
from structsearch.fitting.candidate_result import CandidateResult

STATIC = {"ss": "S", "w": "S"}
REGRESSORS = {"CL0": "1", "CL_KL_ss": "K_L(X_ss)", "CL_KL_w": "K_L(X_w)", "CL_q": "q*cbar/V",
              "CL_de": "de - alpha"}
VALUES = {"a1_ss": 30.0, "a_star_ss": 0.24, "a1_w": 22.0, "a_star_w": 0.28, "CL0": 0.11, "CL_KL_ss": 2.1,
          "CL_KL_w": 2.9, "CL_q": 4.2, "CL_de": 0.37}


def test_the_text_names_every_term_and_state():
    eq = StallModel.declare("m", "CL", REGRESSORS, states={"ss": "U", "w": "Q"}).equations()
    assert eq.text[0] == "CL = CL0 + CL_KL_ss*K_L(X_ss) + CL_KL_w*K_L(X_w) + CL_q*q*cbar/V + CL_de*(de - alpha)"
    assert eq.text[1] == "tau1_ss*dX_ss/dt + X_ss = 0.5*(1 - tanh(a1_ss*(alpha - tau2_ss*alpha_dot - a_star_ss)))"
    assert eq.text[2] == "X_w = 0.5*(1 - tanh(a1_w*(alpha - tau2_w*alpha_dot - a_star_w)))"
    assert eq.text[3].startswith("where K_L(X) = ((1 + sqrt(X))/2)^2 * alpha") and len(eq.text) == 4


def _evaluate(line: str, columns: dict) -> np.ndarray:
    """The right-hand side of an equation line with values in it, evaluated through the project's parser (the
    text is parsed, never run) and the regressor language's own helpers."""
    rhs = line.split(" = ", 1)[1]
    expr = parse_expression(rhs, lambda n: sp.Symbol(n, real=True), HELPERS)
    names = sorted(s.name for s in expr.free_symbols)
    return np.broadcast_to(sp.lambdify([sp.Symbol(n, real=True) for n in names], expr, "numpy")(
        *[columns[n] for n in names]), columns["alpha"].shape)


def test_the_equation_with_its_values_computes_what_the_model_predicts(noise_free_lift):
    """Written with numbers, the state and model equations give the model's own output (static states, whose
    equation is algebraic): a wrong sign, a dropped bracket or a swapped parameter fails this."""
    _, data = noise_free_lift
    model = StallModel.declare("m", "CL", REGRESSORS, states=STATIC)
    text = write_equations("CL", list(REGRESSORS.items()), list(STATIC.items()), values=VALUES).text
    columns = {c: np.asarray(data[c], float) for c in ("alpha", "q", "de", "V")}
    columns["cbar"] = data.constants["cbar"]
    columns["X_ss"] = _evaluate(text[1], columns)
    columns["X_w"] = _evaluate(text[2], columns)
    predicted = model.predict(data, VALUES)
    # the values are written with 4 significant digits (exact here) and the two evaluations differ by rounding
    np.testing.assert_allclose(_evaluate(text[0], columns), predicted, rtol=1e-9, atol=1e-12)


def test_latex_is_balanced_and_names_the_parameters_as_the_table_does():
    eq = StallModel.declare("m", "CL", REGRESSORS, states={"ss": "U", "w": "S"}).equations()
    block = eq.render("latex")
    assert block.startswith("\\begin{align*}") and block.rstrip().endswith("\\end{align*}")
    assert block.count("{") == block.count("}") and block.count(r"\left") == block.count(r"\right")
    for name in REGRESSORS:
        assert r"\mathtt{" + name.replace("_", r"\_") + "}" in block
    assert r"\dot{X_{ss}}" in block and r"\tanh" in block and block.count("&=") == 3


def test_summary_opens_with_the_equations_in_every_format(noise_free_lift):
    _, data = noise_free_lift
    model = StallModel.declare("m", "CL", {"CL0": "1", "CL_KL": "K_L(X)", "CL_de": "de"}, states={"": "S"})
    fit = model.fit(data, start={"a1": 25.0, "a_star": 0.25})
    summary = fit.summary()
    assert summary.as_text().startswith("CL = CL0 + CL_KL*K_L(X) + CL_de*de\nX = 0.5*(1 - tanh(")
    assert summary.as_markdown().startswith("```text\nCL = CL0")
    assert summary.as_html().startswith('<pre class="equations">CL = CL0')
    assert summary.as_latex().startswith("\\begin{align*}\nC_L &= \\mathtt{CL0}")
    assert "CL = " not in summary.as_csv()   # a table of numbers only
    assert math.isfinite(fit.params["CL_KL"])


def test_a_drag_model_says_its_states_are_fixed():
    model = StallModel.declare("d", "CD", {"CD0": "1", "CD_X": "1 - X_ss"}, states={"ss": "U"},
                               fixed={"tau1_ss": 0.2, "tau2_ss": 0.02, "a1_ss": 30.0, "a_star_ss": 0.25})
    assert model.equations().text[1].endswith("(its parameters fixed, not estimated here)")


def test_a_cached_candidate_result_keeps_its_equations():
    eq = Equations(("CL = CL0 + CL_a*alpha",), ("C_L = \\mathtt{CL0} + \\mathtt{CL\\_a}\\, \\alpha",))
    result = CandidateResult(name="c", grid="lift", coefficient="CL", lift=None, seconds=0.0, equations=eq)
    back = CandidateResult.from_json(result.to_json())
    assert back.equations == eq
    assert CandidateResult.from_json(CandidateResult(name="c", grid="lift", coefficient="CL", lift=None,
                                                     seconds=0.0).to_json()).equations is None


@pytest.mark.parametrize("fmt", ["text", "markdown", "html", "latex"])
def test_a_fit_without_a_model_has_no_equation_block(fmt):
    assert Equations((), ()).render(fmt) == ""
