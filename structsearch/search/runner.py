"""Runner: fit every candidate of a grid in parallel, cache each result on disk, resume.

Every finished candidate is written to ``<out>/cache/<grid>/<name>-<key>.json``
(atomically); the key hashes the candidate, the data, the lift parameters it
depends on and the settings, so an interrupted search resumes where it stopped
and a changed input is never served from a stale cache. A failing candidate is
recorded with its reason and never stops the search. Results are identical for
any number of jobs: each fit is seeded and runs on one process.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import sys
import time
from contextlib import ExitStack
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..data.campaign import Campaign
from ..data.flightdata import FlightData
from ..data.errors import StructSearchError
from ..data.atomic import write_json
from .admissibility import centred_correlation
from .candidates import Candidate
from .specs import load_grid
from ..engine.ols import held_out_residuals
from ..engine.scores import ManeuverScores
from ..engine.statistics import DEFAULT_COVARIANCE
from .candidate_result import JSON_LAYOUT, CandidateResult, SplitScores
from .generated import with_lift_uncertainty
from .models import build_model
from .shared_data import LOCAL_PROCESS_BACKENDS, lift_context, resolve_splits, shared_splits
from .staging import STAGE_STARTS, WARM_STARTS, may_donate, stages, warm_start, waves

# Cross-validation folds over the training maneuvers (fewer when a fold would hold fewer than
# CV_MIN_MANEUVERS maneuvers; none below two folds).
CV_FOLDS = 5
CV_MIN_MANEUVERS = 3
# How a fold is fitted: "refit" solves it again from the full fit's estimates (exact); "one-step" takes
# one Gauss-Newton step from them on the fold's maneuvers (linearised: exact for a linear candidate,
# an approximation of second order in the fold's change of the estimates for a nonlinear one, and no
# solve at all: the full fit's Jacobian serves every fold).
CV_METHODS = ("refit", "one-step")


@dataclass(frozen=True)
class Settings:
    n_starts: int = 4
    seed: int = 0
    significance: float = 0.05
    covariance: str = DEFAULT_COVARIANCE
    cv_folds: int = CV_FOLDS          # 0: no cross-validation (diagnosis, calibration: they do not rank)
    bounds: tuple[tuple[str, tuple[float, float]], ...] = ()   # --bound NAME=LO:HI, over declared boxes
    cv_method: str = "refit"          # CV_METHODS

    def __post_init__(self):
        if self.cv_method not in CV_METHODS:
            raise StructSearchError(f"cross-validation method must be one of {', '.join(CV_METHODS)}, "
                                    f"not {self.cv_method!r}")

    def key(self, nonlinear: bool = True) -> dict:
        """What a fit's result depends on; the cross-validation method only for a ``nonlinear`` candidate
        (a linear one's folds are exact either way, so its cached fit serves both methods)."""
        key = {"n_starts": self.n_starts, "seed": self.seed, "covariance": self.covariance,
               "cv_folds": self.cv_folds, "bounds": [[k, list(v)] for k, v in self.bounds]}
        if nonlinear and self.cv_folds:
            key["cv_method"] = self.cv_method
        return key


def check_bounds(bounds, candidates) -> None:
    """An unknown NAME in --bound is an error naming the parameters it could have meant."""
    from .specs import load_grid
    known = set()
    for c in candidates:
        known.update(c.state_parameters)
        if c.lift:
            known.update(load_grid("lift")[c.lift].state_parameters)
    unknown = [k for k, _ in bounds if k not in known]
    if unknown:
        raise StructSearchError(f"--bound {unknown[0]}: no candidate has this nonlinear parameter; known: "
                                f"{', '.join(sorted(known)) or '(none: the candidates are linear)'}")


def maneuver_folds(n_maneuvers: int, folds: int) -> list[list[int]]:
    """Maneuver-grouped folds, round robin over the maneuvers in campaign order (which groups the
    kinds, so every fold sees every kind); [] when fewer than two folds of CV_MIN_MANEUVERS fit."""
    k = min(folds, n_maneuvers // CV_MIN_MANEUVERS)
    if k < 2:
        return []
    return [list(range(i, n_maneuvers, k)) for i in range(k)]


def cross_validate(model, train: FlightData, result, folds: list[list[int]], method: str = "refit") -> np.ndarray:
    """Held-out residuals of every training maneuver: each fold refitted on the other maneuvers and
    predicted on its own. A linear model's folds share one factorisation of its regressors
    (:func:`held_out_residuals`). A nonlinear model's fold is, with ``method`` "refit", one solve warm
    started from the full training fit; with "one-step", one Gauss-Newton step from it: the same
    least-squares problem on the full fit's Jacobian [dPhi/dtheta c, Phi] and residual, so that the
    folds share its factorisation too (for a linear model the step lands on the fold's exact fit);
    parameters on a bound or not identifiable are held at the full fit's values.
    Folds need estimates only: no statistics are computed for them.

    Drag and pitch candidates keep the separation states and C_L of the lift model fitted on all
    training maneuvers (held-out ones included): their comparison is conditional on that lift model,
    as their fits are; it is the same for every candidate of a grid, so it does not favour one."""
    y = train[model.coefficient]
    if not model.nonlinear_names:
        return held_out_residuals(model.bind(train).regression_matrix(np.zeros(0)), y, train.bounds, folds)
    if method == "one-step":
        jac, output = model.jacobian(train, result.params)
        # a parameter on a bound or not identifiable stays where the full fit left it (an approximation: a
        # fold's refit could move it inward, never past the bound; a step along a null direction is arbitrary)
        free = [i for i, n in enumerate(result.names) if n not in result.at_bound and n not in result.unidentifiable]
        return held_out_residuals(jac[:, free], y - output, train.bounds, folds)
    residual = np.empty_like(y)
    slices = train.segment_slices()
    warm = {k: result.params[k] for k in model.nonlinear_names}
    everything = range(len(slices))
    for held in folds:
        rest = [i for i in everything if i not in held]
        subset = train.select(rest)
        # the subset's default box may be narrower (alpha range flown): start inside it
        start = model.inside(subset, warm)
        predicted = model.predict(train.select(held), model.estimate(subset, start=start))
        at = 0
        for i in held:
            n = slices[i].stop - slices[i].start
            residual[slices[i]] = y[slices[i]] - predicted[at:at + n]
            at += n
    return residual


def fingerprint(data: FlightData) -> str:
    """Hash of everything a fit reads from the data: columns, maneuver boundaries and names, constants."""
    h = hashlib.sha256()
    for name in sorted(data.columns):
        h.update(name.encode())
        h.update(np.ascontiguousarray(data.columns[name]).tobytes())
    h.update(np.asarray(data.starts, np.int64).tobytes())
    h.update(json.dumps([list(data.names), sorted((k, float(v)) for k, v in data.constants.items())]).encode())
    return h.hexdigest()[:16]


def campaign_fingerprint(campaign: Campaign) -> str:
    """The data plus the train/validation assignment and the aircraft data of the manifest."""
    h = hashlib.sha256(fingerprint(campaign.data).encode())
    h.update(json.dumps([[m.id, m.kind, m.split] for m in campaign.maneuvers]).encode())
    h.update(json.dumps(sorted((k, v if isinstance(v, (int, float)) else list(v))
                               for k, v in campaign.aircraft.items())).encode())
    return h.hexdigest()[:16]


@lru_cache(maxsize=None)
def code_fingerprint() -> str:
    """Hash of the package's source and shipped grids: any change to the code that fits, scores or
    serialises a candidate makes a new cache key (no hand-bumped version to forget)."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    # model_specs may be a symbolic link (rglob does not follow it): its grids are listed explicitly
    files = [p for p in root.rglob("*.py") if "__pycache__" not in p.parts]
    files += list((root / "model_specs").resolve().glob("*.toml"))
    for path in sorted(files, key=lambda p: (p.suffix, p.name, str(p))):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


# Failures that follow from the data or the declaration (cached); any other exception may be a
# programming error and is retried on the next run.
CACHED_FAILURES = ("not applicable", "DataError", "DeclarationError", "FitError", "StructSearchError",
                   "LinAlgError", "FloatingPointError")


def _derived(coef: str, predicted: np.ndarray, data: FlightData, other: np.ndarray | None):
    """C_X and C_Z from a lift or drag prediction and the other coefficient (predicted or measured)."""
    alpha = data["alpha"]
    if coef == "CL":
        cl, cd = predicted, (other if other is not None else data["CD"])
    elif coef == "CD":
        cd, cl = predicted, (other if other is not None else data["CL"])
    else:
        return None
    cx = -cd * np.cos(alpha) + cl * np.sin(alpha)
    cz = -cl * np.cos(alpha) - cd * np.sin(alpha)
    cl_meas = data["CL_measured"] if "CL_measured" in data else data["CL"]
    mx = data["CX"] if "CX" in data else -data["CD"] * np.cos(alpha) + cl_meas * np.sin(alpha)
    mz = data["CZ"] if "CZ" in data else -cl_meas * np.cos(alpha) - data["CD"] * np.sin(alpha)
    return float(np.mean((cx - mx) ** 2)), float(np.mean((cz - mz) ** 2))


def fit_candidate(c: Candidate, train: FlightData, validation: FlightData, lift: CandidateResult | None,
                  lift_candidate: Candidate | None, settings: Settings,
                  start: dict | None = None, n_starts: int | None = None,
                  declared_too: bool = False) -> CandidateResult:
    """Fit one candidate on the training maneuvers and score it on both splits; ``start`` (a warm start)
    is the first of ``n_starts`` starts (default ``settings.n_starts``), followed by the declared start
    with ``declared_too``."""
    t0 = time.perf_counter()
    c = c.with_bounds(settings.bounds)
    try:
        model = build_model(c, lift)
        missing = [col for col in model.required_columns if col not in train and col not in train.constants]
        if missing:  # e.g. a pitch candidate with x_cg terms on a campaign without x_cg
            return CandidateResult.failure(
                name=c.name, grid=c.grid, coefficient=c.coefficient, lift=c.lift, seconds=time.perf_counter() - t0,
                error=f"not applicable: the campaign has no column {', '.join(missing)}")
        measured, context = train, None
        if c.lift and lift_candidate is not None:
            context = lift_context(train, validation, lift, lift_candidate)
            train, validation = context.train, context.validation
        warm = model.inside(train, start or {})  # a donor's or baseline's estimates, inside the bounds
        starts = settings.n_starts if n_starts is None else n_starts
        # with a lift model the two-step covariance replaces the fit's own: the fit computes the white one
        result = model.fit(train, start=warm or None, n_starts=starts if model.nonlinear_names else 1,
                           seed=settings.seed, covariance="white" if context is not None else settings.covariance,
                           declared_too=declared_too)
        if context is not None:
            result = with_lift_uncertainty(result, model, measured, lift, context, settings.covariance)
        scores = {}
        folds = maneuver_folds(len(train.starts), settings.cv_folds)
        if folds:
            y = train[c.coefficient]
            scores["cv"] = SplitScores.of(ManeuverScores.of(y, cross_validate(model, train, result, folds,
                                                                              settings.cv_method),
                                                            train.segment_slices()), None)
        for split, data in (("train", train), ("validation", validation)):
            y = data[c.coefficient]
            pred = model.predict(data, result.params)
            other = data["CL"] if c.lift and c.coefficient == "CD" else None  # the lift model's output
            scores[split] = SplitScores.of(ManeuverScores.of(y, y - pred, data.segment_slices()),
                                           _derived(c.coefficient, pred, data, other))
        return CandidateResult.from_fit(name=c.name, grid=c.grid, coefficient=c.coefficient, lift=c.lift,
                                        result=result, train=scores["train"], validation=scores["validation"],
                                        cv=scores.get("cv"), cv_folds=len(folds),
                                        # a linear candidate's folds are exact fits whichever method is asked
                                        cv_method=settings.cv_method if model.nonlinear_names and folds else "refit",
                                        seconds=time.perf_counter() - t0,
                                        centred_correlation=centred_correlation(c, model, train, result))
    except (StructSearchError, np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
        return CandidateResult.failure(name=c.name, grid=c.grid, coefficient=c.coefficient, lift=c.lift,
                                       error=f"{type(exc).__name__}: {exc}", seconds=time.perf_counter() - t0)


def fit_staged(c: Candidate, train: FlightData, validation: FlightData, lift: CandidateResult | None,
               lift_candidate: Candidate | None, settings: Settings, start: dict | None = None) -> CandidateResult:
    """:func:`fit_candidate` from a warm start (a donor's estimates) and the declared start when a warm
    start is given. Else from ``settings.n_starts`` starts (declared and quasi-random) plus, for a
    candidate with unsteady states, the estimates of its quasi-steady stage (:func:`.staging.stages`,
    fitted from :data:`.staging.STAGE_STARTS` starts)."""
    if start is not None:
        return fit_candidate(c, train, validation, lift, lift_candidate, settings, start=start,
                             n_starts=WARM_STARTS, declared_too=True)
    for stage in stages(c):
        model = build_model(stage.with_bounds(settings.bounds))
        try:
            params = model.estimate(train, n_starts=STAGE_STARTS, seed=settings.seed)
        except (StructSearchError, np.linalg.LinAlgError, FloatingPointError):
            break  # a stage the data cannot fit gives no start: c keeps its usual starts
        start = {k: params[k] for k in model.nonlinear_names}
    return fit_candidate(c, train, validation, lift, lift_candidate, settings, start=start,
                         declared_too=start is not None)


def fit_lift_model(c: Candidate, train: FlightData, validation: FlightData, settings: Settings):
    """The fitted lift model a drag or pitch candidate names: (summary, lift candidate), or (None, None)."""
    if not c.lift:
        return None, None
    lift_candidate = load_grid("lift")[c.lift]
    lift = fit_staged(lift_candidate, train, validation, None, None, settings)
    if lift.failed:
        raise StructSearchError(f"fitting the lift model {c.lift} that {c.name} needs failed: {lift.error}")
    return lift, lift_candidate


def same_model_fitted(candidates: Sequence[Candidate], fitted: Sequence[tuple[Candidate, CandidateResult]]
                      ) -> dict[int, tuple[Candidate, CandidateResult]]:
    """Candidates (by index) that are, apart from their name and grid, a candidate fitted already (of an
    earlier grid), with that candidate and its result: the same coefficient, regressors (names and
    expressions), states, lift model and search boxes ask the same question of the same data."""
    def model_of(c):
        d = c.to_dict()
        return json.dumps({k: v for k, v in d.items() if k not in ("name", "grid", "note")}, sort_keys=True)
    done = {model_of(c): (c, r) for c, r in fitted if not r.failed}
    return {i: done[model_of(c)] for i, c in enumerate(candidates) if model_of(c) in done}


def may_be_nonlinear(c: Candidate, lift_params: dict | None) -> bool:
    """Whether ``c`` may have nonlinear parameters: separation parameters its lift model does not fix (a
    drag or pitch candidate's states are usually all the lift model's)."""
    return bool(set(c.state_parameters) - set(lift_params or {}))


def cache_path(out: Path, c: Candidate, data_key: str, lift_params: dict | None, settings: Settings) -> Path:
    """Where the fit of ``c`` on this data, lift model and settings is cached. A warm start is not part of
    the key: it chooses where the solver begins, not the question (the study and the report are served
    the search's fits, however they were started). The cross-validation method is, for a candidate that
    may have nonlinear parameters: the study and the report use "refit", so after a search with
    ``--cv-method one-step`` they fit those candidates again (the linear ones they are served)."""
    from .. import __version__
    blob = json.dumps({"candidate": c.to_dict(), "data": data_key, "lift": lift_params,
                       "settings": settings.key(may_be_nonlinear(c, lift_params)),
                       "version": [__version__, code_fingerprint(), JSON_LAYOUT]},
                      sort_keys=True, default=float)
    key = hashlib.sha256(blob.encode()).hexdigest()[:16]
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in c.name)
    return out / "cache" / c.grid / f"{safe}-{key}.json"


def run(candidates: Sequence[Candidate], campaign: Campaign, out: Path, *, lift_results: dict | None = None,
        lift_candidates: dict | None = None, settings: Settings = Settings(), n_jobs: int = 1,
        backend: str = "loky", progress: Callable[[str], None] | None = None,
        fitted_before: Sequence[tuple[Candidate, CandidateResult]] = ()) -> list[CandidateResult]:
    """Fit candidates (cached, in parallel), staged (:mod:`.staging`): a candidate starts from the
    estimates of a candidate nested in it, fitted before it in this grid (an earlier wave) or in
    ``fitted_before`` (earlier grids of the same search). A candidate that is one of ``fitted_before``
    under another name is served that fit from this run's cache (when it has none of its own: a cache
    written by an earlier run serves first, as for every candidate). Local worker processes take a
    candidate as soon as the candidates it may start from are fitted; other backends fit wave after
    wave. Either way a candidate's donors are the same (those of earlier waves), so the results do not
    depend on the backend or the number of jobs. Results come in the order of ``candidates``."""
    say = progress or (lambda msg: None)
    train, validation = campaign.split("train"), campaign.split("validation")
    data_key = campaign_fingerprint(campaign)
    lift_results = lift_results or {}
    lift_candidates = lift_candidates or {}
    results: list[CandidateResult | None] = [None] * len(candidates)
    order = waves(candidates)
    wave_of = {i: w for w, members in enumerate(order) for i in members}
    # the candidates of earlier waves a candidate may start from: it waits for them
    needs = {i: [j for j in wave_of if wave_of[j] < wave_of[i] and may_donate(candidates[j], candidates[i])]
             for i in wave_of}
    paths = {}
    for i, c in enumerate(candidates):
        lift = lift_results.get(c.lift) if c.lift else None
        paths[i] = cache_path(out, c, data_key, lift.params if lift else None, settings)
        results[i] = _read_cached(paths[i], say)
    cached = sum(r is not None for r in results)
    if cached:
        say(f"{cached} of {len(candidates)} candidates from the cache")
    for i, (twin, _) in same_model_fitted(candidates, fitted_before).items():
        if results[i] is not None:
            continue
        # the lift grid's CL-VI is the separation grid's X_ss/X_w U/S: served the twin's fit as cached
        # under this run's key (the same data, settings, lift model and code), never an object from elsewhere
        twin_lift = lift_results.get(twin.lift) if twin.lift else None
        fitted = _read_cached(cache_path(out, twin, data_key, twin_lift.params if twin_lift else None, settings),
                              say)
        if fitted is not None and not fitted.failed:
            results[i] = dataclasses.replace(fitted, name=candidates[i].name, grid=candidates[i].grid)
            write_json(paths[i], results[i].to_json(), indent=1)
            say(f"{candidates[i].grid} {candidates[i].name}: the same model as {twin.grid} {twin.name}, "
                "fitted already")
    todo = [i for i in range(len(candidates)) if results[i] is None]
    if not todo:
        return results

    def start_of(i):
        return warm_start(candidates[i], list(fitted_before) + [(candidates[j], results[j]) for j in needs[i]])

    def done(i, summary, finished, t0, warm):
        if not summary.failed or summary.error.startswith(CACHED_FAILURES):
            write_json(paths[i], summary.to_json(), indent=1)
        results[i] = summary
        status = "failed: " + summary.error if summary.failed else f"{summary.seconds:.1f} s"
        say(f"[{finished}/{len(todo)}] {candidates[i].grid} {candidates[i].name}{' (warm start)' if warm else ''}: "
            f"{status} ({time.perf_counter() - t0:.0f} s elapsed)")

    with ExitStack() as stack:  # the splits are shared with the workers once
        splits = stack.enter_context(shared_splits(train, validation, backend, n_jobs))
        task = _Task(candidates, splits, lift_results, lift_candidates, settings)
        t0 = time.perf_counter()
        if backend in LOCAL_PROCESS_BACKENDS and n_jobs > 1:
            _fit_as_ready(todo, needs, start_of, task, n_jobs, lambda i, s, k, w: done(i, s, k, t0, w))
        else:
            from joblib import Parallel, delayed, parallel_config
            finished = 0
            for wave in order:
                mine = [i for i in wave if i in set(todo)]
                starts = {i: start_of(i) for i in mine}
                with parallel_config(backend=backend, n_jobs=n_jobs):
                    # unordered: each result is cached as soon as it exists (a crash loses only running fits)
                    for i, summary in Parallel(return_as="generator_unordered")(
                            delayed(task)(i, starts[i]) for i in mine):
                        finished += 1
                        done(i, summary, finished, t0, starts[i])
    return results


# Thread pools of numerical libraries a worker process must not multiply by the number of workers.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
                    "VECLIB_MAXIMUM_THREADS", "NUMBA_NUM_THREADS", "NUMEXPR_NUM_THREADS")


class _Task:
    """One candidate's fit in a worker: the splits come from the shared handle."""

    def __init__(self, candidates, splits, lift_results, lift_candidates, settings):
        self.candidates, self.splits, self.settings = candidates, splits, settings
        self.lift_results, self.lift_candidates = lift_results, lift_candidates

    def __call__(self, i, start):
        c = self.candidates[i]
        train, validation = resolve_splits(self.splits)
        return i, fit_staged(c, train, validation, self.lift_results.get(c.lift) if c.lift else None,
                             self.lift_candidates.get(c.lift), self.settings, start=start)


def _fit_as_ready(todo, needs, start_of, task, n_jobs, done) -> None:
    """Fit ``todo`` on local worker processes, each candidate as soon as the ones it ``needs`` are fitted
    (joblib's reusable memmapping executor; its workers survive between the grids of a search)."""
    from concurrent.futures import FIRST_COMPLETED, wait
    from joblib import cpu_count
    from joblib.executor import get_memmapping_executor
    # the workers' thread pools share the cores, as joblib's Parallel arranges, unless the caller said
    threads = str(max(cpu_count() // n_jobs, 1))
    env = {var: os.environ.get(var, threads) for var in THREAD_VARIABLES}
    if "ENABLE_IPC" not in os.environ:  # TBB's schedulers coordinate across processes, as joblib sets it
        env["ENABLE_IPC"] = "1"
    executor = get_memmapping_executor(n_jobs, timeout=300, env=env)
    waiting, running, finished = set(todo), {}, 0
    fitted = set(needs) - set(todo)   # the cached ones
    try:
        while waiting or running:
            for i in sorted(waiting):
                if all(j in fitted for j in needs[i]):
                    start = start_of(i)
                    running[executor.submit(task, i, start)] = (i, start)
                    waiting.discard(i)
            if not running:  # cannot happen: needs only point to earlier waves
                raise RuntimeError(f"candidates {sorted(waiting)} wait for candidates that never finish")
            complete, _ = wait(running, return_when=FIRST_COMPLETED)
            failure = None
            for future in complete:  # every finished fit is kept (cached) before a failure is raised
                i, start = running.pop(future)
                try:
                    _, summary = future.result()
                except BaseException as exc:
                    failure = failure or exc
                    continue
                fitted.add(i)
                finished += 1
                done(i, summary, finished, start)
            if failure is not None:
                raise failure
    except BaseException:
        # a failed task or an interrupt: nothing more starts; the caller then removes the shared splits,
        # so wait for the fits already running (an interrupt waits for them to end) rather than pull
        # their data from under them
        for future in running:
            future.cancel()
        wait(running)
        raise


def _read_cached(path: Path, say) -> CandidateResult | None:
    """A cached result, or None when there is none or the file is unreadable (refitted, said)."""
    if not path.exists():
        return None
    try:
        return CandidateResult.from_json(json.loads(path.read_text()))
    except (ValueError, KeyError, TypeError) as exc:
        say(f"cache file {path} is unreadable ({type(exc).__name__}); refitting")
        return None


def stderr_progress(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)
