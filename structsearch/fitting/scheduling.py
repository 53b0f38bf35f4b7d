"""A call's candidates as one growing graph of tasks (:mod:`.candidate_job`): every candidate's independent
starts at once, and each candidate's other starts as soon as the candidates it may start from have estimates
(:mod:`.staging`: its donors, of earlier waves of the call or of earlier calls). No wave waits for the wave before
it as a whole, and a fit's folds are off the chain its dependants wait on. Which donors a candidate waits for, and
so where it starts, is fixed by the candidates, never by the order tasks finish in: the results are those of a
serial run."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

from .candidate_job import CandidateJob, JobContext
from .candidate_result import CandidateResult
from .candidates import Candidate
from .options import FitOptions
from .staging import DonorEstimate, best_contained, warm_start
from .task_graph import Task, run_tasks
from .trace import Trace


@dataclass
class CallPlan:
    """What one call fits: ``todo`` (indices of ``candidates`` not served from the cache), ``needs`` (each one's
    possible donors, by index), ``known`` (the results in hand: cached or served) and ``fitted_before`` (earlier
    calls' candidates, donors too)."""

    candidates: Sequence[Candidate]
    todo: Sequence[int]
    needs: Mapping[int, Sequence[int]]
    known: dict[int, CandidateResult]
    fitted_before: Sequence[tuple[Candidate, CandidateResult]]


def _dependants(plan: CallPlan) -> dict[int, list[int]]:
    out: dict[int, list[int]] = {i: [] for i in range(len(plan.candidates))}
    for i in plan.todo:
        for j in plan.needs[i]:
            out[j].append(i)
    return out


def _weights(plan: CallPlan, dependants: dict[int, list[int]]) -> dict[int, int]:
    """How many candidates wait (directly or not) for each one: the longer its tail, the sooner it runs."""
    memo: dict[int, set[int]] = {}

    def tail(i: int) -> set[int]:
        if i not in memo:
            memo[i] = set(dependants[i]).union(*(tail(k) for k in dependants[i])) if dependants[i] else set()
        return memo[i]
    return {i: len(tail(i)) for i in plan.todo}


def fit_as_tasks(plan: CallPlan, splits, train, options: FitOptions, lifts: Mapping, pool,
                 trace: Trace | None, done: Callable[[int, CandidateResult, bool], None]) -> None:
    """Fit ``plan.todo`` as tasks on ``pool``; ``done(i, result, warm)`` once candidate ``i`` is scored."""
    estimated = {i: DonorEstimate.of(r) for i, r in plan.known.items()}
    before = [(c, DonorEstimate.of(r)) for c, r in plan.fitted_before]
    task_of: dict[int, tuple[str, ...]] = {}
    dependants = _dependants(plan)
    waiting = {i: {j for j in plan.needs[i] if j not in estimated} for i in plan.todo}
    begun: set[int] = set()
    warm_of: dict[int, bool] = {}

    def begin(i: int) -> list[Task]:
        begun.add(i)
        fitted = before + [(plan.candidates[j], estimated[j]) for j in plan.needs[i]]
        warm = warm_start(plan.candidates[i], fitted)
        warm_of[i] = warm is not None
        parents = tuple(name for j in plan.needs[i] for name in task_of.get(j, ()))
        return jobs[i].begin(warm, best_contained(plan.candidates[i], fitted), parents)

    def on_estimated(i: int, fitted: DonorEstimate, tasks: tuple[str, ...]) -> list[Task]:
        estimated[i], task_of[i] = fitted, tasks
        ready = []
        for k in dependants[i]:
            waiting[k].discard(i)
            if not waiting[k] and k not in begun:
                ready += begin(k)
        return ready

    def on_finished(i: int, result: CandidateResult) -> list[Task]:
        done(i, result, warm_of.get(i, False))
        return []

    namer = trace.unique if trace is not None else (lambda name: name)
    ctx = JobContext(splits, train, options, lifts, namer, trace.roots() if trace is not None else (),
                     on_estimated, on_finished)
    weights = _weights(plan, dependants)
    jobs = {i: CandidateJob(i, plan.candidates[i], ctx, -float(weights[i])) for i in plan.todo}
    first = [t for i in plan.todo for t in jobs[i].early()]
    for i in plan.todo:
        if not waiting[i]:
            first += begin(i)
    run_tasks(first, pool, trace)
