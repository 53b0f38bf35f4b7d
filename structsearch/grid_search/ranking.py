"""Ranking of a grid's candidates (the tables are rendered by :mod:`structsearch.reporting.tables`).

Admissible candidates (:mod:`structsearch.grid_search.admissibility`) come first, ranked among
themselves; the others follow, ranked the same way among themselves, each with its reasons; failed
candidates come last. Within each group the ranking rule is:

Ranking rule (one-standard-error rule on held-out data): candidates are compared by
maneuver-grouped cross-validation over the training maneuvers (each maneuver predicted by a fit
that did not see it), or by the validation maneuvers when the training set is too small for
folds; the validation maneuvers stay the final, independent check. The candidate with
the lowest held-out MSE of the modelled coefficient sets the bar; every
candidate whose per-maneuver relative excess in held-out MSE is, on average,
less than one standard error of that excess (or below 1 %) is "within noise" of it
(with fewer than three maneuvers there is no standard error: "n/a", 1 % only). Those come first, fewest
parameters first (then lowest held-out MSE); the rest follow by held-out MSE.
A candidate the data cannot identify (a parameter without a standard deviation)
is ranked after every identifiable one, whatever its error: its estimates mean
nothing. Failed candidates come last with their reason.
"""
from __future__ import annotations

from typing import Callable

from ..engine.ties import first_of_lowest, sort_with_ties
from ..fitting.candidate_result import CandidateResult
from ..fitting.comparison import relative_excess, within_noise


def _scores(s: CandidateResult, use_cv: bool):
    return s.cv if use_cv else s.validation


def _paired_gap(a: CandidateResult, best: CandidateResult, use_cv: bool) -> tuple[float, float]:
    """Mean and standard error of the per-maneuver relative MSE excess over the best, on the held-out
    training maneuvers (cross-validation) or on the validation maneuvers.

    Relative, because maneuvers differ in difficulty by orders of magnitude (a deep
    stall against a pullup); a missing effect shows as a consistent relative excess.
    """
    sa, sb = _scores(a, use_cv), _scores(best, use_cv)
    return relative_excess(sa.mse_maneuvers, sb.mse_maneuvers, sa.n_maneuvers)


def _use_cv(group: list[CandidateResult]) -> bool:
    """Compare by cross-validation when every candidate of the group has it: the same folds and, among the
    candidates with nonlinear parameters, the same method (a linear candidate's folds are exact fits)."""
    return bool(group) and all(s.cv is not None for s in group) and len({s.cv_folds for s in group}) == 1 \
        and len({s.cv_method for s in group if s.estimates.nonlinear_names}) <= 1


def _placed(group: list[CandidateResult], use_cv: bool) -> list[CandidateResult]:
    """Each fitted candidate with ``gap``, ``gap_se`` and ``within_noise`` against the group's best fit."""
    best = _best_fitting(group, use_cv)
    return [_measured(s, best, use_cv) for s in group]


def _best_fitting(group: list[CandidateResult], use_cv: bool) -> CandidateResult:
    return first_of_lowest(sorted(group, key=lambda s: s.name), lambda s: _scores(s, use_cv).mse)


def _measured(s: CandidateResult, best: CandidateResult, use_cv: bool) -> CandidateResult:
    """``s`` with its gap to ``best``, the gap's standard error and whether it is within noise."""
    gap, se = _paired_gap(s, best, use_cv)
    return s.placed(gap=gap, gap_se=se, within_noise=bool(s is best or within_noise(gap, se)))


def _ordered(group: list[CandidateResult], use_cv: bool) -> list[CandidateResult]:
    """One group best first by the one-standard-error rule."""
    if not group:
        return []
    placed = _placed(group, use_cv)
    # MSEs equal up to rounding (a structure at the nesting point of one it contains): the fewer parameters
    # first, then the name, on every machine
    def by_mse(items):
        return sort_with_ties(list(items), lambda s: _scores(s, use_cv).mse, lambda s: (s.n_params, s.name))
    top = sorted(by_mse(s for s in placed if s.placement.within_noise), key=lambda s: s.n_params)
    rest = by_mse(s for s in placed if not s.placement.within_noise)
    return [s for s in top + rest if s.identifiable] + [s for s in top + rest if not s.identifiable]


def rank(results: list[CandidateResult],
         judge: Callable[[CandidateResult], tuple[str, ...]] | None = None) -> list[CandidateResult]:
    """One grid's results, best first, with ``admissible``, ``reasons``, ``rank``, ``within_noise``, ``gap``
    and ``gap_se`` set. ``judge`` gives a result's reasons for not being admissible (none: all are)."""
    judged = []
    for s in results:
        why = (f"fit failed: {s.error}",) if s.failed else tuple(judge(s)) if judge else ()
        judged.append(s.placed(admissible=not why, reasons=why))
    # one basis of comparison for the whole grid, so both groups' gaps mean the same thing
    use_cv = _use_cv([s for s in judged if not s.failed])
    admissible = _ordered([s for s in judged if not s.failed and s.placement.admissible], use_cv)
    others = _ordered([s for s in judged if not s.failed and not s.placement.admissible], use_cv)
    if admissible:
        # the inadmissible are ordered among themselves, but their gap and "within noise" are measured against
        # the best-fitting admissible candidate, as everyone's: a rejected candidate never looks tied with the
        # winner because it is tied with the best of the rejected (issue 31)
        best = _best_fitting(admissible, use_cv)
        others = [_measured(s, best, use_cv) for s in others]
    failed = [s for s in judged if s.failed]
    return [s.placed(rank=i + 1) for i, s in enumerate(admissible + others)] + failed


def gap_reference(ranked: list[CandidateResult]) -> CandidateResult | None:
    """The candidate every gap of a ranking is measured against: the best-fitting admissible one, else the
    best-fitting one (None when nothing was fitted)."""
    fitted = [s for s in ranked if not s.failed]
    if not fitted:
        return None
    use_cv = _use_cv(fitted)
    return _best_fitting([s for s in fitted if s.placement.admissible] or fitted, use_cv)


def near_best(results: list[CandidateResult]) -> list[CandidateResult]:
    """Candidates within noise of the best-fitting one, admissible or not (fitted ones only)."""
    ok = [s for s in results if not s.failed]
    return [s for s in _placed(ok, _use_cv(ok)) if s.placement.within_noise] if ok else []


def passed_over(ranked: list[CandidateResult]) -> list[CandidateResult]:
    """Candidates that fit better than the winner (by the comparison's scores) but are not admissible."""
    ok = [s for s in ranked if not s.failed]
    if not ok or not ok[0].placement.admissible:
        return []
    use_cv = _use_cv(ok)
    return [s for s in ok if not s.placement.admissible and _scores(s, use_cv).mse < _scores(ok[0], use_cv).mse]
