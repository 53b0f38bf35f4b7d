"""Ranking of a grid's candidates (the tables are rendered by :mod:`structsearch.report.tables`).

Admissible candidates (:mod:`structsearch.search.admissibility`) come first, ranked among
themselves; the others follow, ranked the same way among themselves, each with its reasons; failed
candidates come last. Within each group the ranking rule is:

Ranking rule (one-standard-error rule on validation data): the candidate with
the lowest validation MSE of the modelled coefficient sets the bar; every
candidate whose per-maneuver relative excess in validation MSE is, on average,
less than one standard error of that excess (or below 1 %) is "within noise" of it. Those come first, fewest
parameters first (then lowest validation MSE); the rest follow by validation MSE.
A candidate the data cannot identify (a parameter without a standard deviation)
is ranked after every identifiable one, whatever its error: its estimates mean
nothing. Failed candidates come last with their reason.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..engine.scores import weighted_mean_se
from .candidate_result import CandidateResult

# A relative excess below this is never a reason to prefer a larger model.
PRACTICAL_TOLERANCE = 0.01


def _paired_gap(a: CandidateResult, best: CandidateResult) -> tuple[float, float]:
    """Mean and standard error of the per-maneuver relative validation MSE excess over the best.

    Relative, because maneuvers differ in difficulty by orders of magnitude (a deep
    stall against a pullup); a missing effect shows as a consistent relative excess.
    """
    excess = np.array(a.validation.mse_maneuvers) / np.array(best.validation.mse_maneuvers) - 1.0
    return weighted_mean_se(excess, np.array(a.validation.n_maneuvers, float))


def _ordered(group: list[CandidateResult]) -> list[CandidateResult]:
    """One group best first by the one-standard-error rule, with ``within_noise``, ``gap``, ``gap_se``."""
    if not group:
        return []
    best = min(group, key=lambda s: s.mse_validation)
    placed = []
    for s in group:
        gap, se = _paired_gap(s, best)
        # one validation maneuver gives no standard error: only the practical tolerance applies
        bar = max(se, PRACTICAL_TOLERANCE) if np.isfinite(se) else PRACTICAL_TOLERANCE
        placed.append(s.ranked(gap=gap, gap_se=se, within_noise=bool(s is best or gap <= bar)))
    top = sorted((s for s in placed if s.within_noise), key=lambda s: (s.n_params, s.mse_validation))
    rest = sorted((s for s in placed if not s.within_noise), key=lambda s: s.mse_validation)
    return [s for s in top + rest if s.identifiable] + [s for s in top + rest if not s.identifiable]


def rank(results: list[CandidateResult],
         judge: Callable[[CandidateResult], tuple[str, ...]] | None = None) -> list[CandidateResult]:
    """One grid's results, best first, with ``admissible``, ``reasons``, ``rank``, ``within_noise``, ``gap``
    and ``gap_se`` set. ``judge`` gives a result's reasons for not being admissible (none: all are)."""
    judged = []
    for s in results:
        why = (f"fit failed: {s.error}",) if s.failed else tuple(judge(s)) if judge else ()
        judged.append(s.ranked(admissible=not why, reasons=why))
    admissible = _ordered([s for s in judged if not s.failed and s.admissible])
    others = _ordered([s for s in judged if not s.failed and not s.admissible])
    failed = [s for s in judged if s.failed]
    return [s.ranked(rank=i + 1) for i, s in enumerate(admissible + others)] + failed


def near_best(results: list[CandidateResult]) -> list[CandidateResult]:
    """Candidates within noise of the best-fitting one, admissible or not (fitted ones only)."""
    ok = [s for s in results if not s.failed]
    if not ok:
        return []
    best = min(ok, key=lambda s: s.mse_validation)
    out = []
    for s in ok:
        gap, se = _paired_gap(s, best)
        bar = max(se, PRACTICAL_TOLERANCE) if np.isfinite(se) else PRACTICAL_TOLERANCE
        if s is best or gap <= bar:
            out.append(s)
    return out


def passed_over(ranked: list[CandidateResult]) -> list[CandidateResult]:
    """Candidates that fit the validation data better than the winner but are not admissible."""
    ok = [s for s in ranked if not s.failed]
    if not ok or not ok[0].admissible:
        return []
    return [s for s in ok if not s.admissible and s.mse_validation < ok[0].mse_validation]
