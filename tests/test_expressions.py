"""Expressions of specs and term files are parsed by a grammar, never evaluated (engine/expressions.py)."""
import os

import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from structsearch.data.errors import DeclarationError
from structsearch.engine.regressors import BUILDING_BLOCKS, parse

KNOWN = ("alpha", "q", "V", "de", "CL", "cbar", "x_cg", "CT", "X", "X_ss", "X_w")
CANARY = "/tmp/structsearch-expression-canary"

HOSTILE = [
    f"__import__('os').system('touch {CANARY}')",
    f"exec(\"open('{CANARY}', 'w')\")",
    "().__class__.__bases__[0].__subclasses__()",
    "alpha.__class__", "lambda: 1", "alpha if 1 else 2", "[alpha]", "{1: 2}", "alpha; import os",
    "open('/etc/passwd')", "eval('1')", "getattr(alpha, 'x')", "Symbol('x')", "alpha[0]", "alpha @ q",
    "9**9**9", "2**10**100", "1e999999", "1" * 50, "(" * 200 + "alpha" + ")" * 200, "-" * 500 + "alpha",
    "de/0", "alpha/(q-q)", "log(0)", "K2(X)", "sqrt", "alpha,", "", "   ", "alpha ** ", "*alpha",
]


@pytest.mark.parametrize("text", HOSTILE)
def test_hostile_text_is_one_declaration_error_and_runs_nothing(text):
    with pytest.raises(DeclarationError) as err:
        parse(text, known=KNOWN)
    assert "\n" not in str(err.value)
    assert not os.path.exists(CANARY)


def test_the_error_names_the_offending_token_and_its_position():
    with pytest.raises(DeclarationError, match=r"unexpected character \"'\" at position 12"):
        parse("__import__('os')", known=KNOWN)
    with pytest.raises(DeclarationError, match="unknown function 'system' at position 1"):
        parse("system(alpha)", known=KNOWN)
    with pytest.raises(DeclarationError, match="divides by zero"):
        parse("de/0", known=KNOWN)


@pytest.mark.parametrize("name,template", sorted(BUILDING_BLOCKS.items()))
def test_every_building_block_parses_as_sympy_would(name, template):
    """The grammar reads what the grids declare into the same expression sympy's own parser made of it
    (compared on trusted text, the building blocks of the shipped grids)."""
    from structsearch.engine.regressors import HELPERS, NAMED_EXPRESSIONS
    text = template.replace("{X}", "X_ss")
    local = {n: sp.Symbol(n, real=True) for n in KNOWN}
    local.update(HELPERS)
    local.update({k: make() for k, make in NAMED_EXPRESSIONS.items()})
    assert parse(text, known=KNOWN) == sp.sympify(text, locals=local)


def test_precedence_and_functions():
    a, q = sp.Symbol("alpha", real=True), sp.Symbol("q", real=True)
    assert parse("-alpha**2", known=KNOWN) == -(a ** 2)
    assert parse("2**3**2", known=KNOWN) == 512
    assert parse("alpha - q - 1", known=KNOWN) == a - q - 1
    assert parse("alpha/q/2", known=KNOWN) == a / q / 2
    assert parse("tanh(alpha)*exp(q) + sqrt(abs(alpha)) + pi", known=KNOWN) == \
        sp.tanh(a) * sp.exp(q) + sp.sqrt(sp.Abs(a)) + sp.pi
    assert parse("1.5e-3*alpha", known=KNOWN) == sp.Float("1.5e-3") * a


_ALPHABET = st.sampled_from(list("alpha qVdeCLX_sw0123456789.+-*/(),'\"[]{}:;=<>!@#$%^&|~`\\ \t_eEK") +
                            ["__import__", "os", "system", "lambda", "exec", "eval", "open", "K_L(", "**", "sqrt(",
                             "getattr", ".__class__", "X_ss", "1e308", "9**9"])
hostile_texts = st.lists(_ALPHABET, max_size=40).map("".join) | st.text(max_size=60)


def _parses_or_declines(text):
    try:
        out = parse(text, known=KNOWN)
    except DeclarationError as exc:
        assert "\n" not in str(exc)
        return
    assert isinstance(out, sp.Expr)


@settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(hostile_texts)
def test_fuzzed_text_parses_or_is_declined(text):
    _parses_or_declines(text)


@pytest.mark.slow
@settings(max_examples=10_000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(hostile_texts)
def test_ten_thousand_fuzzed_texts_run_nothing(text):
    _parses_or_declines(text)
    assert not os.path.exists(CANARY)
