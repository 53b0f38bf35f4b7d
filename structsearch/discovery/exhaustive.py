"""``discover --exhaustive``: every structure of a term library up to a number of terms, as one grid.

The library's templates are instantiated on the states a structure may have: for C_L two separation states of
its own, ``X_ss`` and ``X_w``; a structure has a state exactly when one of its terms reads it, with the box its move
would give it (:data:`~.moves.NEW_STATES`), and each of its states takes each kind S, Q and U (a state's kind is
part of the structure, as its terms are); for C_D and C_m the states of the lift model they are fed. Every subset
of those terms of 1 to ``max_terms`` terms, with every choice of its states' kinds, is a structure, in the order of
the library (combinations by size, then lexicographic, then the kinds): a grid whose fits are independent tasks,
ranked as any grid is (:func:`structsearch.grid_search.pipeline.search`). :func:`count` says how many before
anything is fitted: a subset reading s states of its own makes 3^s structures.
"""
from __future__ import annotations

import itertools

from ..data.coefficients import coefficient as coefficient_record
from ..data.errors import DeclarationError
from ..fitting.candidates import Candidate
from .moves import NEW_STATES
from .terms import STATE_SYMBOL, TermLibrary

# the states a C_L structure may own, and the kinds each may take (the vortex and the lag without the delay are
# declared in grids, not enumerated)
OWN_STATES = ("ss", "w")
OWN_KINDS = ("S", "Q", "U")
GRID = "exhaustive"


def count(terms: tuple[tuple[str, str], ...], max_terms: int, fed: bool = False) -> int:
    """How many structures ``terms`` make with 1 to ``max_terms`` terms each (:func:`structures`' number)."""
    total = 0
    for k in range(1, min(max_terms, len(terms)) + 1):
        for chosen in itertools.combinations(terms, k):
            total += 1 if fed else len(OWN_KINDS) ** len(_read(chosen))
    return total


def _read(terms) -> tuple[str, ...]:
    """The states of its own a subset of terms reads, in :data:`OWN_STATES` order."""
    read = {(m.group(1) or "") for _, e in terms for m in STATE_SYMBOL.finditer(e)}
    return tuple(s for s in OWN_STATES if s in read)


def _state_names(lift: Candidate | None) -> tuple[str, ...]:
    return tuple(s for s, _ in lift.states) if lift is not None else OWN_STATES


def library_terms(library: TermLibrary, lift: Candidate | None) -> tuple[tuple[str, str], ...]:
    """The library's terms instantiated on the states a structure may have (module docstring)."""
    return tuple(library.instances(_state_names(lift)))


def name_of(coefficient: str, terms: tuple[tuple[str, str], ...], states=()) -> str:
    """A structure of the exhaustive grid is named by its terms and its own states' kinds:
    ``CL-E(CL0, CL_KL_w; X_w U)``."""
    kinds = "; " + ", ".join(f"X_{s} {k}" for s, k in states) if states else ""
    return f"{coefficient}-E({', '.join(n for n, _ in terms)}{kinds})"


def _structures(terms: tuple[tuple[str, str], ...], lift: Candidate | None, coefficient: str) -> list[Candidate]:
    note = f"{coefficient} = " + " + ".join(f"{n}*{e}" if e != "1" else n for n, e in terms)
    if lift is not None:   # fed the lift model: its states, C_L and boxes
        return [Candidate(name_of(coefficient, terms), GRID, coefficient, terms, lift.states, lift.name, note,
                          lift.bounds, lift.forms)]
    read, boxes, out = _read(terms), dict(NEW_STATES), []
    for kinds in itertools.product(OWN_KINDS, repeat=len(read)):
        states = tuple(zip(read, kinds))
        bounds = tuple((f"a_star_{s}", boxes[s]) for s in read)
        out.append(Candidate(name_of(coefficient, terms, states), GRID, coefficient, terms, states, None, note,
                             bounds))
    return out


def structures(library: TermLibrary, max_terms: int, lift: Candidate | None = None) -> list[Candidate]:
    """Every structure of ``library`` with 1 to ``max_terms`` terms (module docstring); ``lift`` feeds a drag or
    pitch structure (required for them, refused for a coefficient whose structures own their states)."""
    owns = coefficient_record(library.coefficient).owns_states
    if owns == (lift is not None):
        raise DeclarationError(f"{library.coefficient}: " + ("its structures own their states: no lift model feeds "
                                                             "them" if owns else "a lift model must feed its structures"))
    if max_terms < 1:
        raise DeclarationError(f"--max-terms must be at least 1, not {max_terms}")
    terms = library_terms(library, lift)
    out = []
    for k in range(1, min(max_terms, len(terms)) + 1):
        for chosen in itertools.combinations(terms, k):
            out += _structures(chosen, lift, library.coefficient)
    return out
