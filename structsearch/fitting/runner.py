"""Runner: fit every candidate of a grid in parallel, cache each result on disk, resume.

Every finished candidate is written to ``<out>/cache/<grid>/<name>-<key>.json``
(atomically); the key hashes the candidate, the data, the lift parameters it
depends on and the options, so an interrupted search resumes where it stopped
and a changed input is never served from a stale cache. A failing candidate is
recorded with its reason and never stops the search. Results are identical for
any number of jobs and either backend: every task (a start, a fold, a fit's statistics) is seeded and
its arguments are fixed when it is made, never by which task finished first.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from contextlib import ExitStack
from functools import lru_cache
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..data.atomic import write_json
from ..data.campaign import Campaign
from ..data.errors import StructSearchError
from ..data.flightdata import FlightData
from ..data.reading import MAX_CACHE_BYTES, load_json
from .cache_signing import signature, signed
from .candidate_result import JSON_LAYOUT, CandidateResult
from .candidates import Candidate
from .lift_fit import LiftFit
from .options import FitOptions
from .pools import task_pool
from .scheduling import CallPlan, fit_as_tasks
from .staging import may_donate, waves
from .trace import Trace
from .shared_data import shared_splits


def fingerprint(data: FlightData) -> str:
    """Hash of everything a fit reads from the data: columns, maneuver boundaries and names, constants, flights,
    periods."""
    h = hashlib.sha256()
    for name in sorted(data.columns):
        h.update(name.encode())
        h.update(np.ascontiguousarray(data.columns[name]).tobytes())
    h.update(np.asarray(data.starts, np.int64).tobytes())
    h.update(json.dumps([list(data.names), sorted((k, float(v)) for k, v in data.constants.items())]).encode())
    if data.flights is not None:  # a by-flight covariance reads them; data without flights keep their keys
        h.update(json.dumps(list(data.flights)).encode())
    if data.periods is not None:  # periodic states start elsewhere; data without periodic maneuvers keep their keys
        h.update(json.dumps(["periods", list(data.periods)]).encode())
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


def model_key(c: Candidate) -> str:
    """What makes two candidates one question: the whole declaration but its name, grid and note."""
    return json.dumps({k: v for k, v in c.to_dict().items() if k not in ("name", "grid", "note")}, sort_keys=True)


def same_model_fitted(candidates: Sequence[Candidate], fitted: Sequence[tuple[Candidate, CandidateResult]]
                      ) -> dict[int, tuple[Candidate, CandidateResult]]:
    """Candidates (by index) that are, apart from their name and grid, a candidate fitted already (of an
    earlier grid), with that candidate and its result: the same coefficient, regressors (names and
    expressions), states, lift model and search boxes ask the same question of the same data."""
    done = {model_key(c): (c, r) for c, r in fitted if not r.failed}
    return {i: done[model_key(c)] for i, c in enumerate(candidates) if model_key(c) in done}


def may_be_nonlinear(c: Candidate, lift_params: dict | None) -> bool:
    """Whether ``c`` may have nonlinear parameters: separation parameters its lift model does not fix (a
    drag or pitch candidate's states are usually all the lift model's)."""
    return bool(set(c.state_parameters) - set(lift_params or {}))


def cache_path(out: Path, c: Candidate, data_key: str, lift_params: dict | None,
               options: FitOptions) -> tuple[Path, str]:
    """Where (and under which full key, the sha256 of the question) the fit of ``c`` on this data, lift model (``lift_params``: its ``cache_key``, the parameters, and a
    joint lift's partners) and options is cached. A warm start is not part of
    the key: it chooses where the solver begins, not the question (the study and the report are served
    the search's fits, however they were started). The cross-validation method is, for a candidate that
    may have nonlinear parameters: the study and the report use "refit", so after a search with
    ``--cv-method one-step`` they fit those candidates again (the linear ones they are served)."""
    from .._version import __version__
    blob = json.dumps({"candidate": c.to_dict(), "data": data_key, "lift": lift_params,
                       "options": options.key(may_be_nonlinear(c, lift_params)),
                       "version": [__version__, code_fingerprint(), JSON_LAYOUT]},
                      sort_keys=True, default=float)
    key = hashlib.sha256(blob.encode()).hexdigest()
    return out / "cache" / _safe(c.grid) / f"{_safe(c.name)}-{key[:16]}.json", key


def _safe(name: str) -> str:
    """A name as one path component of the cache: never "..", "/" or empty (a grid's name comes from a file)."""
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name)[:100] or "_"


def _lift_key(lifts: dict[str, LiftFit], candidate: Candidate) -> str | None:
    """The cache key of the lift model a drag or pitch candidate reads (None for a lift candidate)."""
    lift = lifts.get(candidate.lift) if candidate.lift else None
    return lift.cache_key if lift else None


def _serve_twins(candidates: Sequence[Candidate], fitted_before, results: list, paths: dict, path_of,
                 say: Callable[[str], None]) -> None:
    """A candidate that is one of ``fitted_before`` under another name, not cached itself, is served the twin's
    fit as cached under this run's key (the same data, options, lift model and code), never an object from
    elsewhere: the lift grid's CL-VI is the separation grid's X_ss/X_w U/S."""
    for i, (twin, _) in same_model_fitted(candidates, fitted_before).items():
        if results[i] is not None:
            continue
        fitted = read_cached(*path_of(twin), say)
        if fitted is not None and not fitted.failed:
            results[i] = dataclasses.replace(fitted, name=candidates[i].name, grid=candidates[i].grid)
            write_cached(*paths[i], results[i])
            say(f"{candidates[i].grid} {candidates[i].name}: the same model as {twin.grid} {twin.name}, "
                "fitted already")


def run(candidates: Sequence[Candidate], campaign: Campaign, out: Path, *, lifts: dict[str, LiftFit] | None = None,
        options: FitOptions = FitOptions(), n_jobs: int = 1,
        backend: str = "loky", progress: Callable[[str], None] | None = None,
        fitted_before: Sequence[tuple[Candidate, CandidateResult]] = (), trace: Trace | None = None,
        meter: Callable[[int, int, str], None] | None = None, staged: bool = True) -> list[CandidateResult]:
    """Fit candidates (cached, in parallel), staged (:mod:`.staging`): a candidate starts from the
    estimates of a candidate nested in it, fitted before it in this grid (an earlier wave) or in
    ``fitted_before`` (earlier grids of the same search). A candidate that is one of ``fitted_before``
    under another name is served that fit from this run's cache (when it has none of its own: a cache
    written by an earlier run serves first, as for every candidate). Each candidate's starts, statistics and
    folds are tasks of their own (:mod:`.scheduling`), on any backend; a candidate's donors are fixed (those of
    earlier waves), so the results do not depend on the backend, the number of jobs or the order tasks finish
    in. Results come in the order of ``candidates``; ``trace`` records every task; ``meter(finished, of, what)`` is
    told of each candidate fitted (``progress`` only of what is worth a line: the cache, a failure). ``staged``
    False: no candidate of this call starts from another of it (each is fitted as it would be alone, the
    candidates side by side: a round of refinements)."""
    say = progress or (lambda msg: None)
    train, validation = campaign.split("train"), campaign.split("validation")
    data_key = campaign_fingerprint(campaign)
    lifts = lifts or {}
    order = waves(candidates)
    wave_of = {i: w for w, members in enumerate(order) for i in members}
    # the candidates of earlier waves a candidate may start from: it waits for them
    needs = {i: [j for j in wave_of if staged and wave_of[j] < wave_of[i]
                 and may_donate(candidates[j], candidates[i])] for i in wave_of}
    paths = {i: cache_path(out, c, data_key, _lift_key(lifts, c), options) for i, c in enumerate(candidates)}
    results: list[CandidateResult | None] = [read_cached(*paths[i], say) for i in range(len(candidates))]
    cached = sum(r is not None for r in results)
    if cached:
        say(f"{cached} of {len(candidates)} candidates from the cache")
    _serve_twins(candidates, fitted_before, results, paths, lambda c: cache_path(
        out, c, data_key, _lift_key(lifts, c), options), say)
    todo = [i for i in range(len(candidates)) if results[i] is None]
    if not todo:
        return results
    finished = [0]

    def done(i, summary, warm):
        if not summary.failed or summary.failure_kind.cached:   # a failure that may be the code's is fitted again
            write_cached(*paths[i], summary)
        results[i] = summary
        finished[0] += 1
        if summary.failed:
            say(f"{candidates[i].grid} {candidates[i].name}: failed: {summary.error}")
        if meter is not None:
            meter(finished[0], len(todo), f"{candidates[i].grid} {candidates[i].name}")

    plan = CallPlan(candidates, todo, needs, {i: r for i, r in enumerate(results) if r is not None},
                    list(fitted_before))
    since = len(trace) if trace is not None else 0
    with ExitStack() as stack:  # the splits are shared with the workers once
        splits = stack.enter_context(shared_splits(train, validation, backend, n_jobs))
        pool = stack.enter_context(task_pool(backend, n_jobs))
        try:
            fit_as_tasks(plan, splits, train, options, lifts, pool, trace, done)
        finally:
            if trace is not None:
                trace.call_boundary(since)
    return results


# A cache entry proves itself: {"key": the full sha256 of its question, "digest": the sha256 of its content,
# "content": the fit, "signature": the HMAC of key and digest under the user's key (:mod:`.cache_signing`)}. A file
# whose key is another question's, whose content was altered (a digest that does not match), that is not signed
# under this user's key (edited and its digest recomputed, or written elsewhere), that is not a regular file of
# bounded size, or that is not such an envelope at all (null, a list, an older layout) is a miss: refitted, said once.
CACHE_ENVELOPE = ("key", "digest", "content", "signature")


def content_digest(content) -> str:
    """The sha256 of a JSON value in canonical form (sorted keys, no spaces)."""
    return hashlib.sha256(json.dumps(content, sort_keys=True, separators=(",", ":"), allow_nan=True)
                          .encode()).hexdigest()


def write_cached(path: Path, key: str, result: CandidateResult) -> None:
    content = json.loads(json.dumps(result.to_json(), default=float))   # as it will read back
    digest = content_digest(content)
    write_json(path, {"key": key, "digest": digest, "content": content, "signature": signature(key, digest)},
               indent=1)


def read_cached(path: Path, key: str, say) -> CandidateResult | None:
    """A cached result that proves itself (its key, content digest and signature), or None (a miss, said once)."""
    if not os.path.lexists(path):
        return None
    try:
        doc = load_json(path, limit=MAX_CACHE_BYTES)
    except StructSearchError as exc:
        return _miss(path, f"unreadable ({str(exc).removeprefix(f'file {path}: ')})", say)
    if not isinstance(doc, dict) or set(doc) != set(CACHE_ENVELOPE):
        return _miss(path, "not a cache entry of this version", say)
    if doc["key"] != key:
        return _miss(path, "its key is another question's", say)
    if doc["digest"] != content_digest(doc["content"]):
        return _miss(path, "its content does not match its digest (altered)", say)
    if not signed(key, doc["digest"], doc["signature"]):
        return _miss(path, "not signed with this user's cache key (altered, or written elsewhere)", say)
    try:
        return CandidateResult.from_json(doc["content"])
    except (ValueError, KeyError, TypeError, AttributeError, IndexError) as exc:
        return _miss(path, f"content not readable ({type(exc).__name__})", say)


def _miss(path: Path, why: str, say) -> None:
    say(f"warning: cache file {path} not used: {why}; refitting")
    return None
