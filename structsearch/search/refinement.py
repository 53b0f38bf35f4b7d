"""Refinement of a grid's best candidate: drop what the data cannot support while the fit barely changes."""
from __future__ import annotations

from typing import Callable

from .candidate_result import CandidateResult
from .candidates import Candidate

# Correlated pairs above this are candidates for removal during refinement (thesis: 0.8).
REFINE_CORRELATION = 0.8
# A refinement step is kept when validation MSE rises by less than this fraction.
REFINE_TOLERANCE = 0.01


def _refined(c: Candidate, drop: list[str], suffix: str) -> Candidate:
    """``c`` without the regressors in ``drop`` (all drops so far, relative to ``c``)."""
    regs = tuple(r for r in c.regressors if r[0] not in drop)
    return Candidate(f"{c.name}{suffix}", c.grid, c.coefficient, regs, c.states, c.lift,
                     f"refined from {c.name}: dropped {', '.join(drop)}", c.bounds)


def refine(c: Candidate, summary: CandidateResult,
           fit: Callable[[Candidate], CandidateResult]) -> list[tuple[Candidate, CandidateResult]]:
    """Drop terms whose t-test accepts zero, then one of a strongly correlated pair while the fit barely changes."""
    out = []
    current, current_summary, dropped = c, summary, []
    for step in range(1, 10):
        linear = [r[0] for r in current.regressors]
        constant = linear[0] if current.regressors[0][1].strip() == "1" else None
        drop = [n for n in current_summary.insignificant if n in linear and n != constant]
        if not drop:
            pairs = [p for p in current_summary.high_correlations
                     if p[0] in linear and p[1] in linear and abs(p[2]) > REFINE_CORRELATION]
            if not pairs:
                break
            a, b, _ = pairs[0]
            worse = max((a, b), key=lambda n: current_summary.p_values[n])
            drop = [worse] if worse != constant else []
            if not drop:
                break
        candidate = _refined(c, dropped + drop, "r" + ("" if step == 1 else str(step)) + "-auto")
        result = fit(candidate)
        if result.failed or result.mse_validation > current_summary.mse_validation * (1 + REFINE_TOLERANCE):
            break
        out.append((candidate, result))
        current, current_summary, dropped = candidate, result, dropped + drop
    return out
