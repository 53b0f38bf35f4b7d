"""One contract for every registered move kind (as scikit-learn runs its estimator checks over every registered
estimator): on structures of each coefficient (and a grey-box simulator term), the moves of a kind are of that kind
only; a nested kind's child holds its parent (its new parameters name terms the parent lacks, and the parent's
terms are all kept); a repairing kind never adds a term or a state; a kind a diagnosis does not make is not among
its kinds; an unknown kind is one error naming the registered ones."""
from __future__ import annotations

import pytest

from structsearch.data.errors import DeclarationError
from structsearch.diagnosis.offset import SimulatorTerm
from structsearch.discovery.moves import DIAGNOSE_KINDS, MOVE_KINDS, NESTED_KINDS, REGISTRY, REPAIR_KINDS, generate
from structsearch.discovery.terms import TermLibrary, normalise, shipped_terms
from structsearch.engine.separation import SeparationState
from structsearch.fitting.specs import find_candidate

PARENTS = ("CL-I", "CL-VI", "CD-I", "Cm-I")
LIFTS = {n: find_candidate(n) for n in ("CL-I", "CL-VI")}


def _library(coefficient: str, grey: bool) -> TermLibrary:
    simulator = (SimulatorTerm(f"sim:aero/coefficient/{coefficient}q", f"sim__{coefficient}q", ("q",)),) if grey else ()
    return TermLibrary(coefficient, tuple(shipped_terms(coefficient)), simulator=simulator)


def _parameters(c) -> set[str]:
    """Every parameter of structure ``c``: its terms' and its own states' (a nonlinear new parameter: tau2_w)."""
    return {n for n, _ in c.regressors} | {p for s, k in c.states for p in SeparationState(s, k, c.form_of(s)).parameters}


def _moves(kind: str):
    """Every (parent, move, child) of ``kind`` from the test structures, white and grey box."""
    out = []
    for name in PARENTS:
        parent = find_candidate(name)
        for grey in (False, True):
            out += [(parent, m, ch) for m, ch in generate(parent, _library(parent.coefficient, grey), LIFTS, (kind,))]
    return out


def test_the_search_reads_the_registry_and_keeps_no_list_of_its_own():
    """The beam search and the final choice judge a kind by the registry's lists (a kind missing from a second
    list switched the test that judges it), and a diagnosis never makes a move it does not declare."""
    from structsearch.discovery import explore, final_choice
    assert explore.NESTED_KINDS is NESTED_KINDS and final_choice.NESTED_KINDS is NESTED_KINDS
    assert explore.REPAIR_KINDS is REPAIR_KINDS
    assert "form" not in DIAGNOSE_KINDS and set(DIAGNOSE_KINDS) < set(MOVE_KINDS) == set(REGISTRY)
    assert not set(NESTED_KINDS) & set(REPAIR_KINDS) - {"state kind"}   # a simplification of a state kind nests


@pytest.mark.parametrize("kind", MOVE_KINDS)
def test_a_kind_generates_moves_of_its_own_kind_and_keeps_its_promises(kind):
    moves = _moves(kind)
    if REGISTRY[kind].generators:
        assert moves, f"no move of kind {kind!r} from {PARENTS}"
    for parent, move, child in moves:
        assert move.kind == kind, move
        before = {normalise(e) for _, e in parent.regressors}
        after = {normalise(e) for _, e in child.regressors}
        if kind in NESTED_KINDS and kind != "state kind":
            assert before <= after and set(move.new_parameters) <= _parameters(child), move.label
            assert move.new_parameters, move.label
        if kind in REPAIR_KINDS and kind not in ("replace", "state kind"):
            assert len(after) < len(before) or len(child.states) < len(parent.states) or child.known, move.label
        if kind == "replace":
            assert len(after) <= len(before) + 1 and (after != before or child.known), move.label


def test_an_unknown_kind_is_one_error_naming_the_kinds():
    parent = find_candidate("CL-I")
    with pytest.raises(DeclarationError, match="unknown move kind 'shuffle'.*add"):
        generate(parent, _library("CL", False), LIFTS, ("shuffle",))
