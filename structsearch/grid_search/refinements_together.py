"""Several refinements at once: each refinement's next fit is made beside the others', in one call of the fitter.

A refinement is a chain (a step starts from the one before), but the refinements of different candidates are
independent: walked together, round by round, each round fits the structure every unfinished refinement asks
for next as one task graph (their starts and folds spread over the workers together). The walks advance in
the order of their starts after each round and share what they took (``known``), so the result is the same on
any number of workers: it depends on the fits, never on which finished first. A structure two refinements ask
for in the same round is fitted once. Where two refinements meet one structure, the one that reaches it in an
earlier round takes it and the other is told it reached it: one refinement after another could give the name
to the other (the same structure and fit, another name); on the campaigns measured the two agree.
"""
from __future__ import annotations

import dataclasses

from typing import Callable, Generator, Sequence

from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
from ..fitting.runner import model_key
from .refinement import Refinement, refinement_walk

FitMany = Callable[[list[Candidate]], list[CandidateResult]]


def refine_together(starts: Sequence[tuple[Candidate, CandidateResult]], fit_many: FitMany,
                    known: dict[tuple, tuple[Candidate, CandidateResult]],
                    alpha_range: tuple[float, float] | None = None) -> list[Refinement]:
    """The refinement of each of ``starts`` (a candidate and its fit), in their order; ``fit_many`` fits a
    round's structures together; ``known``: the structures fitted already (grows with the steps taken)."""
    walks = [refinement_walk(c, s, known, alpha_range) for c, s in starts]
    asked: dict[int, Candidate] = {}
    done: dict[int, Refinement] = {}
    for i, walk in enumerate(walks):
        _advance(i, walk, lambda w: next(w), asked, done)
    while asked:
        order = sorted(asked)
        fitted = _fit_once(fit_many, [asked[i] for i in order])
        for i, result in zip(order, fitted):
            _advance(i, walks[i], lambda w, r=result: w.send(r), asked, done)
    return [done[i] for i in range(len(walks))]


def _advance(i: int, walk: Generator, step: Callable[[Generator], Candidate], asked: dict[int, Candidate],
             done: dict[int, Refinement]) -> None:
    try:
        asked[i] = step(walk)
    except StopIteration as finished:
        asked.pop(i, None)
        done[i] = finished.value


def _fit_once(fit_many: FitMany, candidates: list[Candidate]) -> list[CandidateResult]:
    """Each candidate's fit, a structure asked for twice fitted once (the later asker gets it under its name)."""
    first: dict[tuple, int] = {}
    for i, c in enumerate(candidates):
        first.setdefault(model_key(c), i)
    unique = sorted(set(first.values()))
    results = dict(zip(unique, fit_many([candidates[i] for i in unique])))
    return [results[i] if i in results else
            dataclasses.replace(results[first[model_key(c)]], name=c.name, grid=c.grid)
            for i, c in enumerate(candidates)]
