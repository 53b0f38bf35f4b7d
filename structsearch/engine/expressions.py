"""A grammar for the expressions of model specs and term libraries: parsed, never evaluated as code.

Spec and term files are swapped between colleagues; ``sympy.sympify`` would run any Python in them
(``__import__('os').system(...)``). This parser reads only::

    expression := term (("+" | "-") term)*
    term       := unary (("*" | "/") unary)*
    unary      := ("+" | "-") unary | power
    power      := atom ("**" unary)?                  (right-associative: a**b**c = a**(b**c))
    atom       := NUMBER | NAME | NAME "(" expression ("," expression)* ")" | "(" expression ")"

A NAME is a symbol (a campaign column, an aircraft constant, a separation state, a parameter), one of the
named expressions (``qstar``, ``spline``), the constant ``pi``, or, followed by "(", one of the declared
functions; anything else (a string, an attribute, a subscript, a keyword, an unknown function) is an
:class:`ExpressionError` naming the offending token and its position. Sizes are bounded so that a hostile
text cannot exhaust memory or time: its length, the nesting depth, the digits of a number and the size of a
numeric power.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Callable, Mapping

import sympy as sp

from ..data.errors import DeclarationError

MAX_LENGTH = 2000          # characters of one expression
MAX_DEPTH = 60             # nested parentheses, unary signs and powers
MAX_DIGITS = 40            # digits of one number
MAX_NUMERIC_EXPONENT = 64  # |b| in a**b when both are numbers (2**2**99 would never finish)

# plain mathematical functions beside the model's helpers
MATH_FUNCTIONS: Mapping[str, Callable] = {
    "sqrt": sp.sqrt, "exp": sp.exp, "log": sp.log, "sin": sp.sin, "cos": sp.cos, "tan": sp.tan,
    "tanh": sp.tanh, "abs": sp.Abs, "Abs": sp.Abs,
}
CONSTANTS: Mapping[str, sp.Expr] = {"pi": sp.pi}

_TOKEN = re.compile(r"""
    (?P<space>\s+)
  | (?P<number>(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?)
  | (?P<name>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<op>\*\*|[-+*/(),])
""", re.VERBOSE | re.ASCII)   # ASCII: \d would take any script's digits (300 Arabic-Indic ones pass a digit count)


class ExpressionError(DeclarationError):
    """An expression the grammar does not accept: the message names the token and its position."""


@dataclass(frozen=True)
class _Token:
    kind: str
    text: str
    position: int


def tokenize(text: str) -> list[_Token]:
    """The tokens of ``text``; an unknown character is an error naming it and its position."""
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"expression of {len(text)} characters (at most {MAX_LENGTH})")
    tokens, i = [], 0
    while i < len(text):
        m = _TOKEN.match(text, i)
        if m is None:
            raise ExpressionError(f"unexpected character {text[i]!r} at position {i + 1} of {text!r}")
        if m.lastgroup != "space":
            tokens.append(_Token(m.lastgroup, m.group(), i))
        i = m.end()
    return tokens


def parse_expression(text: str, symbols: Callable[[str], sp.Expr],
                     functions: Mapping[str, Callable]) -> sp.Expr:
    """The sympy expression ``text`` denotes; ``symbols(name)`` gives each bare name's value, ``functions``
    the callable names beyond :data:`MATH_FUNCTIONS`. Raises :class:`ExpressionError`."""
    if not isinstance(text, str):
        raise ExpressionError(f"an expression is text, not {type(text).__name__}")
    tokens = tokenize(text)
    if not tokens:
        raise ExpressionError("empty expression")
    parser = _Parser(text, tokens, symbols, {**MATH_FUNCTIONS, **functions})
    expr = parser.expression(0)
    if parser.i < len(tokens):
        parser.fail(tokens[parser.i], "unexpected")
    if expr.has(sp.zoo, sp.oo, -sp.oo, sp.nan):
        raise ExpressionError(f"{text!r} divides by zero or is not finite")
    return expr


def _log10(x: sp.Expr) -> float:
    """log10 |x| of a sympy number without converting a huge integer to a float."""
    if x == 0:
        return 0.0
    if x.is_Integer or x.is_Rational:
        p, q = abs(int(x.p)), abs(int(x.q))
        return (len(str(p)) - len(str(q))) if max(p, q) > 10 ** 300 else math.log10(p / q)
    value = abs(complex(x))
    return math.log10(value) if value > 0 else 0.0


class _Parser:
    def __init__(self, text, tokens, symbols, functions):
        self.text, self.tokens, self.symbols, self.functions = text, tokens, symbols, functions
        self.i = 0

    def fail(self, token: _Token | None, what: str):
        if token is None:
            raise ExpressionError(f"{self.text!r} ends too early")
        raise ExpressionError(f"{what} {token.text!r} at position {token.position + 1} of {self.text!r}")

    def peek(self) -> _Token | None:
        return self.tokens[self.i] if self.i < len(self.tokens) else None

    def take(self, text: str | None = None) -> _Token:
        token = self.peek()
        if token is None or (text is not None and token.text != text):
            self.fail(token, f"expected {text!r}, found" if text else "expected more after")
        self.i += 1
        return token

    def _deeper(self, depth: int) -> int:
        if depth >= MAX_DEPTH:
            raise ExpressionError(f"{self.text!r} nests deeper than {MAX_DEPTH}")
        return depth + 1

    def expression(self, depth: int) -> sp.Expr:
        depth = self._deeper(depth)
        value = self.term(depth)
        while (t := self.peek()) is not None and t.text in "+-" and t.kind == "op":
            self.i += 1
            right = self.term(depth)
            value = value + right if t.text == "+" else value - right
        return value

    def term(self, depth: int) -> sp.Expr:
        value = self.unary(depth)
        while (t := self.peek()) is not None and t.kind == "op" and t.text in ("*", "/"):
            self.i += 1
            right = self.unary(depth)
            value = value * right if t.text == "*" else value / right
        return value

    def unary(self, depth: int) -> sp.Expr:
        t = self.peek()
        if t is not None and t.kind == "op" and t.text in ("+", "-"):
            self.i += 1
            inner = self.unary(self._deeper(depth))
            return -inner if t.text == "-" else inner
        return self.power(depth)

    def power(self, depth: int) -> sp.Expr:
        base = self.atom(depth)
        t = self.peek()
        if t is None or t.text != "**":
            return base
        self.i += 1
        exponent = self.unary(self._deeper(depth))
        if base.is_number and exponent.is_number:
            self._check_numeric_power(t, base, exponent)
        return base ** exponent

    def _check_numeric_power(self, t: _Token, base: sp.Expr, exponent: sp.Expr) -> None:
        """A power of two numbers is computed exactly by sympy: bound its size before it is (9**9**9 has
        370 million digits)."""
        try:
            e = abs(float(exponent))
            digits = e * abs(_log10(base))
        except (TypeError, ValueError, OverflowError):
            e = digits = math.inf
        if e > MAX_NUMERIC_EXPONENT or digits > 300:
            self.fail(t, f"a numeric power beyond {MAX_NUMERIC_EXPONENT} or 1e300 at")

    def atom(self, depth: int) -> sp.Expr:
        t = self.take()
        if t.kind == "number":
            if len(re.sub(r"[^0-9]", "", t.text)) > MAX_DIGITS or not math.isfinite(float(t.text)):
                self.fail(t, f"a number of more than {MAX_DIGITS} digits or beyond 1e308:")
            return sp.Integer(t.text) if t.text.isdigit() else sp.Float(t.text)
        if t.kind == "name":
            nxt = self.peek()
            if nxt is not None and nxt.text == "(":
                return self.call(t, depth)
            if t.text in self.functions:
                self.fail(t, "a function without its arguments:")
            return CONSTANTS[t.text] if t.text in CONSTANTS else self.symbols(t.text)
        if t.text == "(":
            inner = self.expression(self._deeper(depth))
            self.take(")")
            return inner
        self.fail(t, "unexpected")

    def call(self, name: _Token, depth: int) -> sp.Expr:
        function = self.functions.get(name.text)
        if function is None:
            self.fail(name, "unknown function")
        self.take("(")
        args = [self.expression(self._deeper(depth))]
        while (t := self.peek()) is not None and t.text == ",":
            self.i += 1
            args.append(self.expression(self._deeper(depth)))
        self.take(")")
        try:
            return function(*args)
        except TypeError:
            raise ExpressionError(f"{name.text}() does not take {len(args)} argument(s) in {self.text!r}") from None
