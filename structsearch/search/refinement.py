"""Refinement (thesis chapter 10): drop what the data cannot support while the fit barely changes.

A well-fitting candidate that is not admissible because some of its terms are insignificant or
strongly correlated is refined step by step, one term at a time: first the least significant
linear term whose t-test accepts zero and that has no partner correlated above |rho| = 0.8 (a
partner inflates its variance, so such terms are judged as a pair), then the less significant of
the most correlated pair above 0.8 (the thesis' threshold, read from the full correlation
matrix), as long as the held-out MSE (cross-validation, else validation) rises by less than 1 %.
A step that would leave a separation state without a regressor is not taken; the refinement
says so. Pairs are read from the correlations as estimated (the thesis' rule: C_L and C_L^2 are a
pair), not from the datum-free ones admissibility judges, where centring C_L dissolves that pair. A refined structure that equals a candidate already fitted (the thesis'
declared CD-IXr, for one) reuses that result and is reported as reached.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..engine.regressors import symbol_names
from ..engine.separation import SeparationState
from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate

# Correlated pairs above this are candidates for removal during refinement (thesis: 0.8).
REFINE_CORRELATION = 0.8
# A refinement step is kept when the held-out MSE rises by less than this fraction.
REFINE_TOLERANCE = 0.01
MAX_STEPS = 9


@dataclass(frozen=True)
class Refinement:
    """The steps taken from ``start`` and why the refinement ended."""

    start: str
    steps: tuple[tuple[Candidate, CandidateResult], ...]
    stopped: str
    reached: tuple[str, ...] = ()      # existing candidates a step turned out to be


def _refined(c: Candidate, drop: list[str], suffix: str) -> Candidate:
    """``c`` without the regressors in ``drop`` (all drops so far, relative to ``c``)."""
    regs = tuple(r for r in c.regressors if r[0] not in drop)
    return Candidate(f"{c.name}{suffix}", c.grid, c.coefficient, regs, c.states, c.lift,
                     f"refined from {c.name}: dropped {', '.join(drop)}", c.bounds)


def structure_key(c: Candidate) -> tuple:
    """What makes two candidates the same model: regressor expressions, states, lift model."""
    return (c.coefficient, tuple(sorted(t.replace(" ", "") for _, t in c.regressors)), tuple(sorted(c.states)),
            c.lift)


def _orphans(c: Candidate, drop: list[str]) -> list[str]:
    """Separation states of ``c`` that no regressor would use once ``drop`` is dropped."""
    used = {name for n, t in c.regressors if n not in drop for name in symbol_names(t)}
    symbols = [SeparationState(n, k).symbol for n, k in c.states]
    return [s for s in symbols if s not in used]


def _p(summary: CandidateResult, name: str) -> float:
    """A p-value for ordering; NaN (no standard deviation) counts as the least significant."""
    p = summary.p_values.get(name, float("nan"))
    return p if np.isfinite(p) else 2.0


def _correlated_pairs(summary: CandidateResult, linear: list[str]) -> list[tuple[str, str, float]]:
    corr = summary.correlation_matrix
    names = list(summary.names)
    pairs = [(a, b, float(corr[names.index(a), names.index(b)])) for i, a in enumerate(linear)
             for b in linear[i + 1:]]
    return sorted((p for p in pairs if np.isfinite(p[2]) and abs(p[2]) > REFINE_CORRELATION), key=lambda p: -abs(p[2]))


def refine(c: Candidate, summary: CandidateResult, fit: Callable[[Candidate], CandidateResult],
           known: dict[tuple, tuple[Candidate, CandidateResult]] | None = None) -> Refinement:
    """Refine ``c`` (fitted as ``summary``); ``fit`` fits a new structure, ``known`` maps the structures
    fitted already to their candidate and result (reused instead of refitting)."""
    known = known or {}
    steps, reached = [], []
    current, current_summary, dropped = c, summary, []
    stopped = "nothing left to drop"
    for step in range(1, MAX_STEPS + 1):
        linear = [r[0] for r in current.regressors]
        constant = linear[0] if current.regressors[0][1].strip() == "1" else None
        # backward elimination, one term per step: first the least significant term that has no strongly
        # correlated partner (a partner inflates a t-test's variance, so the pair is judged together),
        # then the less significant member of the most correlated pair
        pairs = [p for p in _correlated_pairs(current_summary, linear) if constant not in p[:2]]
        paired = {n for a, b, _ in pairs for n in (a, b)}
        weak = [n for n in current_summary.insignificant if n in linear and n != constant and n not in paired]
        if weak:
            drop = [max(weak, key=lambda n: _p(current_summary, n))]
            why = f"t-test accepts 0, p = {_p(current_summary, drop[0]):.2g}"
        elif pairs:
            a, b, rho = pairs[0]
            drop = [max((a, b), key=lambda n: _p(current_summary, n))]
            why = f"|rho({a}, {b})| = {abs(rho):.2f} > {REFINE_CORRELATION}"
        else:
            break
        orphans = _orphans(c, dropped + drop)
        if orphans:
            stopped = (f"dropping {', '.join(drop)} ({why}) would leave {', '.join(orphans)} without a regressor; "
                       "not taken")
            break
        candidate = _refined(c, dropped + drop, "r" + ("" if step == 1 else str(step)) + "-auto")
        same = known.get(structure_key(candidate))
        candidate, result = same if same is not None else (candidate, fit(candidate))
        if result.failed:
            stopped = f"the refined {candidate.name} failed: {result.error}"
            break
        rise = result.comparison.mse / current_summary.comparison.mse - 1
        if not np.isfinite(rise):
            stopped = f"the held-out MSE of {candidate.name} cannot be compared (not finite); not taken"
            break
        if rise > REFINE_TOLERANCE:
            stopped = f"dropping {', '.join(drop)} ({why}) raises the held-out MSE by {rise:.1%}; not taken"
            break
        steps.append((candidate, result))
        if same is not None:
            reached.append(candidate.name)
        current, current_summary, dropped = candidate, result, dropped + drop
    else:
        stopped = f"stopped after {MAX_STEPS} steps"
    return Refinement(c.name, tuple(steps), stopped, tuple(reached))
