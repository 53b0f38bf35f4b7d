"""Moves on a candidate structure: the steps a structure search takes.

* ``add`` a term of the term library, ``drop`` a term, ``replace`` one term by another (a term on a state by a
  term on the same state, a term on signals by a term on signals: the structural replacements of the thesis,
  alpha -> C_L^2 in drag, a Cm_alpha term -> a centre-of-pressure term), or one term by a *modulated pair*:
  two library terms A and A * s whose ratio s is a signal (no separation state), such as C_L and x_cg C_L: the
  centre-of-pressure model Cm = C_L (x_cg - x_cp) / cbar replaces Cm_alpha alpha only as a pair, since
  either term alone in its place fits worse than alpha;
* ``state kind``: a separation state's kind one step along S <-> Q <-> U (own states only: a drag or pitch
  candidate takes its states from its lift model);
* ``add state`` / ``remove state``: a separation state with its own K term (K_L, 1 - X, (1 - X) C_L), or a state
  removed with every term on it;
* ``form`` (``discover`` only, :data:`DISCOVER_KINDS`; not a diagnosis' move): a separation state's static
  curve X0 replaced (own states only): a tanh by an exponential (goman),
  two breaks around a plateau (two_break) or a monotone spline of four knots (spline:4), any other form by the
  tanh (:mod:`structsearch.engine.static_forms`). Not nested (the tanh is no form's special case with some
  parameters at zero), so the out-of-sample test judges it;
* ``lift``: a drag or pitch candidate fed another lift model's states and C_L; each of its terms on a state
  is rewritten for every state of the new lift model (1 - X -> 1 - X_ss, 1 - X_w);
* ``effect``: an entry of the effect library (:mod:`.effects`) as a named composite move. A structural move
  that builds the same structure as an effect carries the effect's name;
* on the terms of a simulator baseline (a grey box, ``TermLibrary.simulator``; each a column ``sim__...`` of the
  gap's campaign, whose coefficient is flight minus simulator): ``rescale`` a term (its column added as a regressor
  ``sim:<function>`` whose coefficient c makes the term (1 + c) times the simulator's: nested, c = 0 is the
  parent), ``drop`` it (the known term ``-sim:<function>``, coefficient fixed at 1, takes it out of the simulator's
  sum) or ``replace`` it by a library term that reads one of the signals it reads (dropped, and the term added).

A move that leaves one of a candidate's own states without a regressor, or a candidate without a term, is not
generated.
"""
from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass
from functools import lru_cache
from typing import Callable, Mapping

from ..data.coefficients import coefficient
from ..data.errors import DeclarationError
from ..engine.regressors import parse, symbol_names
from ..engine.separation import SeparationState
from ..engine.static_forms import DEFAULT_FORM, FORMS
from ..fitting.candidates import Candidate
from ..grid_search.refinement import structure_key  # noqa: F401  (what makes two structures the same model)
from . import effects as fx
from .terms import STATE_SYMBOL, TermLibrary, columns_of, normalise, template_of, uses_state

# the static curves a tanh state may take in one move (every registered form; a knotted one with four knots; every
# other form's move is back to the tanh)
FORM_STEPS = tuple(f.name + (":4" if f.knotted else "") for f in FORMS.values() if f.name != DEFAULT_FORM)
KIND_STEPS = {"S": ("Q",), "Q": ("S", "U"), "U": ("Q",)}
# The states a move adds (each with its coefficient's K term: data.coefficients) and their default boxes
# (docs/catalogue.md: the stall strip separates first, then the wing).
NEW_STATES = (("ss", (0.05, 0.27)), ("w", (0.22, 0.45)), ("w2", (0.22, 0.45)))
# A structure a search reaches is named by its path from the start (``Cm-I + cp_shift + elevator``), readable in
# every table and line; only a path longer than a console line (fitting.fitter.CONSOLE_WIDTH) is named by its root
# and a digest of its terms instead (``Cm-I [04152628]``), which says nothing of what it holds.
MAX_NAME = 160


@dataclass(frozen=True)
class Move:
    """One step from a parent structure to a child."""

    kind: str                              # MOVE_KINDS
    label: str                             # what it does, in words ("add CD_CL2 = CL**2", "X_ss: S -> Q")
    new_parameters: tuple[str, ...] = ()   # parameters whose zero gives back the parent (nested moves)
    effect: str | None = None              # the effect library's name for the same change
    at_one_state: bool = False             # the effect at one of the states it adds terms for

    @property
    def name(self) -> str:
        """The effect's name when the move is one (with the term, when at one state), else the label."""
        if self.effect and self.at_one_state:
            return f"{self.effect}: {self.label}"
        return self.effect or self.label

    def to_dict(self) -> dict:
        return {"kind": self.kind, "label": self.label, "effect": self.effect, "at_one_state": self.at_one_state,
                "new_parameters": list(self.new_parameters)}


def _symbol(state: str) -> str:
    return f"X_{state}" if state else "X"


def _valid(c: Candidate) -> bool:
    if not c.regressors or len({normalise(e) for _, e in c.regressors}) != len(c.regressors):
        return False
    if len({n for n, _ in c.regressors}) != len(c.regressors):
        return False
    # a candidate's own state without a regressor is not identifiable
    return c.lift is not None or all(uses_state(c, _symbol(s)) for s, _ in c.states)


def _unique(name: str, taken: set[str]) -> str:
    out, k = name, 2
    while out in taken:
        out, k = f"{name}_{k}", k + 1
    return out


def child_name(parent: Candidate, label: str, regressors, states, lift, forms=()) -> str:
    name = f"{parent.name} + {label}"
    if len(name) <= MAX_NAME:
        return name
    key = (sorted(e for _, e in regressors), sorted(states), lift) + ((sorted(forms),) if forms else ())
    digest = hashlib.sha1(repr(key).encode()).hexdigest()[:8]
    root = parent.name.split(" + ")[0].split(" [")[0]
    return f"{root} [{digest}]"


def _child(parent: Candidate, label: str, regressors, states=None, lift=..., bounds=None, forms=None,
           known=None) -> Candidate:
    states = parent.states if states is None else tuple(states)
    lift = parent.lift if lift is ... else lift
    regressors = tuple(regressors)
    forms = parent.forms if forms is None else tuple(forms)
    kept = tuple((n, f) for n, f in forms if n in dict(states) and f != "tanh")
    # a replace of the parent: a child keeps what the move does not change (its moment reference, ...)
    return dataclasses.replace(parent, name=child_name(parent, label, regressors, states, lift, kept),
                               grid=parent.grid or "discover", regressors=regressors, states=states, lift=lift,
                               note=f"{parent.name} with {label}",
                               bounds=parent.bounds if bounds is None else tuple(bounds), forms=kept,
                               known=parent.known if known is None else tuple(known))


def _keep_bounds(bounds, states, forms=()) -> tuple:
    """The boxes of the separation parameters of ``states`` (name, kind) with static ``forms`` (name, form)."""
    names = {p for n, k in states for p in SeparationState(n, k, dict(forms).get(n, "tanh")).parameters}
    return tuple((k, v) for k, v in bounds if k in names)


def _term_moves(c: Candidate, library: TermLibrary) -> list[tuple[Move, Candidate]]:
    states = tuple(n for n, _ in c.states)
    have = {normalise(e) for _, e in c.regressors}
    names = {n for n, _ in c.regressors}
    options = [(n, e) for n, e in library.instances(states) if normalise(e) not in have]
    out = []
    for name, expr in options:
        name = _unique(name, names)
        label = f"add {name} = {expr}"
        out.append((Move("add", label, (name,)), _child(c, label, c.regressors + ((name, expr),))))
    simulator = {t.name for t in library.simulator}
    for i, (name, expr) in enumerate(c.regressors):
        if normalise(expr) == "1" or name in simulator:
            continue   # the intercept stays; a simulator term's rescale is undone by its own moves
        rest = c.regressors[:i] + c.regressors[i + 1:]
        label = f"drop {name}"
        out.append((Move("drop", label), _child(c, label, rest)))
        own = template_of(name, expr)
        for new_name, new_expr in options:
            other = template_of(new_name, new_expr)
            if own is None or other is None or own.per_state != other.per_state:
                continue
            if own.per_state and _state_of(expr) != _state_of(new_expr):
                continue
            new_name = _unique(new_name, {n for n, _ in rest})
            label = f"replace {name} by {new_name} = {new_expr}"
            out.append((Move("replace", label), _child(c, label, rest[:i] + ((new_name, new_expr),) + rest[i:])))
        # the pairs of terms the candidate does not have yet (``options``): one it has makes the pair an add
        for (a_name, a_expr), (b_name, b_expr) in modulated_pairs(tuple(options)):
            a_name = _unique(a_name, {n for n, _ in rest})
            b_name = _unique(b_name, {n for n, _ in rest} | {a_name})
            label = f"replace {name} by {a_name} = {a_expr} and {b_name} = {b_expr}"
            out.append((Move("replace", label),
                        _child(c, label, rest[:i] + ((a_name, a_expr), (b_name, b_expr)) + rest[i:])))
    return out


@lru_cache(maxsize=256)
def modulated_pairs(options: tuple[tuple[str, str], ...]) -> tuple[tuple[tuple[str, str], tuple[str, str]], ...]:
    """The pairs (A, B) of library instances with B = A * s for a signal s: B / A cancels to an expression of data
    columns that is not a number and holds no separation state (C_L and x_cg/cbar*C_L; not de and X*de, whose
    ratio is a state's). The intercept pairs with every term and is left out."""
    import sympy as sp
    parsed = []
    for name, expr in options:
        if normalise(expr) == "1":
            continue
        try:
            parsed.append((name, expr, parse(expr, known=symbol_names(expr))))
        except DeclarationError:
            continue
    out = []
    for a_name, a_expr, a in parsed:
        for b_name, b_expr, b in parsed:
            if a_name == b_name:
                continue
            ratio = sp.cancel(b / a)
            free = {str(x) for x in ratio.free_symbols}
            # a helper of a state (max_half(X), K2(X, 1)) holds the state's symbol: a free symbol of the ratio
            if not free or any(STATE_SYMBOL.fullmatch(x) for x in free):
                continue
            # B holds A as a factor: the ratio divides by none of A's symbols (qstar / de is two signals, not a
            # modulation of one; x_cg / cbar divides by a constant)
            if sp.fraction(ratio)[1].free_symbols & a.free_symbols:
                continue
            out.append(((a_name, a_expr), (b_name, b_expr)))
    return tuple(out)


def _simulator_moves(c: Candidate, library: TermLibrary, kinds) -> list[tuple[Move, Candidate]]:
    """``rescale``, ``drop`` and ``replace`` of each simulator term the structure still has (module docstring)."""
    have = {normalise(e) for _, e in c.regressors}
    options = [(n, e) for n, e in library.instances(tuple(n for n, _ in c.states)) if normalise(e) not in have]
    known, names = dict(c.known), {n for n, _ in c.regressors}
    out = []
    for t in library.simulator:
        if t.dropped in known:
            continue
        if "rescale" in kinds and t.name not in names:
            label = f"rescale {t.name}"
            out.append((Move("rescale", label, (t.name,)), _child(c, label, c.regressors + ((t.name, t.column),))))
        rest = tuple((n, e) for n, e in c.regressors if n != t.name)
        without = c.known + ((t.dropped, f"-{t.column}"),)
        if "drop" in kinds:
            label = f"drop {t.name}"
            out.append((Move("drop", label), _child(c, label, rest, known=without)))
        if "replace" not in kinds:
            continue
        for name, expr in options:
            if not columns_of(expr) & set(t.signals):
                continue
            name = _unique(name, {n for n, _ in rest})
            label = f"replace {t.name} by {name} = {expr}"
            out.append((Move("replace", label), _child(c, label, rest + ((name, expr),), known=without)))
    return out


def _state_of(expr: str) -> str:
    m = STATE_SYMBOL.search(expr)
    return (m.group(1) or "") if m else ""


def _state_moves(c: Candidate) -> list[tuple[Move, Candidate]]:
    """Kind changes, a new state with its K term, a state removed with its terms (own states only)."""
    if c.lift:
        return []
    out = []
    for i, (s, kind) in enumerate(c.states):
        for to in KIND_STEPS[kind]:
            states = c.states[:i] + ((s, to),) + c.states[i + 1:]
            form = c.form_of(s)
            before, after = SeparationState(s, kind, form).parameters, SeparationState(s, to, form).parameters
            label = f"{_symbol(s)}: {kind} -> {to}"
            out.append((Move("state kind", label, tuple(p for p in after if p not in before)),
                        _child(c, label, c.regressors, states, bounds=_keep_bounds(c.bounds, states, c.forms))))
        rest = tuple(r for r in c.regressors if _symbol(s) not in _symbols(r[1]))
        states = c.states[:i] + c.states[i + 1:]
        label = f"remove state {_symbol(s)}"
        out.append((Move("remove state", label),
                    _child(c, label, rest, states, bounds=_keep_bounds(c.bounds, states, c.forms))))
    taken = {s for s, _ in c.states}
    if "" not in taken:
        fresh = [(s, box) for s, box in NEW_STATES if s not in taken][:1]
        for s, box in fresh:
            name_t, expr_t = coefficient(c.coefficient).k_term
            name = name_t.format(c=c.coefficient, s=f"_{s}")
            expr = expr_t.replace("{X}", _symbol(s))
            states = c.states + ((s, "S"),)
            label = f"add state {_symbol(s)} with {name} = {expr}"
            out.append((Move("add state", label, (name,)),
                        _child(c, label, c.regressors + ((_unique(name, {n for n, _ in c.regressors}), expr),),
                               states, bounds=c.bounds + ((f"a_star_{s}", box),))))
    return out


def _form_moves(c: Candidate) -> list[tuple[Move, Candidate]]:
    """Each own state's static curve replaced: a tanh by each of :data:`FORM_STEPS`, another form by the tanh. The
    box of a tanh's alpha* (where its flow breaks: the stall strip before the wing) carries to the new form's
    angle of the same meaning (goman's alpha*, two_break's first break)."""
    if c.lift:
        return []
    out = []
    for s, _ in c.states:
        form = c.form_of(s)
        for to in (FORM_STEPS if form == "tanh" else ("tanh",)):
            forms = tuple({**dict(c.forms), s: to}.items())
            bounds = list(c.bounds)
            star = dict(c.bounds).get(f"a_star_{s}" if s else "a_star")
            if to == "two_break" and star is not None:
                bounds.append((f"a_k1_{s}" if s else "a_k1", star))
            label = f"{_symbol(s)}: X0 {form} -> {to}"
            out.append((Move("form", label), _child(c, label, c.regressors, c.states,
                                                    bounds=_keep_bounds(bounds, c.states, forms), forms=forms)))
    return out


def _symbols(expr: str) -> set[str]:
    return {m.group(0) for m in STATE_SYMBOL.finditer(expr)}


def _lift_moves(c: Candidate, lifts: Mapping[str, Candidate]) -> list[tuple[Move, Candidate]]:
    """The candidate fed each other lift model: its terms on a state rewritten for the new states."""
    if not c.lift:
        return []
    out = []
    for name, lift in lifts.items():
        if name == c.lift:
            continue
        new_states = tuple(n for n, _ in lift.states)
        regressors: list[tuple[str, str]] = []
        for reg_name, expr in c.regressors:
            t = template_of(reg_name, expr)
            pairs = t.instances(new_states) if t is not None and t.per_state else [(reg_name, expr)]
            for n, e in pairs:
                if normalise(e) not in {normalise(x) for _, x in regressors}:
                    regressors.append((_unique(n, {x for x, _ in regressors}), e))
        label = f"lift {c.lift} -> {name}"
        out.append((Move("lift", label), _child(c, label, regressors, lift.states, name, lift.bounds, lift.forms)))
    return out


def _effect_moves(c: Candidate) -> list[tuple[Move, Candidate]]:
    out = []
    for e in fx.applicable(c):
        changed = e.apply(c)
        child = _child(c, e.name, changed.regressors, changed.states, changed.lift, changed.bounds, changed.forms)
        out.append((Move("effect", e.name, tuple(e.new_parameters(c, changed)), e.name), child))
    return out


def _per_state_effect_terms(c: Candidate) -> dict[str, str]:
    """Normalised expression -> effect name, for the terms a per-state effect of the library would add to ``c``
    (X*de: elevator_effectiveness_loss, 1 - X: separation_drag, (1 - X)*C_L: cp_shift): adding one of them for
    one state is that effect at that state."""
    out = {}
    for e in fx.applicable(c):
        changed = e.apply(c)
        if changed.states != c.states or len(changed.regressors) - len(c.regressors) < 2:
            continue
        for _, expr in changed.regressors[len(c.regressors):]:
            out.setdefault(normalise(expr), e.name)
    return out


# ----- the registry of move kinds -----------------------------------------------------------------------------
Generator = Callable[[Candidate, TermLibrary, Mapping[str, Candidate]], list[tuple[Move, Candidate]]]


@dataclass(frozen=True)
class MoveKind:
    """One kind of move: its ``generators`` (each yields moves of one or more kinds from a structure, its term
    library and the lift models), ``nested`` (its child holds its parent, which is the child with the move's new
    parameters at zero: the Wald test judges it; otherwise the out-of-sample test), ``repairs`` (it removes or
    simplifies, never adds, so it may repair an inadmissible structure), ``in_diagnose`` (a diagnosis makes it:
    a diagnosis explains a gap by what it adds and the terms and states that carry them) and
    ``names_simulator_term`` (it names the simulator's own function that misses: the preferred explanation)."""

    name: str
    generators: tuple[Generator, ...]
    nested: bool
    repairs: bool
    in_diagnose: bool = True
    names_simulator_term: bool = False


def _terms(c, library, lifts):
    return _term_moves(c, library)


def _simulator(c, library, lifts):
    return _simulator_moves(c, library, MOVE_KINDS) if library.simulator else []


def _states(c, library, lifts):
    return _state_moves(c)


def _lifts(c, library, lifts):
    return _lift_moves(c, lifts)


def _forms(c, library, lifts):
    return _form_moves(c)


REGISTRY: Mapping[str, MoveKind] = {k.name: k for k in (
    MoveKind("add", (_terms,), nested=True, repairs=False),
    MoveKind("drop", (_terms, _simulator), nested=False, repairs=True),
    MoveKind("replace", (_terms, _simulator), nested=False, repairs=True),
    MoveKind("state kind", (_states,), nested=True, repairs=True),
    MoveKind("add state", (_states,), nested=True, repairs=False),
    MoveKind("remove state", (_states,), nested=False, repairs=True),
    MoveKind("lift", (_lifts,), nested=False, repairs=False),
    # the effect library's composite moves (.effects) are built for every structure, to name the structural moves
    # that equal one; as moves of their own only when asked
    MoveKind("effect", (), nested=True, repairs=False),
    # another static curve is a change of structure a diagnosis does not search (and each form child costs a
    # nonlinear fit of its own); not nested: the tanh is no form's special case with some parameters at zero
    MoveKind("form", (_forms,), nested=False, repairs=False, in_diagnose=False),
    MoveKind("rescale", (_simulator,), nested=True, repairs=False, names_simulator_term=True),
)}
MOVE_KINDS = tuple(REGISTRY)
DIAGNOSE_KINDS = tuple(k.name for k in REGISTRY.values() if k.in_diagnose)
DISCOVER_KINDS = MOVE_KINDS
NESTED_KINDS = tuple(k.name for k in REGISTRY.values() if k.nested)
REPAIR_KINDS = tuple(k.name for k in REGISTRY.values() if k.repairs)
NAMES_SIMULATOR_TERM = tuple(k.name for k in REGISTRY.values() if k.names_simulator_term)


def generate(c: Candidate, library: TermLibrary, lifts: Mapping[str, Candidate] | None = None,
             kinds=MOVE_KINDS) -> list[tuple[Move, Candidate]]:
    """Every valid move of ``kinds`` from ``c``, one per child structure (an effect's name wins): each generator
    of the kinds asked, once, in the registry's order."""
    if library.coefficient != c.coefficient:
        raise DeclarationError(f"the term library is for {library.coefficient}, and {c.name} models {c.coefficient}")
    unknown = [k for k in kinds if k not in REGISTRY]
    if unknown:
        raise DeclarationError(f"unknown move kind {unknown[0]!r}; the kinds are {', '.join(MOVE_KINDS)}")
    generators = dict.fromkeys(g for k in REGISTRY.values() if k.name in kinds for g in k.generators)
    found: list[tuple[Move, Candidate]] = [(m, ch) for g in generators for m, ch in g(c, library, lifts or {})
                                           if m.kind in kinds]
    # the effect library names the structural moves that equal an effect, whichever kinds are asked
    effect_moves = _effect_moves(c)
    by_key: dict[tuple, tuple[Move, Candidate]] = {}
    parent_key = structure_key(c)
    per_state = _per_state_effect_terms(c)
    named = []
    for move, child in found:
        if move.kind == "add" and len(child.regressors) == len(c.regressors) + 1 and \
                normalise(child.regressors[-1][1]) in per_state:
            effect = per_state[normalise(child.regressors[-1][1])]
            move = Move(move.kind, move.label, move.new_parameters, effect, at_one_state=True)
        named.append((move, child))
    found = named
    for move, child in found + effect_moves:
        key = structure_key(child)
        if key == parent_key or not _valid(child):
            continue
        if key in by_key and move.kind == "effect":
            # the structural move builds an effect of the library: it carries the effect's name
            first, first_child = by_key[key]
            by_key[key] = (Move(first.kind, first.label, first.new_parameters or move.new_parameters, move.effect),
                           dataclasses.replace(first_child, name=child.name, note=child.note))
        elif key not in by_key and (move.kind != "effect" or "effect" in kinds):
            by_key[key] = (move, child)
    return list(by_key.values())
