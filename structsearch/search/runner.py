"""Runner: fit every candidate of a grid in parallel, cache each result on disk, resume.

Every finished candidate is written to ``<out>/cache/<grid>/<name>-<key>.json``
(atomically); the key hashes the candidate, the data, the lift parameters it
depends on and the settings, so an interrupted search resumes where it stopped
and a changed input is never served from a stale cache. A failing candidate is
recorded with its reason and never stops the search. Results are identical for
any number of jobs: each fit is seeded and runs on one process.
"""
from __future__ import annotations

import hashlib
import json
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
from ..engine.snls import model_jacobian
from ..engine.scores import ManeuverScores
from ..engine.statistics import DEFAULT_COVARIANCE
from .candidate_result import JSON_LAYOUT, CandidateResult, SplitScores
from .generated import with_lift_uncertainty
from .models import build_model
from .shared_data import lift_context, resolve_splits, shared_splits
from .staging import STAGE_STARTS, WARM_STARTS, stages, warm_start, waves

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

    def key(self) -> dict:
        return {"n_starts": self.n_starts, "seed": self.seed, "covariance": self.covariance,
                "cv_folds": self.cv_folds, "bounds": [[k, list(v)] for k, v in self.bounds],
                "cv_method": self.cv_method}


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
    folds share its factorisation too (for a linear model the step lands on the fold's exact fit).
    Folds need estimates only: no statistics are computed for them.

    Drag and pitch candidates keep the separation states and C_L of the lift model fitted on all
    training maneuvers (held-out ones included): their comparison is conditional on that lift model,
    as their fits are; it is the same for every candidate of a grid, so it does not favour one."""
    y = train[model.coefficient]
    if not model.nonlinear_names:
        return held_out_residuals(model.bind(train).regression_matrix(np.zeros(0)), y, train.bounds, folds)
    if method == "one-step":
        theta = np.array([result.params[k] for k in model.nonlinear_names], float)
        coef = np.array([result.params[k] for k in model.linear_names], float)
        ev = model.bind(train).evaluate(theta)
        jac = model_jacobian(ev, coef, len(theta))
        return held_out_residuals(jac, y - ev.phi @ coef, train.bounds, folds)
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
                                        cv_method=settings.cv_method,  # a linear candidate's is exact either way
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


def cache_path(out: Path, c: Candidate, data_key: str, lift_params: dict | None, settings: Settings) -> Path:
    """Where the fit of ``c`` on this data, lift model and settings is cached. A warm start is not part of
    the key: it chooses where the solver begins, not the question (the study and the report are served
    the search's fits, however they were started)."""
    from .. import __version__
    blob = json.dumps({"candidate": c.to_dict(), "data": data_key, "lift": lift_params,
                       "settings": settings.key(), "version": [__version__, code_fingerprint(), JSON_LAYOUT]},
                      sort_keys=True, default=float)
    key = hashlib.sha256(blob.encode()).hexdigest()[:16]
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in c.name)
    return out / "cache" / c.grid / f"{safe}-{key}.json"


def run(candidates: Sequence[Candidate], campaign: Campaign, out: Path, *, lift_results: dict | None = None,
        lift_candidates: dict | None = None, settings: Settings = Settings(), n_jobs: int = 1,
        backend: str = "loky", progress: Callable[[str], None] | None = None,
        fitted_before: Sequence[tuple[Candidate, CandidateResult]] = ()) -> list[CandidateResult]:
    """Fit candidates (cached, in parallel) in staged waves (:mod:`.staging`): a candidate starts from the
    estimates of a candidate nested in it, fitted in an earlier wave or in ``fitted_before``. Results
    come in the order of ``candidates``."""
    say = progress or (lambda msg: None)
    train, validation = campaign.split("train"), campaign.split("validation")
    data_key = campaign_fingerprint(campaign)
    lift_results = lift_results or {}
    lift_candidates = lift_candidates or {}
    results: list[CandidateResult | None] = [None] * len(candidates)
    fitted = list(fitted_before)
    splits = None
    with ExitStack() as stack:  # the splits are shared with the workers once, when a fit is needed
        for wave in waves(candidates):
            todo, paths, starts = [], {}, {}
            for i in wave:
                c = candidates[i]
                lift = lift_results.get(c.lift) if c.lift else None
                starts[i] = warm_start(c, fitted)
                paths[i] = cache_path(out, c, data_key, lift.params if lift else None, settings)
                cached = _read_cached(paths[i], say)
                if cached is not None:
                    results[i] = cached
                else:
                    todo.append(i)
            if len(todo) < len(wave):
                say(f"{len(wave) - len(todo)} of {len(wave)} candidates from the cache")
            if todo:
                if splits is None:
                    splits = stack.enter_context(shared_splits(train, validation, backend, n_jobs))
                _fit_wave(todo, candidates, starts, paths, results, splits, lift_results, lift_candidates,
                          settings, n_jobs, backend, say)
            fitted += [(candidates[i], results[i]) for i in wave]
    return results


def _fit_wave(todo, candidates, starts, paths, results, splits, lift_results, lift_candidates,
              settings, n_jobs, backend, say) -> None:
    """Fit the candidates ``todo`` of one wave in parallel, caching each result as soon as it exists;
    ``splits`` is a handle of :func:`.shared_data.shared_splits`."""
    def task(i):
        c = candidates[i]
        train, validation = resolve_splits(splits)
        return i, fit_staged(c, train, validation, lift_results.get(c.lift) if c.lift else None,
                             lift_candidates.get(c.lift), settings, start=starts[i])

    from joblib import Parallel, delayed, parallel_config
    done = 0
    t0 = time.perf_counter()
    with parallel_config(backend=backend, n_jobs=n_jobs):
        # unordered: each result is cached as soon as it exists (a crash loses only running fits)
        for i, summary in Parallel(return_as="generator_unordered")(delayed(task)(i) for i in todo):
            if not summary.failed or summary.error.startswith(CACHED_FAILURES):
                write_json(paths[i], summary.to_json(), indent=1)
            results[i] = summary
            done += 1
            status = "failed: " + summary.error if summary.failed else f"{summary.seconds:.1f} s"
            warm = " (warm start)" if starts[i] else ""
            say(f"[{done}/{len(todo)}] {candidates[i].grid} {candidates[i].name}{warm}: {status} "
                f"({time.perf_counter() - t0:.0f} s elapsed)")


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
