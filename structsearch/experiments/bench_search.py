"""The search half of ``structsearch bench``: ``search --grid all`` against two references measured in
the same run (issue 27, decision 1): a naive fan-out of the same candidates and the search's own
critical path; and the same search with one-step cross-validation folds.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from ..fitting.candidates import Candidate


def _peak_rss_mb(pid: int) -> float:
    """Peak resident memory (VmHWM) of a process in MB; 0 where /proc is not available."""
    try:
        for line in open(f"/proc/{pid}/status"):
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def _children(pid: int) -> list[int]:
    out = []
    try:
        for entry in os.listdir("/proc"):
            if entry.isdigit():
                try:
                    fields = open(f"/proc/{entry}/stat").read().rsplit(")", 1)[1].split()
                    if int(fields[1]) == pid:
                        out.append(int(entry))
                except (OSError, IndexError, ValueError):
                    continue
    except OSError:
        pass
    return out


def run_search(n_jobs: int = 2, seed: int = 0, progress=None, naive: bool = True, one_step: bool = True,
               scale: float = 1.0) -> dict:
    """``search --grid all`` on the default simulated campaign from an empty cache, against two references
    measured in the same run (issue 27, decision 1): the naive fan-out of the same candidates
    (:func:`naive_fan_out`) and the search's own critical path (:func:`critical_path`)."""
    import tempfile
    from ..fitting.fitter import Fitter, RunConfig
    from ..fitting.options import FitOptions
    from ..flight.flighttest import build_campaign
    from ..grid_search.pipeline import grids_for, search
    from ..reporting.tables import write_tables
    say = progress or (lambda m: None)
    say("simulating the default campaign for the search benchmark")
    t0 = time.perf_counter()
    campaign = build_campaign(seed=seed, scale=scale)
    t_sim = time.perf_counter() - t0
    say("one CL-VI start (declared start, training maneuvers), three times")
    unit = one_start_unit(campaign)
    grids = grids_for("all")
    with tempfile.TemporaryDirectory() as tmp:
        say("search --grid all from an empty cache")
        t0 = time.perf_counter()
        result = search(Fitter(RunConfig(campaign, Path(tmp), FitOptions(), n_jobs)), "all")
        write_tables(result.grids, Path(tmp))
        total = time.perf_counter() - t0
        workers = _children(os.getpid())
        worker_peaks = [_peak_rss_mb(p) for p in workers]
    winners = {g: next((s.name for s in r if not s.failed), None) for g, r in result.grids.items()}
    main_peak = _peak_rss_mb(os.getpid())
    seconds = [{s.name: s.seconds for s in result.grids[g.name]} for g in grids]
    path = critical_path([(list(g.candidates), [sec[c.name] for c in g.candidates]) for g, sec in zip(grids, seconds)])
    out = {"samples": campaign.data.n_samples, "simulate_s": t_sim, "search_s": total,
           "cl_vi_start_s": unit, "search_in_cl_vi_starts": total / unit,
           "by_grid_s": result.seconds, "candidates": {g: len(r) for g, r in result.grids.items()},
           "failed": {g: sum(s.failed for s in r) for g, r in result.grids.items()},
           "winners": winners, "n_jobs": n_jobs, "main_peak_rss_mb": main_peak,
           "worker_peak_rss_mb": worker_peaks,
           "critical_path": path, "search_over_critical_path": total / path["seconds"]}
    if naive:
        refined = {g: [c for r in result.refinements.get(g, []) for c, _ in r.steps] for g in result.grids}
        say(f"naive fan-out of the same candidates on {n_jobs} processes (declared starts, no staging)")
        out["naive"] = naive_fan_out(campaign, grids, refined, n_jobs)
        out["search_over_naive"] = total / out["naive"]["seconds"]
    if one_step:
        with tempfile.TemporaryDirectory() as tmp:
            say("search --grid all --cv-method one-step from an empty cache")
            t0 = time.perf_counter()
            other = search(Fitter(RunConfig(campaign, Path(tmp), FitOptions(cv_method="one-step"), n_jobs)), "all")
            write_tables(other.grids, Path(tmp))
            total_one_step = time.perf_counter() - t0
        out["one_step"] = {"search_s": total_one_step, "search_in_cl_vi_starts": total_one_step / unit,
                           "by_grid_s": other.seconds, **ranking_agreement(result.grids, other.grids)}
    return out


def naive_fan_out(campaign, grids, refined: dict, n_jobs: int) -> dict:
    """Wall time of fitting the search's candidates (those of ``grids`` and the refinement steps in
    ``refined``, by grid name) the naive way: each by :func:`~structsearch.fitting.candidate_fit.fit_candidate`
    from its declared start with the default :class:`FitOptions` (multistart, exact refit folds), on
    ``n_jobs`` joblib processes; no staging, no warm start, nothing shared beyond what ``fit_candidate``
    does itself. The lift models drag and pitch candidates use are fitted first (the same way) and serve
    as the lift grid's fits of those candidates."""
    from joblib import Parallel, delayed
    from ..fitting.candidate_fit import fit_candidate
    from ..fitting.lift_fit import LiftFit
    from ..fitting.options import FitOptions
    from ..fitting.specs import load_grid
    options = FitOptions()
    train, validation = campaign.split("train"), campaign.split("validation")
    t0 = time.perf_counter()
    lift_grid = load_grid("lift")
    needed = sorted({c.lift for g in grids for c in g.candidates if c.lift})
    fitted = Parallel(n_jobs=n_jobs)(delayed(fit_candidate)(lift_grid[n], train, validation, None, options)
                                     for n in needed)
    t_lift = time.perf_counter() - t0
    lifts = {n: LiftFit(lift_grid[n], r) for n, r in zip(needed, fitted)}
    todo = [c for g in grids for c in list(g.candidates) + refined.get(g.name, [])
            if not (c.grid == "lift" and c.name in lifts)]
    results = Parallel(n_jobs=n_jobs)(delayed(fit_candidate)(c, train, validation, lifts.get(c.lift) if c.lift else None,
                                                             options) for c in todo)
    total = time.perf_counter() - t0
    everything = list(fitted) + list(results)
    return {"seconds": total, "lift_models_s": t_lift, "lift_models": needed, "candidates": len(everything),
            "failed": sum(r.failed for r in everything), "n_jobs": n_jobs,
            "summed_fit_s": float(sum(r.seconds for r in everything))}


class _Fitted:
    """What :func:`~structsearch.fitting.runner.same_model_fitted` asks of a result."""
    failed = False


def critical_path(grids) -> dict:
    """The search's longest staged chain: ``grids`` holds, in search order, each grid's candidates and
    the recorded ``seconds`` of their fits. A candidate's chain is its own seconds plus the longest chain
    among what it waits for: the candidates that may donate its warm start (:func:`.staging.may_donate`)
    in earlier waves of its grid (:func:`.staging.waves`) or in earlier grids, and its lift model (the
    lift grid's candidate of that name) for a drag or pitch candidate. A candidate the search serves
    from an earlier grid's twin (:func:`~structsearch.fitting.runner.same_model_fitted`) takes that
    twin's chain. Refinement steps are not on it (they follow a grid's ranking). Returns the longest
    chain's seconds and its candidates, first fitted first.

    A candidate's recorded seconds are the work of all its tasks (starts, statistics, folds), which run
    side by side on several workers, so this chain is an upper bound of the critical path, not the path
    itself: ``structsearch bench --trace FILE`` measures the task-level path from a trace."""
    from ..fitting.staging import may_donate, waves
    from ..fitting.runner import same_model_fitted
    earlier: list[tuple[Candidate, tuple[float, tuple[str, ...]]]] = []
    lift_chains: dict[str, tuple[float, tuple[str, ...]]] = {}
    longest: tuple[float, tuple[str, ...]] = (0.0, ())
    for candidates, seconds in grids:
        chains: dict[int, tuple[float, tuple[str, ...]]] = {}
        twins = same_model_fitted(candidates, [(c, _Fitted()) for c, _ in earlier])
        chain_of = {c.name + "\0" + c.grid: ch for c, ch in earlier}
        order = waves(candidates)
        wave_of = {i: w for w, members in enumerate(order) for i in members}
        for members in order:
            for i in members:
                c = candidates[i]
                if i in twins:
                    twin = twins[i][0]
                    chains[i] = chain_of[twin.name + "\0" + twin.grid]
                    continue
                before = [chains[j] for j in chains if wave_of[j] < wave_of[i] and may_donate(candidates[j], c)]
                before += [ch for d, ch in earlier if may_donate(d, c)]
                if c.lift and c.lift in lift_chains:
                    before.append(lift_chains[c.lift])
                base = max(before, default=(0.0, ()), key=lambda ch: ch[0])
                chains[i] = (base[0] + float(seconds[i]), base[1] + (f"{c.grid} {c.name}",))
        for i, c in enumerate(candidates):
            earlier.append((c, chains[i]))
            if c.grid == "lift":
                lift_chains[c.name] = chains[i]
            longest = max(longest, chains[i], key=lambda ch: ch[0])
    return {"seconds": longest[0], "chain": list(longest[1])}


def ranking_agreement(refit: dict, one_step: dict) -> dict:
    """How the rankings of two searches of the same grids agree: the same first candidate and the same
    admissible ones per grid, the candidates whose rank moved, the largest relative CV MSE difference."""
    out = {"same_first": {}, "same_admissible": {}, "moved": {}, "max_rel_cv_difference": {}}
    for g, ranked in refit.items():
        a = {s.name: s for s in ranked if not s.failed}
        b = {s.name: s for s in one_step[g] if not s.failed}
        first = lambda r: next((s.name for s in r if not s.failed), None)  # noqa: E731
        out["same_first"][g] = first(ranked) == first(one_step[g])
        out["same_admissible"][g] = {n for n, s in a.items() if s.placement.admissible} == \
            {n for n, s in b.items() if s.placement.admissible}
        out["moved"][g] = sorted(n for n in a if n in b and a[n].placement.rank != b[n].placement.rank)
        diffs = [abs(b[n].cv.mse / a[n].cv.mse - 1) for n in a
                 if n in b and a[n].cv is not None and b[n].cv is not None and a[n].cv.mse > 0]
        out["max_rel_cv_difference"][g] = float(np.nanmax(diffs)) if diffs and not np.all(np.isnan(diffs)) \
            else float("nan")
    return out


def one_start_unit(campaign, repeats: int = 3) -> float:
    """Median wall time of one CL-VI fit from its declared start on the campaign's training maneuvers,
    with the default covariance (what ``structsearch fit --model CL-VI --starts 1`` computes, without
    cross-validation and I/O): the machine-independent unit the search is measured in."""
    from ..fitting.models import build_model
    from ..fitting.specs import resolve_candidate
    model = build_model(resolve_candidate("CL-VI"))
    train = campaign.split("train")
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        model.fit(train, n_starts=1)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))
