"""Structure search: grids fitted in dependency order, ranked, refined, tabulated."""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

from .campaign import Campaign
from .ranking import rank, write_tables
from .runner import Settings, run
from .specs import BUILTIN_GRIDS, Candidate, Grid, load_grid

# Correlated pairs above this are candidates for removal during refinement (thesis: 0.8).
REFINE_CORRELATION = 0.8
# A refinement step is kept when validation MSE rises by less than this fraction.
REFINE_TOLERANCE = 0.01


def grids_for(spec: str) -> list[Grid]:
    if spec == "all":
        lift = load_grid("lift")
        return [load_grid("separation"), lift, load_grid("drag", lift), load_grid("pitch", lift)]
    if spec in BUILTIN_GRIDS:
        return [load_grid(spec)]
    return [load_grid(spec)]


def _refined(c: Candidate, drop: list[str], suffix: str) -> Candidate:
    """``c`` without the regressors in ``drop`` (all drops so far, relative to ``c``)."""
    regs = tuple(r for r in c.regressors if r[0] not in drop)
    return Candidate(f"{c.name}{suffix}", c.grid, c.coefficient, regs, c.states, c.lift,
                     f"refined from {c.name}: dropped {', '.join(drop)}", c.bounds)


def refine(c: Candidate, summary: dict, fit: Callable[[Candidate], dict]) -> list[tuple[Candidate, dict]]:
    """Drop terms whose t-test accepts zero, then one of a strongly correlated pair while the fit barely changes."""
    out = []
    current, current_summary, dropped = c, summary, []
    for step in range(1, 10):
        linear = [r[0] for r in current.regressors]
        constant = linear[0] if current.regressors[0][1].strip() == "1" else None
        drop = [n for n in current_summary["insignificant"] if n in linear and n != constant]
        if not drop:
            pairs = [p for p in current_summary["high_correlations"]
                     if p[0] in linear and p[1] in linear and abs(p[2]) > REFINE_CORRELATION]
            if not pairs:
                break
            a, b, _ = pairs[0]
            worse = max((a, b), key=lambda n: current_summary["p_values"][n])
            drop = [worse] if worse != constant else []
            if not drop:
                break
        candidate = _refined(c, dropped + drop, "r" + ("" if step == 1 else str(step)) + "-auto")
        result = fit(candidate)
        if "error" in result or result["mse_validation"] > current_summary["mse_validation"] * (1 + REFINE_TOLERANCE):
            break
        out.append((candidate, result))
        current, current_summary, dropped = candidate, result, dropped + drop
    return out


def search(campaign: Campaign, grid_spec: str, out: Path, *, n_jobs: int = 1, settings: Settings = Settings(),
           backend: str = "loky", progress: Callable[[str], None] | None = None, do_refine: bool = True) -> dict:
    """Fit, rank and tabulate the grids; returns {"grids": {name: ranked}, "seconds": {name: s}}."""
    say = progress or (lambda m: None)
    grids = grids_for(grid_spec)
    ranked_by_grid, seconds = {}, {}
    lift_results: dict[str, dict] = {}
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
        ranked = rank(results)
        if do_refine and ranked and "error" not in ranked[0]:
            best = grid[ranked[0]["name"]]

            def fit_one(c):
                return run([c], campaign, out, lift_results=lift_results, lift_candidates=lift_candidates,
                           settings=settings, n_jobs=1, backend=backend)[0]

            extra = refine(best, ranked[0], fit_one)
            if extra:
                say(f"grid {grid.name}: refined {best.name} -> {', '.join(c.name for c, _ in extra)}")
                ranked = rank(results + [s for _, s in extra])
        ranked_by_grid[grid.name] = ranked
        seconds[grid.name] = time.perf_counter() - t0
    write_tables(ranked_by_grid, out)
    return {"grids": ranked_by_grid, "seconds": seconds}
