"""Refinement (thesis chapter 10): drop what the data cannot support while the fit barely changes.

A well-fitting candidate that is not admissible because some of its terms are insignificant or strongly
correlated is refined step by step, one term at a time. Each step tries, in this order, until one is taken:

1. every linear term whose t-test accepts zero: first those without a correlated partner, then those with one
   (issue 30: such a term was skipped for the pair, whose dropping then cost 4857 % and ended the refinement
   before the insignificant term was ever tried), each group least significant first;
2. the less significant member of each pair correlated above |rho| = 0.8 (the thesis' threshold), most
   correlated first. Correlations are read as admissibility reads them: with the data columns centred where
   centring keeps the model (``CandidateResult.centred_correlation``), else as estimated. A pair the ranking
   forgave (C_L with x_cg C_L, one column times another) is not chased.

A drop is taken when the held-out MSE (cross-validation, else validation) rises by less than 1 %. A drop that
removes a separation state's last regressor removes the state too (its parameters and box): the state can no
longer be identified, and keeping it would end the refinement (a drag or pitch candidate keeps its lift model's
states, whose parameters it does not estimate). Every structure a step takes is a candidate of the
ranking (the search adds them), so the best admissible one it passes through is kept. A refined structure that
equals a candidate already fitted (the thesis' declared CD-IXr, for one) reuses that result and is reported as
reached.
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
    """``c`` without the regressors in ``drop`` (all drops so far, relative to ``c``), and without the separation
    states no remaining regressor uses (with their parameters' boxes)."""
    regs = tuple(r for r in c.regressors if r[0] not in drop)
    # a drag or pitch candidate reads its lift model's states (their parameters fixed): one it no longer uses
    # costs nothing, and its states must stay the lift model's
    orphans = set() if c.lift else set(_orphans(c, drop))
    states = tuple((n, k) for n, k in c.states if SeparationState(n, k).symbol not in orphans)
    kept = {p for n, k in states for p in SeparationState(n, k).parameters}
    gone = {p for n, k in c.states for p in SeparationState(n, k).parameters} - kept
    bounds = tuple((name, box) for name, box in c.bounds if name not in gone)
    note = f"refined from {c.name}: dropped {', '.join(drop)}"
    if orphans:
        note += f" and the state(s) {', '.join(sorted(orphans))} they left without a regressor"
    return Candidate(f"{c.name}{suffix}", c.grid, c.coefficient, regs, states, c.lift, note, bounds)


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
    p = summary.estimates.p_values.get(name, float("nan"))
    return p if np.isfinite(p) else 2.0


def _correlated_pairs(summary: CandidateResult, linear: list[str]) -> list[tuple[str, str, float]]:
    """Pairs of ``linear`` correlated above REFINE_CORRELATION, most correlated first, read as admissibility reads
    them (data columns centred where that keeps the model, else as estimated)."""
    centred = summary.centred_correlation
    corr = np.asarray(centred, float) if len(centred) else summary.estimates.correlation
    names = list(summary.estimates.names)
    pairs = [(a, b, float(corr[names.index(a), names.index(b)])) for i, a in enumerate(linear)
             for b in linear[i + 1:]]
    return sorted((p for p in pairs if np.isfinite(p[2]) and abs(p[2]) > REFINE_CORRELATION), key=lambda p: -abs(p[2]))


def _options(current: Candidate, summary: CandidateResult) -> list[tuple[str, str]]:
    """The drops a step tries, in order (module docstring): (term, why)."""
    linear = [r[0] for r in current.regressors]
    constant = linear[0] if current.regressors[0][1].strip() == "1" else None
    pairs = [p for p in _correlated_pairs(summary, linear) if constant not in p[:2]]
    paired = {n for a, b, _ in pairs for n in (a, b)}
    weak = [n for n in summary.insignificant if n in linear and n != constant]
    # the insignificant terms without a correlated partner first (their t-tests are not inflated by one: the
    # thesis' q* before C_L in CD-IX), then those with one, each least significant first; then the pairs
    ordered = sorted(weak, key=lambda n: (n in paired, -_p(summary, n)))
    out = [(n, f"t-test accepts 0, p = {_p(summary, n):.2g}") for n in ordered]
    for a, b, rho in pairs:
        # the less significant member first; the other when that one was tried already (as insignificant)
        tried = {o for o, _ in out}
        for n in sorted((a, b), key=lambda x: -_p(summary, x)):
            if n not in tried:
                out.append((n, f"|rho({a}, {b})| = {abs(rho):.2f} > {REFINE_CORRELATION}"))
                break
    return out


def refine(c: Candidate, summary: CandidateResult, fit: Callable[[Candidate], CandidateResult],
           known: dict[tuple, tuple[Candidate, CandidateResult]] | None = None) -> Refinement:
    """Refine ``c`` (fitted as ``summary``); ``fit`` fits a new structure, ``known`` maps the structures
    fitted already to their candidate and result (reused instead of refitting)."""
    known = known or {}
    steps, reached = [], []
    current, current_summary, dropped = c, summary, []
    stopped = "nothing left to drop"
    for step in range(1, MAX_STEPS + 1):
        options = _options(current, current_summary)
        if not options:
            stopped = "nothing left to drop"
            break
        refused = []
        taken = None
        for name, why in options:
            drop = dropped + [name]
            if len(drop) >= len(c.regressors):
                refused.append(f"dropping {name} ({why}) would leave no term")
                continue
            candidate = _refined(c, drop, "r" + ("" if step == 1 else str(step)) + "-auto")
            same = known.get(structure_key(candidate))
            candidate, result = same if same is not None else (candidate, fit(candidate))
            if result.failed:
                refused.append(f"the refined {candidate.name} (without {name}) failed: {result.error}")
                continue
            rise = result.comparison.mse / current_summary.comparison.mse - 1
            if not np.isfinite(rise):
                refused.append(f"the held-out MSE without {name} cannot be compared (not finite)")
                continue
            if rise > REFINE_TOLERANCE:
                refused.append(f"dropping {name} ({why}) raises the held-out MSE by {rise:.1%}")
                continue
            taken = (candidate, result, name, same is not None)
            break
        if taken is None:
            stopped = "; ".join(refused) + "; not taken"
            break
        candidate, result, name, was_known = taken
        steps.append((candidate, result))
        if was_known:
            reached.append(candidate.name)
        current, current_summary, dropped = candidate, result, dropped + [name]
    else:
        stopped = f"stopped after {MAX_STEPS} steps"
    return Refinement(c.name, tuple(steps), stopped, tuple(reached))
