"""The term library a structure search draws from: regressor templates per coefficient.

A template is a regressor whose separation state, if it has one, is a placeholder: ``1 - {X}`` stands for
``1 - X_ss``, ``1 - X_w`` or ``1 - X``, whichever states the candidate has (its own, or its lift model's). The
default library is every regressor declared in the shipped grids (``model_specs/``) for the coefficient plus
the regressors of the effect library (:mod:`.effects`); users add their own in TOML (docs/interfaces.md,
section "Term library")::

    coefficient = "CD"                 # optional: the coefficient the terms are for
    [terms]
    CD_alpha3 = "alpha**3"             # any campaign column, constant or helper (K_L, K_D, K2, KS, max_half)
    CD_KD = "K_D(X)"                   # X: each separation state of the candidate in turn

A term on a column the campaign lacks is an error for a user's term (the file and the term named) and is
set aside, with the reason, for a shipped one (a pitch term on x_cg on a campaign without x_cg).
"""
from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..data.coefficients import COEFFICIENTS
from ..data.errors import DeclarationError
from ..engine.regressors import HELPERS, NAMED_EXPRESSIONS, parse, symbol_names
from ..fitting.candidates import Candidate
from ..fitting.specs import BUILTIN_GRIDS, load_grid, read_toml

# a separation state's symbol in an expression: X (the single state) or X_<name>
STATE_SYMBOL = re.compile(r"\bX(?:_([A-Za-z0-9]+))?\b")
_PLACEHOLDER = "{X}"


@dataclass(frozen=True)
class Term:
    """One regressor template: ``name`` and ``expression`` hold ``{s}`` and ``{X}`` where a state goes."""

    name: str
    expression: str
    source: str = "model_specs"

    @property
    def per_state(self) -> bool:
        return _PLACEHOLDER in self.expression

    def instances(self, states: tuple[str, ...]) -> list[tuple[str, str]]:
        """(name, expression) for each state of ``states`` (names), or the term itself without a state."""
        if not self.per_state:
            return [(self.name, self.expression)]
        return [(self.name.replace("{s}", f"_{s}" if s else ""), self.expression.replace(_PLACEHOLDER, f"X_{s}" if s else "X"))
                for s in states]


@dataclass(frozen=True)
class SimulatorTerm:
    """A term of a simulator baseline taken as a grey box: ``name`` (``sim:<function>``, e.g.
    ``sim:aero/coefficient/CLq``), the campaign ``column`` holding its values, and the campaign signals it reads
    (a library term that replaces it must read one of them)."""

    name: str
    column: str
    signals: tuple[str, ...] = ()

    @property
    def dropped(self) -> str:
        """The name of the known term that takes it out of the simulator's sum (``-sim:...``)."""
        return f"-{self.name}"


@dataclass(frozen=True)
class TermLibrary:
    """The templates of one coefficient, and the shipped ones set aside for the campaign (with why); ``simulator``:
    the terms of a simulator baseline the search may rescale, drop or replace (:mod:`.moves`)."""

    coefficient: str
    terms: tuple[Term, ...]
    set_aside: tuple[tuple[str, str], ...] = field(default=())
    simulator: tuple[SimulatorTerm, ...] = field(default=())

    def instances(self, states: tuple[str, ...]) -> list[tuple[str, str]]:
        out, seen = [], set()
        for t in self.terms:
            for name, expr in t.instances(states):
                key = normalise(expr)
                if key not in seen:
                    seen.add(key)
                    out.append((name, expr))
        return out

    def to_dict(self) -> dict:
        out = {"coefficient": self.coefficient, "terms": {t.name: t.expression for t in self.terms},
               "set_aside": dict(self.set_aside)}
        if self.simulator:
            out["simulator"] = {t.name: {"column": t.column, "signals": list(t.signals)} for t in self.simulator}
        return out


def normalise(expression: str) -> str:
    return expression.replace(" ", "")


def template_of(name: str, expression: str) -> Term | None:
    """The template of a declared regressor; None when it mixes two separation states."""
    states = {m.group(1) or "" for m in STATE_SYMBOL.finditer(expression)}
    if not states:
        return Term(name, expression)
    if len(states) > 1:
        return None
    (s,) = states
    expr = STATE_SYMBOL.sub(_PLACEHOLDER, expression)
    if s and f"_{s}" in name:
        i = name.index(f"_{s}")
        name = name[:i] + "{s}" + name[i + len(s) + 1:]
    else:
        name = name + "{s}"
    return Term(name, expr)


def _add(terms: list[Term], term: Term) -> None:
    """Append unless the expression is known; a name another template holds gets a numeral."""
    if any(normalise(t.expression) == normalise(term.expression) for t in terms):
        return
    names = {t.name for t in terms}
    name, k = term.name, 2
    while name in names:
        name = term.name.replace("{s}", "") + f"_{k}" + ("{s}" if term.per_state else "")
        k += 1
    terms.append(Term(name, term.expression, term.source))


def shipped_terms(coefficient: str) -> list[Term]:
    """Every regressor declared for ``coefficient`` in the shipped grids, then the effect library's."""
    from .effects import effect_terms
    if coefficient not in COEFFICIENTS:
        raise DeclarationError(f"no term library for coefficient {coefficient!r}; one of {', '.join(COEFFICIENTS)}")
    terms: list[Term] = []
    lift = load_grid("lift")
    for grid_name in BUILTIN_GRIDS:
        grid = lift if grid_name == "lift" else load_grid(grid_name, lift)
        if grid.coefficient != coefficient:
            continue
        for c in grid.candidates:
            for name, expr in c.regressors:
                t = template_of(name, expr)
                if t is not None:
                    _add(terms, t)
    for name, expr in effect_terms(coefficient):
        t = template_of(name, expr)
        if t is not None:
            _add(terms, Term(t.name, t.expression, "effect library"))
    return terms


def read_terms(path: str | Path, coefficient: str) -> list[Term]:
    """A user's term file (TOML, module docstring); every error names the file and the term."""
    path = Path(path)
    doc = read_toml(path)
    unknown = [k for k in doc if k not in ("coefficient", "terms")]
    if unknown:
        close = difflib.get_close_matches(unknown[0], ("coefficient", "terms"), n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]!r}?)" if close else " (a term file holds `coefficient` and [terms])"
        raise DeclarationError(f"{path}: unknown key {unknown[0]!r}{hint}")
    declared = doc.get("coefficient", coefficient)
    if declared != coefficient:
        raise DeclarationError(f"{path}: the terms are for {declared}, not {coefficient}")
    table = doc.get("terms")
    if not isinstance(table, dict) or not table:
        raise DeclarationError(f"{path}: no [terms] table (name = \"expression\" lines)")
    out: list[Term] = []
    for name, expr in table.items():
        if not isinstance(expr, str) or not expr.strip():
            raise DeclarationError(f"{path}: term {name!r}: the expression must be a non-empty string")
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
            raise DeclarationError(f"{path}: term {name!r}: a name is letters, digits and underscores")
        try:
            parse(STATE_SYMBOL.sub("X", expr), known=())
        except DeclarationError as exc:
            # one line: sympy's messages span several
            raise DeclarationError(f"{path}: term {name!r}: {' '.join(str(exc).split())}") from None
        t = template_of(name, expr)
        if t is None:
            raise DeclarationError(f"{path}: term {name!r}: one separation state per term (X stands for each)")
        out.append(Term(t.name, t.expression, str(path)))
    return out


def columns_of(expression: str) -> set[str]:
    """The campaign columns (or constants) a term reads: its free symbols other than states and helpers."""
    names = symbol_names(STATE_SYMBOL.sub("X", expression.replace(_PLACEHOLDER, "X")))
    return {n for n in names if not STATE_SYMBOL.fullmatch(n) and n not in HELPERS and n not in NAMED_EXPRESSIONS}


# what a drag or pitch structure's lift model gives it, whether or not the campaign logs it
FROM_LIFT_MODEL = {"CD": {"CL"}, "Cm": {"CL"}}


def _missing(term: Term, data, coefficient: str) -> list[str]:
    expr = term.expression.replace(_PLACEHOLDER, "X")
    given = FROM_LIFT_MODEL.get(coefficient, set())
    return sorted(c for c in columns_of(expr) if c not in data and c not in data.constants and c not in given)


def library_for(coefficient: str, data, user_terms: str | Path | None = None) -> TermLibrary:
    """The shipped templates (those the campaign ``data`` can evaluate) and a user's term file."""
    kept: list[Term] = []
    aside = []
    for t in shipped_terms(coefficient):
        missing = _missing(t, data, coefficient)
        if missing:
            aside.append((t.name.replace("{s}", ""), f"the campaign has no column {', '.join(missing)}"))
        else:
            kept.append(t)
    if user_terms is not None:
        for t in read_terms(user_terms, coefficient):
            missing = _missing(t, data, coefficient)
            if missing:
                raise DeclarationError(f"{user_terms}: term {t.name.replace('{s}', '')!r} reads "
                                       f"{', '.join(missing)}, which the campaign does not have")
            _add(kept, t)
    return TermLibrary(coefficient, tuple(kept), tuple(aside))


def uses_state(c: Candidate, symbol: str) -> bool:
    return any(symbol in {m.group(0) for m in STATE_SYMBOL.finditer(expr)} for _, expr in c.regressors)
