"""The answer of a ranking: the admissible structure it ranks first, when it fits near the best fit, else the
statement that no admissible structure is near (docs/interfaces.md 8.1).

A structure the search rejects is never presented as the answer, and neither is an admissible one that fits much
worse than the best fit: the outputs then say "no admissible structure within X % of the best fit", name the
best fit with its reasons and the best admissible structure with its cost. One rule for ``search``, ``discover``
and ``diagnose``: the cost is the mean per-maneuver relative excess of held-out MSE (the ranking's statistic),
the tolerance :func:`structsearch.fitting.comparison.answer_bar`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..fitting.candidate_result import CandidateResult
from ..fitting.comparison import answer_bar, relative_excess

ADMISSIBLE = "admissible"
NONE_NEAR = "none_admissible_near"


@dataclass(frozen=True)
class Answer:
    """What a ranking answers: ``status`` (``admissible`` or ``none_admissible_near``), the ``tolerance`` it was
    judged by, the ``best_fit`` (lowest held-out MSE, admissible or not) with its ``best_fit_reasons``, the
    ``best_admissible`` structure (the ranking's first admissible one; None when none is) and its ``cost`` (its
    relative excess over the best fit; None without an admissible structure)."""

    status: str
    tolerance: float
    best_fit: str
    best_admissible: str | None
    cost: float | None
    best_fit_reasons: tuple[str, ...] = ()

    @property
    def answered(self) -> bool:
        return self.status == ADMISSIBLE

    @property
    def structure(self) -> str | None:
        """The answer's structure (None: no admissible structure is near the best fit)."""
        return self.best_admissible if self.answered else None

    def sentence(self) -> str:
        """The answer in words, as every output states it."""
        if self.answered:
            near = "the best fit" if self.best_admissible == self.best_fit else \
                f"{_percent(self.cost)} above the best fit {self.best_fit}"
            return f"{self.best_admissible} (admissible; {near})"
        worst = f"no admissible structure within {self.tolerance:.0%} of the best fit"
        fit = f"the best fit {self.best_fit} is not admissible ({'; '.join(self.best_fit_reasons) or 'no reason'})"
        other = (f"the best admissible one, {self.best_admissible}, fits {_percent(self.cost)} worse" if
                 self.best_admissible else "none is admissible")
        return f"{worst}: {fit}; {other}"

    def to_dict(self) -> dict:
        return {"status": self.status, "tolerance": self.tolerance, "best_fit": self.best_fit,
                "best_admissible": self.best_admissible,
                "cost": None if self.cost is None or not math.isfinite(self.cost) else self.cost,
                "best_fit_reasons": list(self.best_fit_reasons)}


def _percent(x: float | None) -> str:
    return "an unknown amount" if x is None or not math.isfinite(x) else f"{x:+.1%}"


def answer_of(ranked: list[CandidateResult]) -> Answer | None:
    """The answer of a ranking (:func:`structsearch.grid_search.ranking.rank`'s output); None when nothing
    was fitted."""
    from .ranking import _best_fitting, _scores, _use_cv   # the ranking's own comparison, not a copy
    fitted = [s for s in ranked if not s.failed and s.identifiable]
    if not fitted:
        return None
    use_cv = _use_cv(fitted)
    best = _best_fitting(fitted, use_cv)
    chosen = next((s for s in ranked if not s.failed and s.placement.admissible), None)
    if chosen is None:
        return Answer(NONE_NEAR, answer_bar(float("nan")), best.name, None, None, tuple(best.placement.reasons))
    a, b = _scores(chosen, use_cv), _scores(best, use_cv)
    cost, se = (0.0, float("nan")) if chosen is best else relative_excess(a.mse_maneuvers, b.mse_maneuvers,
                                                                          a.n_maneuvers)
    tolerance = answer_bar(se)
    status = ADMISSIBLE if math.isfinite(cost) and cost <= tolerance else NONE_NEAR
    return Answer(status, tolerance, best.name, chosen.name, cost, tuple(best.placement.reasons))
