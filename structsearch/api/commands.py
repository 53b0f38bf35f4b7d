"""What each command does, as typed Python functions (docs/interfaces.md 6.1): ``fit``, ``search``, ``diagnose``,
``simulate``, ``preprocess``, ``study``. Options are keyword-only with the command line's defaults; nothing
prints (``progress`` receives the lines the command writes to stderr). ``campaign`` is a
:class:`~structsearch.data.campaign.Campaign` or the directory of one."""
from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Callable, Mapping, Sequence

from ..data.campaign import Campaign, read_campaign
from ..data.atomic import write_json
from ..data.coefficients import LONGITUDINAL, coefficient as coefficient_record
from ..data.errors import DeclarationError
from ..fitting.options import check_box_names
from ..fitting.pools import warm_workers
from ..grid_search.admissibility import MAX_CORRELATION
from .results import FitOutcome, PreprocessOutcome, Ranking, StudyOutcome
from .settings import FlightTestPlan, Settings, as_campaign, command_fitter, dask_client, fit_options



def fit(campaign: Campaign | str | os.PathLike, model: str, *, settings: Settings = Settings(),
        band_samples: int = 0, profile: bool = False) -> FitOutcome:
    """Fit one candidate (a catalogue name such as ``"CD-IXr"`` or a spec file) as ``structsearch fit`` does:
    a drag or pitch candidate first fits the lift model it names, on the training maneuvers. The outcome holds
    the static curve's 95 % confidence and prediction bands (``.bands``); ``band_samples`` > 0 adds their
    cross-check by parameter sampling (that many draws, seeded by ``settings.seed``). ``profile``: also the 95 %
    and 68 % profile intervals of the nonlinear parameters (``.profile``, :mod:`structsearch.engine.profile`)."""
    _check_samples(band_samples)
    from ..fitting.specs import resolve_candidate
    # a misspelled name is answered before the campaign is read
    candidate = resolve_candidate(model).with_moment_reference(settings.moment_reference)
    warm_workers(settings.backend, settings.processes)
    campaign = as_campaign(campaign, settings.segment, settings.reference_point)
    options = fit_options("fit", settings, campaign)
    progress = settings.progress
    check_box_names(options.parameter_boxes, [candidate])
    train = campaign.split("train")
    if progress is not None:
        progress(f"fit: {candidate.name}" + (f" on {candidate.lift}" if candidate.lift else ""))
    with command_fitter("fit", campaign, settings) as fitter:  # its starts and folds are tasks on the workers
        lift = _lift_model(fitter, candidate)
        result = fitter.with_lifts({candidate.lift: lift} if lift else {}).fit_one(candidate)
    if result.failed:
        raise DeclarationError(f"{candidate.name}: {result.error}")
    from ..fitting.bands import static_bands
    profiles = None
    if profile:
        from ..fitting.profile import profile_candidate
        if progress is not None:
            progress(f"fit: profile intervals of {', '.join(result.estimates.nonlinear_names) or 'no nonlinear parameter'}")
        profiles = profile_candidate(candidate, result, train, lift)
    from .results import campaign_record
    return FitOutcome(candidate, result, lift, static_bands(candidate, result, train, lift, samples=band_samples,
                                                            seed=settings.seed), profiles, campaign_record(campaign),
                      campaign.aircraft.get("reference_point"))


def _lift_model(fitter, candidate):
    """The fitted lift model a drag or pitch candidate names (None for a lift or separation candidate)."""
    from ..fitting.lift_fit import LiftFit
    from ..fitting.specs import lift_candidate as named_lift
    if not candidate.lift:
        return None
    lift_candidate = named_lift(candidate.lift)
    lift = fitter.fit_one(lift_candidate)
    if lift.failed:
        raise DeclarationError(f"fitting the lift model {candidate.lift} that {candidate.name} needs failed: "
                               f"{lift.error}")
    return LiftFit(lift_candidate, lift)


def _check_samples(band_samples: int) -> None:
    if band_samples != 0 and band_samples < 2:
        raise DeclarationError(f"--band-samples {band_samples}: parameter sampling needs at least 2 draws (0: none)")


def fit_joint(campaign: Campaign | str | os.PathLike, structures: str | Sequence[str], *,
              settings: Settings = Settings(), band_samples: int = 0, replay_maneuver: str | None = None):
    """Fit two or three structures (lift, drag, pitch) jointly, sharing their separation states, as
    ``structsearch fit --joint`` does: ``structures`` is "CL-VI,CD-IXr,Cm-XXXIIIr", a list of names or spec
    files, or a joint spec file. Returns the typed :class:`structsearch.fitting.joint.JointFit` (``to_dict()``
    is its ``fit.json``). ``band_samples`` > 0: the static bands' cross-check by parameter sampling and, for a
    fit of all three coefficients, a validation maneuver's forward replay with its sampled band
    (``replay_maneuver``, default the one that flies deepest; :mod:`structsearch.flight.replay_bands`)."""
    _check_samples(band_samples)
    from ..fitting.joint import fit_joint as run, joint_structures
    campaign = as_campaign(campaign, settings.segment, settings.reference_point)
    candidates = [c.with_moment_reference(settings.moment_reference)
                  for c in joint_structures(structures if isinstance(structures, str) else ",".join(structures))]
    options = fit_options("fit", settings, campaign)
    progress = settings.progress
    check_box_names(options.parameter_boxes, candidates)
    candidates = [c.with_bounds(options.parameter_boxes) for c in candidates]
    if progress is not None:
        progress("fit: " + " + ".join(c.name for c in candidates) + " jointly")
    joint = run(candidates, campaign.split("train"), campaign.split("validation"), options, band_samples=band_samples)
    if band_samples and {c.coefficient for c in candidates} == set(LONGITUDINAL):
        import dataclasses
        from ..flight.replay_bands import replay_band
        if progress is not None:
            progress(f"fit: the forward replay with {band_samples} parameter draws")
        joint = dataclasses.replace(joint, replay=replay_band(joint, campaign.split("validation"), replay_maneuver,
                                                             band_samples, settings.seed))
    elif replay_maneuver is not None:
        raise DeclarationError("--replay-maneuver needs --band-samples and a joint fit of C_L, C_D and C_m")
    import dataclasses
    from .results import campaign_record
    return dataclasses.replace(joint, data=campaign_record(campaign))


def search_candidates(grid: str) -> list:
    """Every candidate of ``grid`` (a shipped grid's name, ``all``, ``lateral`` or a grid spec file)."""
    from ..grid_search.pipeline import grids_for
    return [c for g in grids_for(grid) for c in g.candidates]


def search(campaign: Campaign | str | os.PathLike, grid: str = "all", *, settings: Settings = Settings(),
           out: str | os.PathLike | None = None, cv_method: str = "refit", scheduler: str | None = None,
           max_correlation: float = MAX_CORRELATION, refine: bool = True,
           joint_lift: str | Sequence[str] | None = None) -> Ranking:
    """Fit and rank every candidate of ``grid`` as ``structsearch search`` does. The fits are cached under
    ``settings.cache`` (default ``out``, else a temporary directory); ``out``: also write ``ranking.csv`` and the
    tables there (and ``joint_lift.json``, the joint fit, with ``joint_lift``). ``joint_lift``: structures fitted
    jointly first ("CL-VI,CD-IXr,Cm-XXXIIIr", a list or a joint spec file); drag and pitch candidates read its
    lift block (``search --joint-lift``). ``scheduler``: a dask scheduler's address (``backend="dask"``)."""
    from ..grid_search.pipeline import search as run_search
    candidates = search_candidates(grid)   # a misspelled grid is answered before the campaign is read
    warm_workers(settings.backend, settings.processes)
    campaign = as_campaign(campaign, settings.segment, settings.reference_point)
    options = fit_options("search", settings, campaign, cv_method=cv_method)
    check_box_names(options.parameter_boxes, candidates)
    joint = _joint_lift_structures(joint_lift, settings, options) if joint_lift else ()
    client = dask_client(scheduler, settings.processes) if settings.backend == "dask" else None
    try:
        with command_fitter("search", campaign, settings, out, cv_method=cv_method) as fitter:
            result = run_search(fitter, grid, max_correlation=max_correlation, do_refine=refine, joint_lift=joint,
                                moment_reference=settings.moment_reference)
            grids, discovered = _with_discovered(fitter, result, candidates) if refine else (result.grids, {})
    finally:
        if client is not None:
            client.close()
    ranking = Ranking(grids, result.seconds, result.refinements, joint=result.joint, discovered=discovered)
    if out is not None:
        write_search_tables(ranking, campaign, Path(out))
        _note_thesis_stderr(ranking, campaign, settings.progress)
        if result.joint is not None:
            write_json(Path(out) / "joint_lift.json", result.joint.to_dict())
    return ranking


def _with_discovered(fitter, result, declared) -> tuple[dict, dict]:
    """Each grid's ranking with what a structure search found where the grid has no admissible structure
    (:mod:`.fallback`), and per grid the structures it added."""
    from .fallback import discover_beside, needs_discovery
    grids, discovered = dict(result.grids), {}
    for name, ranked in result.grids.items():
        if needs_discovery(ranked):
            refined = [c for r in result.refinements.get(name, []) for c, _ in r.steps]
            grids[name], found = discover_beside(fitter, name, ranked, list(declared) + refined)
            if found:
                discovered[name] = found
    return grids, discovered


def _joint_lift_structures(joint_lift: str | Sequence[str], settings: Settings, options) -> list:
    """``search --joint-lift``'s structures, checked (a lift one among them, a covariance a joint first step can
    give) and bounded by the boxes."""
    from ..engine.twostep import SCORE_KINDS
    from ..fitting.joint import joint_structures
    joint = joint_structures(joint_lift if isinstance(joint_lift, str) else ",".join(joint_lift))
    if not any(coefficient_record(c.coefficient).owns_states for c in joint):
        raise DeclarationError("--joint-lift: the joint structures need a lift structure (CL-...) for drag "
                               "and pitch to read")
    if settings.covariance not in SCORE_KINDS:
        raise DeclarationError(f"--joint-lift with --covariance {settings.covariance}: the two-step covariance "
                               f"with a joint first step needs one of {', '.join(SCORE_KINDS)} "
                               f"({settings.covariance} models the first step's residual series, which a joint "
                               "fit of three coefficients does not have as one)")
    check_box_names(options.parameter_boxes, joint)
    return [c.with_bounds(options.parameter_boxes) for c in joint]


def write_search_tables(ranking: Ranking, campaign: Campaign, out: Path) -> list[Path]:
    """``ranking.csv`` and each grid's tables (with the thesis-estimator refits of the final models)."""
    from ..reporting.tables import write_tables
    from ..thesis_study.thesis_estimator import thesis_estimator_fits
    written = write_tables(ranking.grids, out, thesis_estimator_fits(ranking.grids, campaign),
                           refined_structures(ranking))
    answers = {g: a.to_dict() for g, a in ranking.answers.items() if a is not None}
    return written + [write_json(out / "search_answer.json", {"answers": answers})]


def _note_thesis_stderr(ranking: Ranking, campaign: Campaign, progress) -> None:
    """One line when the search fitted the thesis' final models but ``thesis_stderr.md`` is left out: the campaign
    flies another aircraft than the thesis' Citation."""
    from ..flight.reference import FINAL_MODEL_NAMES
    from ..thesis_study.thesis_estimator import other_aircraft
    fitted = {r.name for ranked in ranking.grids.values() for r in ranked if not r.failed}
    note = other_aircraft(campaign)
    if progress is not None and note is not None and set(FINAL_MODEL_NAMES.values()) <= fitted:
        progress(f"search: {note}")


def refined_structures(ranking: Ranking) -> dict[str, list]:
    """Per grid the structures its refinements reached that are no declared candidate (their "-auto" names are
    in ``ranking.csv``; the report reads them back from ``refined_<grid>.toml``)."""
    out: dict[str, list] = {}
    for grid, done in ranking.refinements.items():
        seen = out.setdefault(grid, [])
        for r in done:
            seen += [c for c, _ in r.steps if c.name not in r.reached and c not in seen]
    for grid, found in ranking.discovered.items():   # a structure search's, beside the grid
        out.setdefault(grid, []).extend(c for c in found if c not in out[grid])
    return {g: cs for g, cs in out.items() if cs}


def diagnose(campaign: Campaign | str | os.PathLike, model: str | None = None, *, settings: Settings = Settings(),
             coefficient: str | None = None, out: str | os.PathLike | None = None,
             terms: str | os.PathLike | None = None, beam: int | None = None, max_steps: int | None = None,
             baseline_column: str | None = None, simulator: str | None = None, simulator_inputs=()):
    """Diagnose ``model`` (the baseline) as ``structsearch diagnose`` does: a structure search over moves from it
    (``terms``: a user's term file; ``beam``, ``max_steps``: the search's width and length); with ``out``, also
    write ``diagnosis.json`` and ``diagnosis.md`` there and cache the fits in ``out/cache``. Returns the
    diagnosis (``to_dict()``: diagnosis.json). Instead of ``model``, a simulator's ``coefficient`` as the baseline
    (a fixed offset): ``baseline_column`` names the campaign column it wrote, ``simulator`` is
    "jsbsim:NAME_OR_DIR" (``simulator_inputs``: "PROPERTY=COLUMN|VALUE" items;
    :func:`structsearch.api.diagnosing.diagnose_simulator`)."""
    given = [o for o, v in (("--model", model), ("--baseline-column", baseline_column), ("--simulator", simulator))
             if v is not None]
    if len(given) != 1:
        raise DeclarationError("diagnose takes one baseline: --model NAME, --baseline-column NAME or --simulator "
                               "jsbsim:AIRCRAFT" + (f" (given: {', '.join(given)})" if given else ""))
    if model is None:
        from .diagnosing import diagnose_simulator
        return diagnose_simulator(campaign, coefficient=coefficient, baseline_column=baseline_column,
                                  simulator=simulator, settings=settings, out=out, terms=terms, beam=beam,
                                  max_steps=max_steps, simulator_inputs=simulator_inputs)
    from ..diagnosis.diagnose import DIAGNOSE, diagnose as run_diagnosis
    from ..fitting.specs import resolve_candidate
    campaign = as_campaign(campaign, settings.segment, settings.reference_point)
    baseline = resolve_candidate(model, coefficient).with_moment_reference(settings.moment_reference)
    check_box_names(fit_options("diagnose", settings).parameter_boxes, [baseline])
    with command_fitter("diagnose", campaign, settings, out) as fitter:
        result = run_diagnosis(fitter, baseline, DIAGNOSE.but(beam=beam, max_rounds=max_steps), seed=settings.seed,
                               terms=None if terms is None else str(terms))
    if out is not None:
        from ..reporting.diagnosis_doc import write
        write(result, Path(out))
    return result


def simulate(plan: FlightTestPlan = FlightTestPlan(), *, seed: int = 0, scale: float = 1.0,
             out: str | os.PathLike | None = None, format: str = "csv") -> Campaign:
    """Simulate a flight-test campaign as ``structsearch simulate`` does (same seed, same campaign bit for bit);
    with ``out``, also write it there. ``plan``: what it flies besides (:class:`FlightTestPlan`)."""
    from ..data.campaign import write_campaign
    from ..flight.flighttest import build_campaign
    campaign = build_campaign(seed=seed, withhold=tuple(plan.withhold or ()), scale=scale, extras=plan.extras,
                              aircraft=plan.aircraft, anomaly=plan.anomaly, raw=plan.raw,
                              slow_errors=plan.slow_errors, flights=plan.flights, nominal=plan.nominal,
                              cg_spread=plan.cg_spread, cg_moment=plan.cg_moment)
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


def study(campaign: Campaign | str | os.PathLike, *, settings: Settings = Settings(),
          out: str | os.PathLike | None = None, command: str | None = None) -> StudyOutcome:
    """The thesis' comparison tables as ``structsearch study`` computes them; fits are cached under
    ``settings.cache`` (default ``out``, else a temporary directory); with ``out``, the tables and box plots are
    written there."""
    from ..thesis_study.study import run_study
    campaign = as_campaign(campaign, settings.segment, settings.reference_point)
    with command_fitter("study", campaign, settings, out) as fitter:
        result = run_study(fitter)
    written: list[Path] = []
    if out is not None:
        from ..reporting import figures
        from ..reporting.study_doc import write
        written = write(result, Path(out), command or f"structsearch study --out {out}",
                        figures=figures.plt is not None)
    return StudyOutcome(result, written)
