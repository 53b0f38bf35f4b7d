"""One candidate's fit as tasks small enough to spread: each start of its multistart, its quasi-steady stage's
starts, its statistics and scores, and each refitted cross-validation fold, a task of its own.

It computes what :func:`.candidate_fit.fit_staged` computes, start for start: the starts are the same points in
the same order (:func:`.candidate_fit.start_points`), the best is chosen the same way (the first of the lowest
cost, in start order), the statistics are those of that optimum and the folds refit from it. Only where the
solves run differs. The declared start is solved at once, before the candidates the fit may start from are
fitted (every full fit tries it), and so are the quasi-random starts of a fit that climbs its stage first (seeded
points of the box: the stage does not move them); the other starts wait for what they are made from. Once the
best start is known, the statistics and the folds run beside each other (both start from that optimum), and the
candidates that start from this one go ahead: they wait for its estimates, not for its statistics or folds.

A candidate with a lift model or without separation parameters (a linear fit, or one that reads its states)
is one task; so is any fit whose starts cannot be planned apart (a declaration the data reject): it is then
fitted as a whole, by the same function as a serial run, and fails or succeeds the same way.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from ..data.errors import StructSearchError
from ..engine.snls import best_of
from .folds import plan_folds
from .candidate_fit import (StartSpec, fit_from, fit_staged, fold_residual, solve_start, stage_of, staged_spec,
                            start_points, with_folds)
from .candidate_result import CandidateResult
from .candidates import Candidate
from .options import FitOptions
from .shared_data import resolve_splits
from .staging import STAGE_STARTS, DonorEstimate
from .task_graph import Task

PLANNING_ERRORS = (StructSearchError, np.linalg.LinAlgError, FloatingPointError, ValueError)


# ----- what runs on a worker (module functions: a process pool pickles them by name) ---------------------------
def _solve(splits, c: Candidate, options: FitOptions, point: np.ndarray):
    t0 = time.perf_counter()
    return solve_start(c, resolve_splits(splits)[0], options, point), time.perf_counter() - t0


def _fit(splits, c: Candidate, options: FitOptions, spec: StartSpec, solved):
    train, validation = resolve_splits(splits)
    return fit_from(c, train, validation, None, options, spec, solved=solved, folds_apart=True)


def _fold(splits, c: Candidate, options: FitOptions, params: Mapping[str, float], plan, fold: int):
    t0 = time.perf_counter()
    rows, values = fold_residual(c, resolve_splits(splits)[0], options, params, plan, fold)
    return rows, values, time.perf_counter() - t0


def _whole(splits, c: Candidate, lift, options: FitOptions, warm, nested):
    train, validation = resolve_splits(splits)
    return fit_staged(c, train, validation, lift, options, start=warm, nested=nested)


@dataclass(frozen=True)
class JobContext:
    """What every candidate job of a call shares: the splits' handle for the workers, the training maneuvers for
    planning on the driver, the options and lift models, how tasks are named, the first tasks' parents, and the
    runner's callbacks: ``estimated(i, fitted, tasks)`` once a fit's estimates exist (a :class:`.staging.DonorEstimate`,
    made by ``tasks``: its dependants may start), ``finished(i, result)`` once it is scored; each returns the tasks
    it makes ready."""

    splits: object
    train: object
    options: FitOptions
    lifts: Mapping
    name: Callable[[str], str]
    roots: tuple[str, ...]
    estimated: Callable
    finished: Callable


class CandidateJob:
    """The tasks of candidate ``index`` (see the module's docstring); ``priority``: lower runs first."""

    def __init__(self, index: int, candidate: Candidate, ctx: JobContext, priority: float):
        self.i, self.c, self.ctx, self.priority = index, candidate, ctx, priority
        # a fit with flight effects solves its starts and folds on its coded data itself (candidate_fit.fit_from)
        self.whole = (bool(candidate.lift) or not candidate.state_parameters
                      or bool(candidate.flight_effects or ctx.options.flight_effects))
        self.outcomes: dict[bytes, object] = {}
        self.solving: dict[bytes, str] = {}
        self.keys: list[bytes] | None = None
        self.work = 0.0
        self.result: CandidateResult | None = None
        self.parts: list = []
        self.finished = False

    def _task(self, what: str, fn, args, then, parents, urgency: float = 0.0) -> Task:
        """A task of this candidate; ``then(result, name)`` on the driver once it has run."""
        name = self.ctx.name(f"{self.c.grid}/{self.c.name}: {what}")
        return Task(name, what.rsplit(" ", 1)[0] if what[-1].isdigit() else what, fn, (self.ctx.splits, *args),
                    lambda out: then(out, name), tuple(parents) or self.ctx.roots, self.priority + urgency)

    # ----- starts -------------------------------------------------------------------------------------------
    def early(self) -> list[Task]:
        """The declared start, which every full fit tries, solved before the fit's donors are fitted."""
        if self.whole or self.ctx.options.scores_only:
            return []
        try:
            point = start_points(self.c, self.ctx.train, self.ctx.options, StartSpec(None, 1))[0]
        except PLANNING_ERRORS:
            return []
        return self._solve_tasks([point], ())

    def begin(self, warm, nested, parents: tuple[str, ...]) -> list[Task]:
        """The tasks that follow once the candidates this fit may start from are fitted (``warm``: a donor's
        estimates, ``nested``: a contained structure's optimum; ``parents``: their tasks)."""
        self.warm, self.nested = warm, nested
        if self.whole:
            return [self._whole_task(parents)]
        if warm is None:
            stage = stage_of(self.c, self.ctx.options)
            if stage is not None:
                return self._stage(stage, parents)
        return self._plan(staged_spec(self.c, self.ctx.options, warm, nested=nested), parents)

    def _whole_task(self, parents) -> Task:
        self.whole = True
        lift = self.ctx.lifts.get(self.c.lift) if self.c.lift else None
        return self._task("fit", _whole, (self.c, lift, self.ctx.options, self.warm, self.nested),
                          self._estimated_whole, parents)

    def _stage(self, stage, parents) -> list[Task]:
        candidate, model = stage
        try:
            points = model.start_points(self.ctx.train, n_starts=STAGE_STARTS, seed=self.ctx.options.seed)
        except PLANNING_ERRORS:
            return self._plan(staged_spec(self.c, self.ctx.options, None, nested=self.nested), parents)
        self.stage_outcomes: list = [None] * len(points)
        tasks = [self._task(f"stage start {k}", _solve, (candidate, self.ctx.options, p),
                            lambda out, _, k=k: self._stage_done(k, out, model), parents) for k, p in enumerate(points)]
        self.stage_tasks = tuple(t.name for t in tasks)
        return tasks + self._quasi_random(parents)

    def _quasi_random(self, parents) -> list[Task]:
        """The quasi-random starts of a fit without a warm start: seeded points of the box, whatever the stage gives,
        so they need not wait for it."""
        try:
            points = start_points(self.c, self.ctx.train, self.ctx.options, StartSpec(None, None))[1:]
        except PLANNING_ERRORS:
            return []
        return self._solve_tasks([p for p in points if p.tobytes() not in self.solving], parents)

    def _stage_done(self, k: int, out, model) -> list[Task]:
        self.stage_outcomes[k], seconds = out
        self.work += seconds
        if any(o is None for o in self.stage_outcomes):
            return []
        try:
            best = best_of(self.stage_outcomes, model.target(self.ctx.train)).best
            params = dict(zip(model.nonlinear_names + model.linear_names, np.concatenate([best.theta, best.coef])))
        except PLANNING_ERRORS:
            params = None   # a stage the data cannot fit gives no start: the candidate keeps its usual starts
        spec = staged_spec(self.c, self.ctx.options, None, nested=self.nested, stage_params=params,
                           stage_model=model)
        return self._plan(spec, self.stage_tasks)

    def _plan(self, spec: StartSpec, parents) -> list[Task]:
        try:
            points = start_points(self.c, self.ctx.train, self.ctx.options, spec)
        except PLANNING_ERRORS:
            return [self._whole_task(parents)]
        self.spec, self.keys = spec, [p.tobytes() for p in points]
        if len(points) == 1 and self.keys[0] not in self.solving:
            # one start (a screening): nothing to spread, so the solve and its statistics share one task and one
            # bound problem
            return [self._task("fit", _fit, (self.c, self.ctx.options, spec, None), self._fitted_alone, parents)]
        tasks = self._solve_tasks([p for p in points if p.tobytes() not in self.solving], parents)
        if tasks or any(k not in self.outcomes for k in self.keys):
            return tasks   # the last start to finish makes the fit ready (one may be running already)
        return self._select()

    def _solve_tasks(self, points, parents) -> list[Task]:
        tasks = []
        for p in points:
            key = p.tobytes()
            tasks.append(self._task(f"start {len(self.solving)}", _solve, (self.c, self.ctx.options, p),
                                    lambda out, _, key=key: self._solved(key, out), parents))
            self.solving[key] = tasks[-1].name
        return tasks

    def _solved(self, key: bytes, out) -> list[Task]:
        self.outcomes[key], seconds = out
        self.work += seconds
        if self.keys is None or any(k not in self.outcomes for k in self.keys):
            return []
        return self._select()

    # ----- the fit's statistics beside its folds --------------------------------------------------------------
    def _select(self) -> list[Task]:
        parents = tuple(self.solving[k] for k in self.keys)
        try:
            solved = best_of([self.outcomes[k] for k in self.keys], self.ctx.train[self.c.coefficient])
        except PLANNING_ERRORS:
            return [self._whole_task(parents)]   # no start fitted: the whole fit says why, as a serial run does
        fit = self._task("fit", _fit, (self.c, self.ctx.options, self.spec, solved), self._fitted, parents)
        # the optimum is the estimate (the statistics that follow do not move it): the folds refit from it, and the
        # candidates that start from this one need not wait for the statistics either; its training MSE is the
        # optimum's cost per sample
        best, model = solved.best, self._model()
        params = dict(zip(model.nonlinear_names + model.linear_names, np.concatenate([best.theta, best.coef])))
        folds = self._fold_tasks(model, params, parents)
        fitted = DonorEstimate(params, 2.0 * best.cost / len(self.ctx.train[self.c.coefficient]))
        return [fit] + folds + self.ctx.estimated(self.i, fitted, parents)

    def _model(self):
        from .models import build_model
        return build_model(self.c.with_bounds(self.ctx.options.parameter_boxes))

    def _fold_tasks(self, model, params, parents) -> list[Task]:
        """The refitted folds, which :func:`.candidate_fit.fit_from` leaves apart (the same rule decides)."""
        o = self.ctx.options
        plan = plan_folds(self.ctx.train, o.cv_folds, o.cv_fold_size, o.cv_block_convective_times)
        if not (plan.folds and model.nonlinear_names and o.cv_method == "refit"):
            return []
        self.plan, self.parts = plan, [None] * plan.n_folds
        return [self._task(f"fold {k}", _fold, (self.c, o, params, plan, k),
                           lambda out, _, k=k: self._fold_done(k, out), parents, urgency=0.5)
                for k in range(plan.n_folds)]

    def _estimated_whole(self, result: CandidateResult, name: str) -> list[Task]:
        return self.ctx.estimated(self.i, DonorEstimate.of(result), (name,)) + self.ctx.finished(self.i, result)

    def _fitted_alone(self, out, name: str) -> list[Task]:
        """A fit of one start, solved and scored in one task: its estimates, then its folds."""
        self.result, apart = out
        ready = self.ctx.estimated(self.i, DonorEstimate.of(self.result), (name,))
        folds = [] if apart is None or self.result.failed else \
            self._fold_tasks(self._model(), self.result.estimates.params, (name,))
        if not folds:
            self.parts = []
        return ready + (folds or self._finish())

    def _fitted(self, out, name: str) -> list[Task]:
        self.result, apart = out
        if apart is None:   # no folds left apart (or a failed fit: its folds are not scored)
            self.parts = []
        return self._finish()

    def _fold_done(self, k: int, out) -> list[Task]:
        rows, values, seconds = out
        self.parts[k] = (rows, values)
        self.work += seconds
        return self._finish()

    def _finish(self) -> list[Task]:
        """The candidate's record, once its statistics and every fold are in (once)."""
        if self.result is None or self.finished or any(p is None for p in self.parts):
            return []
        self.finished = True
        if not self.parts:
            return self.ctx.finished(self.i, _plus(self.result, self.work))
        return self.ctx.finished(self.i, with_folds(self.result, self.ctx.train, self.plan, self.parts, self.work,
                                                               self.ctx.options))


def _plus(result: CandidateResult, seconds: float) -> CandidateResult:
    """``result`` with the seconds its starts took on other tasks added to its own."""
    return dataclasses.replace(result, seconds=result.seconds + seconds)
