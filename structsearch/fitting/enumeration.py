"""Grid expansion: the candidates a grid document declares by blocks and rules, in order."""
from __future__ import annotations

import dataclasses
import difflib
from itertools import product
from typing import Sequence

import numpy as np

from ..data.errors import DeclarationError
from ..engine.regressors import parse
from ..engine.separation import SeparationState
from ..engine.static_forms import check_form
from .spec_types import ENTRY_TYPES, GRID_TYPES, check_types
from .candidates import MOMENT_REFERENCES, Candidate, Grid, from_roman, parse_drives, roman
from ..data.reading import shown


def _blocks(doc: dict, names: Sequence[str], where: str) -> list[tuple[str, str]]:
    table = doc.get("blocks", {})
    out: list[tuple[str, str]] = []
    for b in names:
        if b not in table:
            raise DeclarationError(f"{where}: unknown block {shown(b)} (blocks: {', '.join(table)})")
        for reg, expr in table[b].items():
            if any(reg == r for r, _ in out):
                raise DeclarationError(f"{where}: regressor {shown(reg)} appears twice")
            out.append((reg, str(expr)))
    return out


# Every key a grid file and each of its entries may hold: any other is a typo, refused with the close match.
GRID_KEYS = ("name", "coefficient", "prefix", "lift", "sets", "blocks", "bounds", "entry")
ENTRY_KEYS = ("name", "lift", "states", "note", "bounds", "from", "drop", "kinds", "prefix", "blocks", "always",
              "combinations", "regressors", "flight_effects", "x0", "moment_reference", "drive")


def check_keys(table: dict, known: Sequence[str], where: str) -> None:
    """Refuse a key of ``table`` not in ``known``, naming it, where it is and the close match."""
    unknown = [k for k in table if k not in known]
    if unknown:
        close = difflib.get_close_matches(unknown[0], known, n=1, cutoff=0.6)
        hint = f" (did you mean {shown(close[0])}?)" if close else f" (known: {', '.join(known)})"
        raise DeclarationError(f"{where}: unknown key {shown(unknown[0])}{hint}")


def _check_grid(doc: dict, source: str) -> None:
    """Refuse a grid document with an unknown key, without its name, coefficient or entries, or whose entries are
    not tables."""
    check_keys(doc, GRID_KEYS, source)
    for key in ("name", "coefficient", "entry"):
        if key not in doc:
            raise DeclarationError(f"{source}: missing {shown(key)}")
    if not isinstance(doc["entry"], list) or not all(isinstance(e, dict) for e in doc["entry"]):
        raise DeclarationError(f"{source}: 'entry' must be a list of [[entry]] tables")
    check_types(doc, GRID_TYPES, source)
    for i, entry in enumerate(doc["entry"]):
        check_types(entry, ENTRY_TYPES, f"{source} [[entry]] #{i + 1}")


def _check_expressions(regs, where: str) -> None:
    """Parse every regressor's expression of a candidate, refusing one that is not a string or does not parse."""
    for reg_name, text in regs:   # parsed now (a grammar, never code): an error names the file and entry
        if not isinstance(text, str):
            raise DeclarationError(f"{where}: regressor {shown(reg_name)}: an expression is a quoted string, "
                                   f"not {shown(text)}")
        try:
            parse(text, known=())
        except DeclarationError as exc:
            raise DeclarationError(f"{where}: regressor {shown(reg_name)}: {exc}") from None


def _derived(entry: dict, candidates: Sequence[Candidate], where: str) -> tuple[Candidate, list]:
    """An entry ``from`` an earlier candidate: that candidate and its regressors less the entry's ``drop``."""
    base = next((c for c in candidates if c.name == entry["from"]), None)
    if base is None:
        raise DeclarationError(f"{where}: 'from' names {shown(entry['from'])}, which is not declared before it")
    drop = entry.get("drop", [])
    missing = [d for d in drop if d not in dict(base.regressors)]
    if missing:
        raise DeclarationError(f"{where}: cannot drop {shown(missing[0])}: not a regressor of {base.name}")
    return base, [r for r in base.regressors if r[0] not in drop]


def expand(doc: dict, source: str) -> Grid:
    """Expand a grid document (see :mod:`structsearch.fitting.specs`) into its candidates, in order."""
    _check_grid(doc, source)
    name, coefficient = doc["name"], doc["coefficient"]
    prefix = doc.get("prefix", f"{name}-")
    default_lift = doc.get("lift")
    counter = 0
    candidates: list[Candidate] = []
    used_bounds: set[str] = set()

    def add(cand_name: str | None, regs, states, lift, note, where, bounds=(), forms=(), reference="cg"):
        nonlocal counter
        if cand_name is None:
            counter += 1
            cand_name = prefix + roman(counter)
        else:
            number = from_roman(cand_name[len(prefix):]) if cand_name.startswith(prefix) else None
            if number is not None:
                counter = number
        if any(c.name == cand_name for c in candidates):
            raise DeclarationError(f"{where}: candidate name {shown(cand_name)} used twice")
        if not regs:
            raise DeclarationError(f"{where}: candidate {shown(cand_name)} has no regressors")
        _check_expressions(regs, where)
        try:
            own = {p for k, kind in states for p in _state_params(k, kind, dict(forms).get(k, "tanh"))}
        except DeclarationError as exc:   # an unknown kind: named with the file and entry that declare it
            raise DeclarationError(f"{where}: {exc}") from None
        used_bounds.update(b[0] for b in bounds if b[0] in own)
        candidates.append(Candidate(cand_name, name, coefficient, tuple(regs), tuple(states), lift, note,
                                    tuple(b for b in bounds if b[0] in own), tuple(forms),
                                    moment_reference=reference))

    for i, entry in enumerate(doc["entry"]):
        where = f"{source} [[entry]] #{i + 1}"
        check_keys(entry, ENTRY_KEYS, where)
        first_of_entry = len(candidates)
        lift = entry.get("lift", default_lift)
        states = _own_states(entry)
        note = entry.get("note", "")
        bounds = _bounds(doc.get("bounds", {}), f"{source} [bounds]")
        own_bounds = _bounds(entry.get("bounds", {}), f"{where} bounds")
        bounds += own_bounds
        before = set(used_bounds)
        used_bounds.clear()
        reference = _moment_reference(entry, coefficient, where)
        _declare_entry(doc, entry, where, candidates, add, (lift, states, note, bounds, own_bounds, reference))
        _with_flight_effects(candidates, first_of_entry, entry, where)
        _with_wings(candidates, first_of_entry, entry, where)
        unused = [k for k, _ in own_bounds if k not in used_bounds]
        if unused:
            raise DeclarationError(f"{where}: bounds for {shown(unused[0])}, which no candidate of this entry has as a "
                                   "separation parameter")
        used_bounds.update(before)
    unused = [k for k in doc.get("bounds", {}) if k not in used_bounds]
    if unused:
        raise DeclarationError(f"{source} [bounds]: bounds for {shown(unused[0])}, which no candidate of the grid has as "
                               "a separation parameter")
    return Grid(name, coefficient, tuple(candidates), source)


def _declare_entry(doc: dict, entry: dict, where: str, candidates: list[Candidate], add, context) -> None:
    """Declare an entry's candidates through ``add``: derived ``from`` another, one per combination of ``kinds``,
    one per set of ``combinations``, or one of its ``blocks`` and ``regressors``."""
    lift, states, note, bounds, own_bounds, reference = context
    prefix = doc.get("prefix", f"{doc['name']}-")
    sets = doc.get("sets", {})
    if "from" in entry:
        base, regs = _derived(entry, candidates, where)
        forms = {**dict(base.forms), **dict(_forms(entry, [n for n, _ in base.states], lift, where))}
        add(entry.get("name"), regs, base.states, base.lift, note, where, base.bounds + own_bounds,
            tuple(forms.items()), reference or base.moment_reference)
    elif "kinds" in entry:
        kinds = entry["kinds"]
        regs = _blocks(doc, entry.get("blocks", []), where)
        forms = _forms(entry, list(kinds), lift, where)
        for combo in product(*kinds.values()):
            st = tuple(zip(kinds.keys(), combo))
            add(entry.get("prefix", prefix) + "/".join(combo), regs, st, lift, note, where, bounds, forms,
                reference or "cg")
    elif "combinations" in entry:
        combos = entry["combinations"]
        if isinstance(combos, str):
            if combos not in sets:
                raise DeclarationError(f"{where}: unknown set {shown(combos)}")
            combos = sets[combos]
        forms = _forms(entry, [n for n, _ in states], lift, where)
        for combo in combos:
            add(None, _blocks(doc, list(entry.get("always", [])) + list(combo), where), states, lift, note,
                where, bounds, forms, reference or "cg")
    else:
        regs = _blocks(doc, entry.get("blocks", []), where)
        regs += [(k, str(v)) for k, v in entry.get("regressors", {}).items()]
        add(entry.get("name"), regs, states, lift, note, where, bounds, _forms(entry, [n for n, _ in states],
                                                                           lift, where), reference or "cg")


def _own_states(entry: dict) -> tuple[tuple[str, str], ...]:
    """The entry's own states (name, kind); a list of states names wing states instead (:func:`_with_wings`)."""
    declared = entry.get("states", {})
    return tuple(declared.items()) if isinstance(declared, dict) else ()


def _with_wings(candidates: list[Candidate], first: int, entry: dict, where: str) -> None:
    """The entry's wing states (``drive``, and ``states`` as a list naming the same ones) on the candidates it
    declared (from ``first``): lift-fed candidates only, each reading the lift model's wing state."""
    declared = entry.get("states", {})
    if "drive" not in entry:
        if isinstance(declared, list):
            raise DeclarationError(f"{where}: 'states' as a list names wing states: give each one's angle of "
                                   "attack in drive = { X_left = \"alpha - 0.5*pstar\", ... } (own states are a "
                                   "table of state names to kinds, such as { ss = \"S\" })")
        return
    wings = parse_drives(entry["drive"], where)
    if isinstance(declared, list) and sorted(declared) != sorted(f"X_{n}" for n, _ in wings):
        raise DeclarationError(f"{where}: states {declared} and drive {sorted(entry['drive'])} name different "
                               "wing states")
    for i in range(first, len(candidates)):
        if not candidates[i].lift:
            raise DeclarationError(f"{where} ({candidates[i].name}): wing states are the lift model's wing state "
                                   "at each wing's angle of attack: give the entry a lift model (lift = \"CL-II\")")
        candidates[i] = dataclasses.replace(candidates[i], wings=wings)


def _with_flight_effects(candidates: list[Candidate], first: int, entry: dict, where: str) -> None:
    """The entry's ``flight_effects`` (docs/interfaces.md 7.5) on the candidates it declared (from ``first``)."""
    from .flight_effects import check_declared, parse_effects
    effects = parse_effects(entry.get("flight_effects"), where)
    if not effects:
        return
    for i in range(first, len(candidates)):
        check_declared(effects, candidates[i].regressors, f"{where} ({candidates[i].name})",
                       fixed=candidates[i].moment_reference == "fixed")
        candidates[i] = dataclasses.replace(candidates[i], flight_effects=effects)
def _moment_reference(entry: dict, coefficient: str, where: str) -> str | None:
    """An entry's ``moment_reference`` ("cg" or "fixed", pitch grids only); None when it gives none."""
    if "moment_reference" not in entry:
        return None
    value = entry["moment_reference"]
    if value not in MOMENT_REFERENCES:
        raise DeclarationError(f"{where}: moment_reference must be one of "
                               f"{', '.join(repr(r) for r in MOMENT_REFERENCES)}, not {shown(value)}")
    if value == "fixed" and coefficient != "Cm":
        raise DeclarationError(f"{where}: moment_reference = \"fixed\" takes C_m about a fixed point; this grid "
                               f"models {coefficient}")
    return value


def _bounds(table, where: str) -> tuple[tuple[str, tuple[float, float]], ...]:
    """A bounds table {parameter: [lo, hi]}, each a pair of finite numbers with lo < hi."""
    out = []
    for key, value in table.items():
        ok = (isinstance(value, list) and len(value) == 2
              and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
              and all(np.isfinite(v) for v in value) and value[0] < value[1])
        if not ok:
            raise DeclarationError(f"{where}: {shown(key)} must be [lo, hi] with finite numbers lo < hi, not {shown(value)}")
        out.append((key, (float(value[0]), float(value[1]))))
    return tuple(out)


def _state_params(state: str, kind: str, form: str = "tanh") -> list[str]:
    return list(SeparationState(state, kind, form).parameters)


def _forms(entry: dict, states: Sequence[str], lift, where: str) -> tuple[tuple[str, str], ...]:
    """The entry's ``x0`` table (state name -> static separation form) checked against its ``states``: one
    DeclarationError naming the entry, the state or form and the close match."""
    table = entry.get("x0", {})
    if not isinstance(table, dict):
        raise DeclarationError(f"{where}: x0 is a table from state to form, such as x0 = {{ ss = \"goman\" }}, "
                               f"not {shown(table)}")
    if table and lift:
        raise DeclarationError(f"{where}: x0: a structure fed the lift model {shown(lift)} takes its states' forms from "
                               "that model")
    out = []
    for state, form in table.items():
        if state not in states:
            close = difflib.get_close_matches(state, list(states), n=1, cutoff=0.5)
            hint = f" (did you mean {shown(close[0])}?)" if close else ""
            raise DeclarationError(f"{where}: x0 names the state {shown(state)}, which the entry does not declare "
                                   f"(its states: {', '.join(states) or 'none'}){hint}")
        try:
            out.append((state, check_form(form)))
        except DeclarationError as exc:
            raise DeclarationError(f"{where}: x0 of state {shown(state)}: {exc}") from None
    return tuple(out)
