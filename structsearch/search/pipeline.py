"""Structure search: grids fitted in dependency order (lift before drag and pitch), ranked, refined."""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ..data.campaign import Campaign
from .candidate_result import CandidateResult
from .admissibility import AdmissibilityRules, MAX_CORRELATION, reasons
from .ranking import rank
from .refinement import refine
from .runner import Settings, run
from .candidates import Candidate, Grid
from .specs import load_grid


@dataclass(frozen=True)
class SearchResult:
    """Each grid's results, best first, and the wall time each grid took."""

    grids: dict[str, list[CandidateResult]]
    seconds: dict[str, float]


def grids_for(spec: str) -> list[Grid]:
    if spec == "all":
        lift = load_grid("lift")
        return [load_grid("separation"), lift, load_grid("drag", lift), load_grid("pitch", lift)]
    return [load_grid(spec)]


def rules_for(campaign: Campaign, max_correlation: float = MAX_CORRELATION) -> AdmissibilityRules:
    """What admissibility needs from a campaign: the alpha range flown in training, the cg envelope."""
    alpha = campaign.split("train")["alpha"]
    envelope = campaign.aircraft.get("x_cg_range")
    return AdmissibilityRules(max_correlation=max_correlation, alpha_range=(float(alpha.min()), float(alpha.max())),
                              cg_range=tuple(envelope) if envelope is not None else None,
                              cbar=float(campaign.aircraft["cbar"]))


def search(campaign: Campaign, grid_spec: str, out: Path, *, n_jobs: int = 1, settings: Settings = Settings(),
           backend: str = "loky", progress: Callable[[str], None] | None = None,
           do_refine: bool = True, max_correlation: float = MAX_CORRELATION) -> SearchResult:
    """Fit and rank the grids of ``grid_spec``, refining each grid's best; ``out`` holds the cache."""
    say = progress or (lambda m: None)
    rules = rules_for(campaign, max_correlation)
    grids = grids_for(grid_spec)
    ranked_by_grid, seconds = {}, {}
    lift_results: dict[str, CandidateResult] = {}
    lift_candidates: dict[str, Candidate] = {}

    def ensure_lift(names):
        missing = [n for n in names if n not in lift_results]
        if not missing:
            return
        lift_grid = load_grid("lift")
        cands = [lift_grid[n] for n in missing]
        for c, s in zip(cands, run(cands, campaign, out, settings=settings, n_jobs=n_jobs, backend=backend,
                                   progress=say)):
            lift_results[c.name], lift_candidates[c.name] = s, c

    for grid in grids:
        t0 = time.perf_counter()
        needed = sorted({c.lift for c in grid.candidates if c.lift})
        ensure_lift(needed)
        say(f"grid {grid.name}: {len(grid.candidates)} candidates")
        results = run(grid.candidates, campaign, out, lift_results=lift_results, lift_candidates=lift_candidates,
                      settings=settings, n_jobs=n_jobs, backend=backend, progress=say)
        if grid.name == "lift":
            for c, s in zip(grid.candidates, results):
                lift_results[c.name], lift_candidates[c.name] = s, c
        by_name = {c.name: c for c in grid.candidates}

        def judge(result, by_name=by_name):
            return reasons(result, by_name.get(result.name), rules)

        ranked = rank(results, judge)
        if do_refine and ranked and not ranked[0].failed:
            best = grid[ranked[0].name]

            def fit_one(c):
                return run([c], campaign, out, lift_results=lift_results, lift_candidates=lift_candidates,
                           settings=settings, n_jobs=1, backend=backend)[0]

            extra = refine(best, ranked[0], fit_one)
            if extra:
                say(f"grid {grid.name}: refined {best.name} -> {', '.join(c.name for c, _ in extra)}")
                by_name.update({c.name: c for c, _ in extra})
                ranked = rank(results + [s for _, s in extra], judge)
        ranked_by_grid[grid.name] = ranked
        seconds[grid.name] = time.perf_counter() - t0
    return SearchResult(ranked_by_grid, seconds)
