"""The effect library: unmodelled effects a diagnosis can add to a model structure.

Each effect knows the coefficients it applies to and how to add itself to a
candidate: a new regressor, a new separation state, or a change of a state's
kind (S -> Q adds tau2, Q -> U adds tau1). Applying an effect the candidate
already has, or to a coefficient it does not apply to, is a clear error. An effect
also declares the anomalies its term is the first-order signature of (:mod:`.equivalents`).
"""
from __future__ import annotations

import dataclasses

from dataclasses import dataclass, replace
from typing import Callable

from ..data.coefficients import LONGITUDINAL
from ..data.errors import DeclarationError
from ..fitting.candidates import Candidate
from .equivalents import ALPHA_DOT_TERM, VANE_LAG, Equivalent

ALL = LONGITUDINAL


@dataclass(frozen=True)
class Effect:
    name: str
    description: str
    applies_to: tuple[str, ...]
    apply: Callable[[Candidate], Candidate]
    # names of the parameters whose "absent" value is zero (Wald test of the improvement)
    new_parameters: Callable[[Candidate, Candidate], tuple[str, ...]]
    # measurement or structural anomalies its term equals to first order, with the conversion of the coefficient
    equivalents: tuple[Equivalent, ...] = ()


def _prefix(c: Candidate) -> str:
    return c.coefficient


def _state_names(c: Candidate) -> list[str]:
    return [n for n, _ in c.states]


def _symbol(name: str) -> str:
    return f"X_{name}" if name else "X"


def _uses(c: Candidate, text: str) -> bool:
    return any(expr.replace(" ", "") == text.replace(" ", "") for _, expr in c.regressors)


def _add_regressors(effect: str, pairs: list[tuple[str, str]]):
    def apply(c: Candidate) -> Candidate:
        existing = {n for n, _ in c.regressors}
        if any(_uses(c, expr) or name in existing for name, expr in pairs):
            raise DeclarationError(f"baseline {c.name} already contains the effect {effect!r}")
        return dataclasses.replace(c, name=f"{c.name} + {effect}", regressors=c.regressors + tuple(pairs),
                                   note=f"{c.name} with {effect}")
    return apply


def _regressor_effect(name: str, description: str, applies_to, make: Callable[[Candidate], list[tuple[str, str]]]):
    def apply(c: Candidate) -> Candidate:
        return _add_regressors(name, make(c))(c)

    def new(base: Candidate, changed: Candidate) -> tuple[str, ...]:
        old = {n for n, _ in base.regressors}
        return tuple(n for n, _ in changed.regressors if n not in old)
    return Effect(name, description, tuple(applies_to), apply, new)


def _per_state(c: Candidate, fmt: str, label: str) -> list[tuple[str, str]]:
    states = _state_names(c)
    if not states:
        raise DeclarationError(f"effect needs a separation state, and {c.name} has none")
    return [(f"{_prefix(c)}_{label}{('_' + s) if s else ''}", fmt.format(X=_symbol(s))) for s in states]


def _kind_change(name: str, description: str, from_kind: str, to_kind: str, parameter: str) -> Effect:
    def target(c: Candidate) -> str:
        kinds = dict(c.states)
        order = sorted(kinds, key=lambda s: (s != "ss", s))  # the stall strip first
        for s in order:
            if kinds[s] == from_kind:
                return s
        if any(k == to_kind or (to_kind == "Q" and k == "U") for k in kinds.values()):
            raise DeclarationError(f"baseline {c.name} already contains the effect {name!r}")
        raise DeclarationError(f"effect {name!r} needs a {from_kind} separation state; {c.name} has "
                               f"{', '.join(f'{_symbol(s)}: {k}' for s, k in kinds.items()) or 'none'}")

    def apply(c: Candidate) -> Candidate:
        if c.lift:
            raise DeclarationError(f"effect {name!r} changes a separation state, which {c.name} takes "
                                   f"from its lift model {c.lift}: diagnose the lift coefficient instead")
        s = target(c)
        states = tuple((n, to_kind if n == s else k) for n, k in c.states)
        return dataclasses.replace(c, name=f"{c.name} + {name}", states=states, note=f"{c.name} with {name}")

    def new(base: Candidate, changed: Candidate) -> tuple[str, ...]:
        s = target(base)
        return (f"{parameter}_{s}" if s else parameter,)
    return Effect(name, description, ALL, apply, new)


def _second_state() -> Effect:
    name = "second_separation_state"

    def apply(c: Candidate) -> Candidate:
        if c.lift:
            raise DeclarationError(f"effect {name!r} adds a separation state, which {c.name} takes from its "
                                   f"lift model {c.lift}: diagnose the lift coefficient instead")
        if len(c.states) != 1:
            raise DeclarationError(f"baseline {c.name} already contains the effect {name!r} "
                                   f"({len(c.states)} separation states)" if len(c.states) > 1 else
                                   f"effect {name!r} needs one separation state to add a second to")
        # the added state is the wing's (separating after the first): X_w, unless that name is taken
        state = "w" if "w" not in _state_names(c) else "w2"
        x = _symbol(state)
        term = {"CL": f"K_L({x})", "CD": f"1 - {x}", "Cm": f"(1 - {x})*CL"}[c.coefficient]
        states = c.states + ((state, "S"),)
        bounds = c.bounds + ((f"a_star_{state}", (0.22, 0.45)),)
        return dataclasses.replace(c, name=f"{c.name} + {name}",
                                   regressors=c.regressors + ((f"{c.coefficient}_{x}", term),), states=states,
                                   note=f"{c.name} with {name}", bounds=bounds)

    def new(base, changed):
        return (changed.regressors[-1][0],)
    return Effect(name, "a second separation state with its own K term", ALL, apply, new)


LIBRARY: dict[str, Effect] = {e.name: e for e in [
    _kind_change("unsteady_lag", "tau1 on a separation state (Q -> U)", "Q", "U", "tau1"),
    _kind_change("separation_delay", "tau2 on a separation state (S -> Q)", "S", "Q", "tau2"),
    _second_state(),
    _regressor_effect("pitch_rate", "q* regressor", ALL, lambda c: [(f"{c.coefficient}_qstar", "qstar")]),
    replace(_regressor_effect("alpha_dot", "alpha_dot regressor (distinct from q*)", ALL,
                              lambda c: [(f"{c.coefficient}_alphadot", ALPHA_DOT_TERM)]), equivalents=(VANE_LAG,)),
    _regressor_effect("elevator", "delta_e regressor", ALL, lambda c: [(f"{c.coefficient}_de", "de")]),
    _regressor_effect("elevator_effectiveness_loss", "X*delta_e regressor(s)", ("CL", "Cm"),
                      lambda c: _per_state(c, "{X}*de", "Xde")),
    _regressor_effect("thrust", "C_T regressor", ALL, lambda c: [(f"{c.coefficient}_CT", "CT")]),
    _regressor_effect("induced_drag", "C_L^2 in drag", ("CD",), lambda c: [("CD_CL2", "CL**2")]),
    _regressor_effect("separation_drag", "(1-X) terms in drag", ("CD",),
                      lambda c: _per_state(c, "1 - {X}", "1mX")),
    _regressor_effect("cp_shift", "(1-X)*C_L terms in pitch", ("Cm",),
                      lambda c: _per_state(c, "(1 - {X})*CL", "1mXCL")),
]}


def applicable(candidate: Candidate) -> list[Effect]:
    """Effects of the library that apply to the candidate's coefficient and that it does not contain yet."""
    out = []
    for e in LIBRARY.values():
        if candidate.coefficient not in e.applies_to:
            continue
        try:
            e.apply(candidate)
        except DeclarationError:
            continue
        out.append(e)
    return out


def get(name: str, coefficient: str) -> Effect:
    if name not in LIBRARY:
        raise DeclarationError(f"unknown effect {name!r}; the library holds {', '.join(LIBRARY)}")
    e = LIBRARY[name]
    if coefficient not in e.applies_to:
        raise DeclarationError(f"effect {name!r} does not apply to {coefficient} (it applies to "
                               f"{', '.join(e.applies_to)})")
    return e


# A candidate of one separation state, to read the regressors an effect adds as templates.
_PROBE_STATE = (("", "U"),)


def effect_terms(coefficient: str) -> list[tuple[str, str]]:
    """The regressors the library's regressor effects add to a ``coefficient`` model of one state (the
    term library's templates: X stands for each state)."""
    out = []
    for e in LIBRARY.values():
        if coefficient not in e.applies_to:
            continue
        probe = Candidate("probe", "", coefficient, (), _PROBE_STATE)
        try:
            changed = e.apply(probe)
        except DeclarationError:
            continue
        if changed.states == probe.states:  # a regressor effect (not a change of states)
            out += [pair for pair in changed.regressors if pair not in probe.regressors]
    return out


def equivalents_of(expression: str) -> list[tuple[str, Equivalent]]:
    """(effect, equivalent) for every declared equivalent whose term is ``expression`` (spaces aside)."""
    key = expression.replace(" ", "")
    return [(e.name, q) for e in LIBRARY.values() for q in e.equivalents if q.term.replace(" ", "") == key]
