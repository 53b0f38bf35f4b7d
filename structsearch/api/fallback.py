"""A grid with no admissible structure at all: the structure search (``discover``'s moves over the grid's term
library) goes on from the minimal structure, and the admissible structures it fits in full are ranked beside the
grid, marked "discovered" (docs/interfaces.md 8.1). A drag or pitch search is fed the lift model the grid's best
fit is fed (its states and C_L), which must be one of the lift grid's structures."""
from __future__ import annotations

import dataclasses
from typing import Callable

from ..data.coefficients import LIFT, coefficient
from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
from ..fitting.fitter import Fitter
from ..grid_search.ranking import rank
from ..grid_search.refinement import structure_key


def needs_discovery(ranked: list[CandidateResult]) -> bool:
    """Whether a ranking holds no admissible structure (and something was fitted)."""
    fitted = [r for r in ranked if not r.failed]
    return bool(fitted) and not any(r.placement.admissible for r in fitted)


def _best_fit(ranked: list[CandidateResult]) -> CandidateResult:
    return next(r for r in ranked if not r.failed)


def _lift_of(fitter: Fitter, grid: str, ranked: list[CandidateResult]) -> tuple[tuple[str, ...], bool]:
    """The lift model a drag or pitch search is fed (none for a lift search), and whether the search can run."""
    best = _best_fit(ranked)
    if coefficient(best.coefficient).owns_states:
        return (), True
    from ..fitting.specs import load_grid
    if best.lift in {c.name for c in load_grid(LIFT.grid).candidates}:
        return (best.lift,), True
    fitter.say(f"grid {grid}: no admissible structure; the structure search needs a lift model of the lift grid to "
               f"feed, and the best fit is fed {best.lift}")
    return (), False


def discover_beside(fitter: Fitter, grid: str, ranked: list[CandidateResult], known: list[Candidate],
                    max_steps: int | None = None) -> tuple[list[CandidateResult], list[Candidate]]:
    """``ranked`` with the admissible structures a structure search from the minimal structure fitted in full
    (origin "discovered"), ranked again; and their candidates (named in the ranking, written beside it)."""
    from ..diagnosis.discover import discover_structures
    from ..discovery.search_setting import DISCOVER
    lifts, possible = _lift_of(fitter, grid, ranked)
    if not possible:
        return ranked, []
    fed = f" fed {lifts[0]}" if lifts else ""
    fitter.say(f"grid {grid}: no admissible structure; the structure search goes on from the minimal structure{fed}")
    found = discover_structures(fitter.quiet(), _best_fit(ranked).coefficient, DISCOVER.but(max_rounds=max_steps),
                                start="minimal", lifts=lifts)
    seen = {structure_key(c) for c in known}
    new = []
    for node in found.exploration.fitted():
        key = structure_key(node.candidate)
        if node.admissible and key not in seen:
            seen.add(key)
            # named as the refinement names what it reaches ("-auto"): a report reads them back beside the ranking
            name = node.candidate.name if node.candidate.name.endswith("-auto") else f"{node.candidate.name}-auto"
            new.append((dataclasses.replace(node.candidate, grid=grid, name=name),
                        dataclasses.replace(node.result, grid=grid, name=name).placed(origin="discovered")))
    fitter.say(f"grid {grid}: the structure search fitted {found.structures_fitted} structures, "
               f"{len(new)} admissible and new")
    if not new:
        return ranked, []
    verdicts: dict[str, tuple[str, ...]] = {r.name: tuple(r.placement.reasons) for r in ranked}
    judge: Callable[[CandidateResult], tuple[str, ...]] = lambda r: verdicts.get(r.name, ())
    return rank(list(ranked) + [r for _, r in new], judge), [c for c, _ in new]
