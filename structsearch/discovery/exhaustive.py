"""``discover --exhaustive``: every structure of a term library up to a number of terms, as one grid.

The library's templates are instantiated on the states a structure may have: for C_L two separation states of
its own, ``X_ss`` and ``X_w`` (each of kind U, the most general; a structure has a state exactly when one of its
terms reads it, with the box its move would give it, :data:`~.moves.NEW_STATES`); for C_D and C_m the states of
the lift model they are fed. Every subset of those terms of 1 to ``max_terms`` terms is a structure, in the order of
the library (combinations by size, then lexicographic): a grid whose fits are independent tasks, ranked as any
grid is (:func:`structsearch.grid_search.pipeline.search`). A library of n terms makes sum_k C(n, k) structures,
:func:`count` says how many before anything is fitted.
"""
from __future__ import annotations

import itertools
import math

from ..data.coefficients import coefficient as coefficient_record
from ..data.errors import DeclarationError
from ..fitting.candidates import Candidate
from .moves import NEW_STATES
from .terms import STATE_SYMBOL, TermLibrary

# the states a C_L structure may own, each of the most general kind (a simpler kind is discover's move, not a term)
OWN_STATES = ("ss", "w")
OWN_KIND = "U"
GRID = "exhaustive"


def count(n_terms: int, max_terms: int) -> int:
    """How many structures a library of ``n_terms`` terms makes with 1 to ``max_terms`` terms each."""
    return sum(math.comb(n_terms, k) for k in range(1, min(max_terms, n_terms) + 1))


def _state_names(lift: Candidate | None) -> tuple[str, ...]:
    return tuple(s for s, _ in lift.states) if lift is not None else OWN_STATES


def library_terms(library: TermLibrary, lift: Candidate | None) -> tuple[tuple[str, str], ...]:
    """The library's terms instantiated on the states a structure may have (module docstring)."""
    return tuple(library.instances(_state_names(lift)))


def name_of(coefficient: str, terms: tuple[tuple[str, str], ...]) -> str:
    """A structure of the exhaustive grid is named by its terms: ``CL-E(CL0, CL_KL_w)``."""
    return f"{coefficient}-E({', '.join(n for n, _ in terms)})"


def _structure(terms: tuple[tuple[str, str], ...], lift: Candidate | None, coefficient: str) -> Candidate:
    name = name_of(coefficient, terms)
    note = f"{coefficient} = " + " + ".join(f"{n}*{e}" if e != "1" else n for n, e in terms)
    if lift is not None:   # fed the lift model: its states, C_L and boxes
        return Candidate(name, GRID, coefficient, terms, lift.states, lift.name, note, lift.bounds, lift.forms)
    read = {(m.group(1) or "") for _, e in terms for m in STATE_SYMBOL.finditer(e)}
    boxes = dict(NEW_STATES)
    states = tuple((s, OWN_KIND) for s in OWN_STATES if s in read)
    bounds = tuple((f"a_star_{s}", boxes[s]) for s, _ in states)
    return Candidate(name, GRID, coefficient, terms, states, None, note, bounds)


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
            out.append(_structure(chosen, lift, library.coefficient))
    return out
