"""Staged, warm-started fits: a candidate starts where a simpler candidate nested in it ended.

Candidate B is *nested* in A when both model the same coefficient without a lift model, B's
regressors are a subset of A's and B's separation parameters a subset of A's: a steady state
(a1, a_star) is nested in the quasi-steady one (+ tau2), which is nested in the unsteady one
(+ tau1); CL-III is nested in CL-IV, which adds a regressor. A grid is fitted in *waves* of
increasing size (separation parameters, then regressors), so every candidate finds the candidates
nested in it already fitted; it starts from the closest one's estimates (the most separation
parameters, then the lowest training MSE), with the parameters that candidate lacks at their
declared or default start. Quasi-random starts are kept where nesting gives no start (the first
wave). A single fit (``structsearch fit``) builds its own chain: the candidate with every state
steady, then quasi-steady, then as declared.

Drag and pitch candidates take their states from the lift model (nothing to stage): one wave.
"""
from __future__ import annotations

from typing import Sequence

from ..engine.separation import SeparationState
from .candidate_result import CandidateResult
from .candidates import Candidate

# A warm-started candidate is fitted from its warm start and this many starts in all (the warm start
# first, then quasi-random points): one, measured by `structsearch bench --staged` (results/bench.md).
WARM_STARTS = 1
# Kinds in order of nesting: each adds one parameter to the previous one.
KIND_ORDER = {"S": 0, "Q": 1, "U": 2}


def _size(c: Candidate) -> tuple[int, int]:
    return len(c.state_parameters), len(c.regressors)


def nested_in(inner: Candidate, outer: Candidate) -> bool:
    """Whether ``inner``'s fitted parameters are a start for ``outer`` (see the module's docstring)."""
    if inner.name == outer.name or inner.coefficient != outer.coefficient or inner.lift or outer.lift:
        return False
    if not inner.state_parameters:
        return False
    regressors = {text.replace(" ", "") for _, text in outer.regressors}
    return (set(inner.state_parameters) <= set(outer.state_parameters)
            and all(text.replace(" ", "") in regressors for _, text in inner.regressors))


def waves(candidates: Sequence[Candidate]) -> list[list[int]]:
    """Indices of ``candidates`` in waves of equal size; a candidate's nested ones lie in earlier waves.
    Candidates with a lift model or without separation parameters form one wave (nothing to stage)."""
    staged = [i for i, c in enumerate(candidates) if c.state_parameters and not c.lift]
    plain = [i for i in range(len(candidates)) if i not in set(staged)]
    sizes = sorted({_size(candidates[i]) for i in staged})
    out = [[i for i in staged if _size(candidates[i]) == s] for s in sizes]
    return ([plain] if plain else []) + out


def warm_start(c: Candidate, fitted: Sequence[tuple[Candidate, CandidateResult]]) -> dict[str, float] | None:
    """The estimates of the closest fitted candidate nested in ``c`` for ``c``'s separation parameters
    (those it lacks are left to ``c``'s own start); None when no fitted candidate is nested in ``c``."""
    donors = [(d, r) for d, r in fitted if not r.failed and nested_in(d, c)]
    if not donors:
        return None
    donor, result = min(donors, key=lambda dr: (-len(dr[0].state_parameters), dr[1].mse_train))
    return {k: result.params[k] for k in c.state_parameters if k in result.params}


def demoted(c: Candidate, highest: str) -> Candidate:
    """``c`` with every state's kind lowered to at most ``highest`` (S or Q)."""
    states = tuple((n, min(k, highest, key=KIND_ORDER.get)) for n, k in c.states)
    own = {p for n, k in states for p in SeparationState(n, k).parameters}
    return Candidate(f"{c.name} [{highest}]", c.grid, c.coefficient, c.regressors, states, c.lift,
                     f"stage of {c.name}", tuple(b for b in c.bounds if b[0] in own))


def stages(c: Candidate) -> list[Candidate]:
    """The chain a single fit of ``c`` climbs before ``c`` itself: every state steady, then at most
    quasi-steady (stages equal to ``c`` or to each other are left out)."""
    if c.lift or not c.states:
        return []
    out: list[Candidate] = []
    for highest in ("S", "Q"):
        stage = demoted(c, highest)
        if stage.states != c.states and (not out or stage.states != out[-1].states):
            out.append(stage)
    return out
