"""What each command does, as typed Python functions (docs/interfaces.md 6.1): ``fit``, ``search``, ``diagnose``,
``simulate``, ``preprocess``, ``study``. Options are keyword-only with the command line's defaults; nothing
prints (``progress`` receives the lines the command writes to stderr). ``campaign`` is a
:class:`~structsearch.data.campaign.Campaign` or the directory of one."""
from __future__ import annotations

import os
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

from ..data.campaign import Campaign, read_campaign
from ..data.atomic import write_json
from ..data.errors import DeclarationError
from ..engine.statistics import DEFAULT_COVARIANCE
from ..fitting.options import FitOptions, check_box_names
from ..grid_search.admissibility import MAX_CORRELATION
from .results import FitOutcome, PreprocessOutcome, Ranking, StudyOutcome

Progress = Callable[[str], None] | None
Bounds = Mapping[str, tuple[float, float]] | Iterable[tuple[str, tuple[float, float]]] | None


def as_campaign(campaign: Campaign | str | os.PathLike, segment: str | None = None) -> Campaign:
    """``campaign`` itself, or the standard campaign read from that directory. ``segment`` (``--segment``):
    "cycles" cuts every record into its cycles, "none" keeps each whole, None as campaign.toml says
    (:mod:`structsearch.data.records`; a campaign in memory: :func:`structsearch.data.cycles.segmented`)."""
    if isinstance(campaign, Campaign):
        from ..data.cycles import segmented
        return segmented(campaign, segment)
    return read_campaign(campaign, segment=segment)


def process_count(jobs: int) -> int:
    """``jobs`` as a process count: 0 means every core (the commands' ``--jobs``)."""
    return jobs or os.cpu_count() or 1


def parameter_boxes(bounds: Bounds) -> tuple:
    """``bounds`` (a mapping or pairs, as repeated ``--bound NAME=LO:HI``) as FitOptions' sorted boxes, the
    last box of a name winning."""
    pairs = dict(bounds.items() if isinstance(bounds, Mapping) else (bounds or ()))
    return tuple(sorted((name, (float(lo), float(hi))) for name, (lo, hi) in pairs.items()))


def fit_options(starts: int, seed: int, covariance: str, bounds: Bounds, campaign: Campaign | None = None,
                **more: Any) -> FitOptions:
    """The commands' FitOptions; with the ``campaign``, its cross-validation folds leave one cycle out when its
    training maneuvers are cycles of periodic records (:func:`structsearch.fitting.folds.fold_size_for`), and
    blocked folds last at least the campaign's shortest maneuver worth fitting
    (:func:`structsearch.fitting.folds.block_convective_times`)."""
    if campaign is not None and "cv_fold_size" not in more:
        from ..fitting.folds import fold_size_for
        more["cv_fold_size"] = fold_size_for(campaign.maneuvers)
    if campaign is not None and "cv_block_convective_times" not in more:
        from ..fitting.folds import block_convective_times
        more["cv_block_convective_times"] = block_convective_times(campaign)
    return FitOptions(n_starts=starts, seed=seed, covariance=covariance, parameter_boxes=parameter_boxes(bounds),
                      **more)


@contextmanager
def cache_directory(cache: str | os.PathLike | None) -> Iterator[Path]:
    """``cache`` as a Path, or a temporary directory (removed afterwards) when it is None."""
    if cache is not None:
        yield Path(cache)
        return
    with tempfile.TemporaryDirectory(prefix="structsearch-") as tmp:
        yield Path(tmp)


def fit(campaign: Campaign | str | os.PathLike, model: str, *, starts: int = 4, seed: int = 0,
        covariance: str = DEFAULT_COVARIANCE, bounds: Bounds = None, progress: Progress = None,
        band_samples: int = 0, profile: bool = False, segment: str | None = None) -> FitOutcome:
    """Fit one candidate (a catalogue name such as ``"CD-IXr"`` or a spec file) as ``structsearch fit`` does:
    a drag or pitch candidate first fits the lift model it names, on the training maneuvers. The outcome holds
    the static curve's 95 % confidence and prediction bands (``.bands``); ``band_samples`` > 0 adds their
    cross-check by parameter sampling (that many draws, seeded by ``seed``). ``profile``: also the 95 % and 68 %
    profile intervals of the nonlinear parameters (``.profile``, :mod:`structsearch.engine.profile`).
    ``segment``: "cycles" fits a periodic record's cycles as maneuvers (:func:`as_campaign`)."""
    _check_samples(band_samples)
    from ..fitting.candidate_fit import fit_lift_model, fit_staged
    from ..fitting.specs import resolve_candidate
    candidate = resolve_candidate(model)   # a misspelled name is answered before the campaign is read
    campaign = as_campaign(campaign, segment)
    options = fit_options(starts, seed, covariance, bounds, campaign)
    check_box_names(options.parameter_boxes, [candidate])
    train, validation = campaign.split("train"), campaign.split("validation")
    if progress is not None:
        progress(f"fit: {candidate.name}" + (f" on {candidate.lift}" if candidate.lift else ""))
    lift = fit_lift_model(candidate, train, validation, options)
    result = fit_staged(candidate, train, validation, lift, options)
    if result.failed:
        raise DeclarationError(result.error)
    from ..fitting.bands import static_bands
    profiles = None
    if profile:
        from ..fitting.profile import profile_candidate
        if progress is not None:
            progress(f"fit: profile intervals of {', '.join(result.nonlinear_names) or 'no nonlinear parameter'}")
        profiles = profile_candidate(candidate, result, train, lift)
    return FitOutcome(candidate, result, lift, static_bands(candidate, result, train, lift, samples=band_samples,
                                                            seed=seed), profiles)


def _check_samples(band_samples: int) -> None:
    if band_samples != 0 and band_samples < 2:
        raise DeclarationError(f"--band-samples {band_samples}: parameter sampling needs at least 2 draws (0: none)")


def fit_joint(campaign: Campaign | str | os.PathLike, structures: str | Sequence[str], *, starts: int = 4,
              seed: int = 0, covariance: str = DEFAULT_COVARIANCE, bounds: Bounds = None,
              progress: Progress = None, band_samples: int = 0, replay_maneuver: str | None = None,
              segment: str | None = None):
    """Fit two or three structures (lift, drag, pitch) jointly, sharing their separation states, as
    ``structsearch fit --joint`` does: ``structures`` is "CL-VI,CD-IXr,Cm-XXXIIIr", a list of names or spec
    files, or a joint spec file. Returns the typed :class:`structsearch.fitting.joint.JointFit` (``to_dict()``
    is its ``fit.json``). ``band_samples`` > 0: the static bands' cross-check by parameter sampling and, for a
    fit of all three coefficients, a validation maneuver's forward replay with its sampled band
    (``replay_maneuver``, default the one that flies deepest; :mod:`structsearch.flight.replay_bands`)."""
    _check_samples(band_samples)
    from ..fitting.joint import fit_joint as run, joint_structures
    campaign = as_campaign(campaign, segment)
    candidates = joint_structures(structures if isinstance(structures, str) else ",".join(structures))
    options = fit_options(starts, seed, covariance, bounds, campaign)
    check_box_names(options.parameter_boxes, candidates)
    candidates = [c.with_bounds(options.parameter_boxes) for c in candidates]
    if progress is not None:
        progress("fit: " + " + ".join(c.name for c in candidates) + " jointly")
    joint = run(candidates, campaign.split("train"), campaign.split("validation"), options, band_samples=band_samples)
    if band_samples and {c.coefficient for c in candidates} == {"CL", "CD", "Cm"}:
        import dataclasses
        from ..flight.replay_bands import replay_band
        if progress is not None:
            progress(f"fit: the forward replay with {band_samples} parameter draws")
        joint = dataclasses.replace(joint, replay=replay_band(joint, campaign.split("validation"), replay_maneuver,
                                                             band_samples, seed))
    elif replay_maneuver is not None:
        raise DeclarationError("--replay-maneuver needs --band-samples and a joint fit of C_L, C_D and C_m")
    return joint


def search_candidates(grid: str) -> list:
    """Every candidate of ``grid`` (separation, lift, drag, pitch, all or a grid spec file)."""
    from ..grid_search.pipeline import grids_for
    return [c for g in grids_for(grid) for c in g.candidates]


def search(campaign: Campaign | str | os.PathLike, grid: str = "all", *, out: str | os.PathLike | None = None,
           cache: str | os.PathLike | None = None, jobs: int = 0, starts: int = 4, seed: int = 0,
           covariance: str = DEFAULT_COVARIANCE, bounds: Bounds = None, cv_method: str = "refit",
           backend: str = "loky", scheduler: str | None = None, max_correlation: float = MAX_CORRELATION,
           refine: bool = True, progress: Progress = None, joint_lift: str | Sequence[str] | None = None,
           segment: str | None = None) -> Ranking:
    """Fit and rank every candidate of ``grid`` as ``structsearch search`` does. ``cache``: the directory whose
    ``cache/`` holds the fits (default ``out``, else a temporary directory); ``out``: also write
    ``ranking.csv`` and the tables there (and ``joint_lift.json``, the joint fit, with ``joint_lift``).
    ``joint_lift``: structures fitted jointly first ("CL-VI,CD-IXr,Cm-XXXIIIr", a list or a joint spec
    file); drag and pitch candidates read its lift block (``search --joint-lift``)."""
    from ..grid_search.pipeline import search as run_search
    candidates = search_candidates(grid)   # a misspelled grid is answered before the campaign is read
    campaign = as_campaign(campaign, segment)
    options = fit_options(starts, seed, covariance, bounds, campaign, cv_method=cv_method)
    check_box_names(options.parameter_boxes, candidates)
    joint = ()
    if joint_lift:
        from ..engine.twostep import SCORE_KINDS
        from ..fitting.joint import joint_structures
        joint = joint_structures(joint_lift if isinstance(joint_lift, str) else ",".join(joint_lift))
        if not any(c.coefficient == "CL" for c in joint):
            raise DeclarationError("--joint-lift: the joint structures need a lift structure (CL-...) for drag "
                                   "and pitch to read")
        if covariance not in SCORE_KINDS:
            raise DeclarationError(f"--joint-lift with --covariance {covariance}: the two-step covariance with a "
                                   f"joint first step needs one of {', '.join(SCORE_KINDS)} ({covariance} models "
                                   "the first step's residual series, which a joint fit of three coefficients "
                                   "does not have as one)")
        check_box_names(options.parameter_boxes, joint)
        joint = [c.with_bounds(options.parameter_boxes) for c in joint]
    client = dask_client(scheduler, process_count(jobs)) if backend == "dask" else None
    try:
        with cache_directory(cache if cache is not None else out) as where:
            result = run_search(campaign, grid, where, n_jobs=process_count(jobs), options=options,
                                backend=backend, max_correlation=max_correlation, progress=progress,
                                do_refine=refine, joint_lift=joint)
    finally:
        if client is not None:
            client.close()
    ranking = Ranking(result.grids, result.seconds, result.refinements, joint=result.joint)
    if out is not None:
        write_search_tables(ranking, campaign, Path(out))
        if result.joint is not None:
            write_json(Path(out) / "joint_lift.json", result.joint.to_dict())
    return ranking


def write_search_tables(ranking: Ranking, campaign: Campaign, out: Path) -> list[Path]:
    """``ranking.csv`` and each grid's tables (with the thesis-estimator refits of the final models)."""
    from ..reporting.tables import write_tables
    from ..thesis_study.thesis_estimator import thesis_estimator_fits
    return write_tables(ranking.grids, out, thesis_estimator_fits(ranking.grids, campaign))


def dask_client(scheduler: str | None, jobs: int):
    """A dask.distributed Client: the given scheduler, else a local cluster of ``jobs`` single-threaded workers."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise DeclarationError("--backend dask needs the optional dependency dask.distributed "
                               "(pip install 'structsearch[dask]')") from None
    if scheduler:
        return Client(scheduler)
    return Client(LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True, dashboard_address=None))


def diagnose(campaign: Campaign | str | os.PathLike, model: str, *, coefficient: str | None = None,
             starts: int = 2, seed: int = 0, covariance: str = DEFAULT_COVARIANCE, bounds: Bounds = None,
             jobs: int = 0, out: str | os.PathLike | None = None, progress: Progress = None,
             terms: str | os.PathLike | None = None, beam: int | None = None, max_steps: int | None = None,
             backend: str = "loky", segment: str | None = None):
    """Diagnose ``model`` (the baseline) as ``structsearch diagnose`` does: a structure search over moves from it
    (``terms``: a user's term file; ``beam``, ``max_steps``: the search's width and length); with ``out``, also
    write ``diagnosis.json`` and ``diagnosis.md`` there and cache the fits in ``out/cache``. Returns the
    diagnosis (``to_dict()``: diagnosis.json)."""
    import dataclasses
    from ..diagnosis.diagnose import diagnose as run_diagnosis
    from ..discovery.explore import DEFAULT_BEAM, DEFAULT_MAX_STEPS
    from ..fitting.specs import resolve_candidate
    campaign = as_campaign(campaign, segment)
    baseline = resolve_candidate(model, coefficient)
    # structures with separation parameters are cross-validated by one-step folds in a structure search
    options = dataclasses.replace(fit_options(starts, seed, covariance, bounds, campaign), cv_method="one-step")
    check_box_names(options.parameter_boxes, [baseline])
    result = run_diagnosis(campaign, baseline, options=options, n_jobs=process_count(jobs), seed=seed,
                           progress=progress, terms=None if terms is None else str(terms),
                           beam=beam or DEFAULT_BEAM, max_rounds=max_steps or DEFAULT_MAX_STEPS,
                           cache_dir=out, backend=backend)
    if out is not None:
        from ..reporting.diagnosis_doc import write
        write(result, Path(out))
    return result


def simulate(*, seed: int = 0, withhold: Iterable[str] = (), scale: float = 1.0, extras: bool = False,
             aircraft: str = "citation", anomaly: str | None = None, raw: bool = False, slow_errors: float = 1.0,
             out: str | os.PathLike | None = None, format: str = "csv", flights: int = 0) -> Campaign:
    """Simulate a flight-test campaign as ``structsearch simulate`` does (same seed, same campaign bit for bit);
    with ``out``, also write it there. ``flights`` = N > 0: the maneuvers flown on N flights that share errors
    (``simulate --flights N``)."""
    from ..data.campaign import write_campaign
    from ..flight.flighttest import build_campaign
    campaign = build_campaign(seed=seed, withhold=tuple(withhold or ()), scale=scale, extras=extras,
                              aircraft=aircraft, anomaly=anomaly, raw=raw, slow_errors=slow_errors, flights=flights)
    if out is not None:
        write_campaign(campaign, Path(out), fmt=format)
    return campaign


def preprocess(raw: Campaign | str | os.PathLike, out: str | os.PathLike | None = None, *,
               cutoffs: Mapping[str, float] | None = None, suggested_cutoffs: bool = False,
               stall_alpha: float | None = None, stall_state: str | None = None, figures: bool = True,
               command: str | None = None, progress: Callable[[str, float], None] | None = None) -> PreprocessOutcome:
    """Turn a raw campaign (docs/interfaces.md 5.2) into a standard one as ``structsearch preprocess`` does;
    ``stall_alpha`` in degrees; with ``out``, write the standard campaign and preprocess.md there."""
    import numpy as np

    from ..data.campaign import write_campaign
    from ..preprocessing.pipeline import preprocess as run_preprocess, truth_agreement
    started = time.perf_counter()
    if out is not None and not isinstance(raw, Campaign) and Path(raw).resolve() == Path(out).resolve():
        raise DeclarationError(f"--out {out} is the raw campaign itself: it would be replaced; give another directory")
    raw_campaign = raw if isinstance(raw, Campaign) else read_campaign(raw, fmt="raw")
    result = run_preprocess(raw_campaign, dict(cutoffs or {}), use_suggested=suggested_cutoffs,
                            stall_alpha_rad=None if stall_alpha is None else np.deg2rad(stall_alpha),
                            stall_state=stall_state, progress=progress)
    directory = markdown = None
    warnings: tuple[str, ...] = ()
    if out is not None:
        from ..reporting.preprocess_doc import NO_FIGURES, figures_available, write
        if figures and not figures_available():
            warnings = (f"figures skipped: {NO_FIGURES}; the campaign and preprocess.md are written",)
        directory = write_campaign(result.campaign, Path(out))
        markdown = write(result, directory, command or f"structsearch preprocess --raw {raw} --out {out}",
                         time.perf_counter() - started, figures=figures)
    worst: dict[str, float] = {}
    for _, name, r2 in truth_agreement(result.campaign):
        worst[name] = np.fmin(worst.get(name, np.inf), r2)   # a NaN R^2 (constant truth) does not hide others
    return PreprocessOutcome(result, directory, markdown, worst, time.perf_counter() - started, warnings)


def study(campaign: Campaign | str | os.PathLike, *, out: str | os.PathLike | None = None,
          cache: str | os.PathLike | None = None, starts: int = 4, jobs: int = 0, command: str | None = None,
          progress: Progress = None) -> StudyOutcome:
    """The thesis' comparison tables as ``structsearch study`` computes them; fits are cached under ``cache``
    (default ``out``, else a temporary directory); with ``out``, the tables and box plots are written there."""
    from ..thesis_study.study import run_study
    campaign = as_campaign(campaign)
    with cache_directory(cache if cache is not None else out) as where:
        result = run_study(campaign, where, FitOptions(n_starts=starts), n_jobs=process_count(jobs),
                           progress=progress)
    written: list[Path] = []
    if out is not None:
        from ..reporting import figures
        from ..reporting.study_doc import write
        written = write(result, Path(out), command or f"structsearch study --out {out}",
                        figures=figures.plt is not None)
    return StudyOutcome(result, written)

