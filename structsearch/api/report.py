"""``report``: the fits a campaign report shows (the identified and the Van Ingen model sets, a diagnosis and its
best effect), then the page (:func:`structsearch.reporting.page.build`, which fits nothing)."""
from __future__ import annotations

import os
import time
from pathlib import Path

from ..data.campaign import Campaign
from ..data.errors import DataError, DeclarationError
from ..engine.statistics import DEFAULT_COVARIANCE
from ..fitting.options import FitOptions, check_box_names
from .commands import Bounds, Progress, as_campaign, fit_options, process_count, search_candidates
from .results import ReportOutcome


def fit_report_models(campaign: Campaign, out: Path, options: FitOptions, *, jobs: int = 1,
                      diagnose: str | None = "Cm", models: tuple[str, ...] = (), progress: Progress = None):
    """The :class:`~structsearch.reporting.page.ReportFits` of a report in ``out`` (the search's winners in
    ``out/ranking.csv`` or ``models``; fits cached under ``out/cache``)."""
    from ..diagnosis.diagnose import diagnose as run_diagnosis
    from ..flight.reference import VAN_INGEN_MODEL_NAMES
    from ..reporting.page import ReportFits, applicable_models, best_effect, chosen_models
    from ..thesis_study.model_set import fit_model_set, fit_with_effect
    say = progress or (lambda m: None)
    names, notes = chosen_models(out, models)
    names, more = applicable_models(names, campaign)
    notes += more
    say(f"report: fitting {', '.join(names.values())} and the Van Ingen structures")
    identified = fit_model_set("identified", names, campaign, out, options, n_jobs=jobs)
    try:
        van_ingen = fit_model_set("Van Ingen", VAN_INGEN_MODEL_NAMES, campaign, out, options, n_jobs=jobs)
    except (DeclarationError, DataError) as exc:  # e.g. a column the campaign lacks
        van_ingen = None
        notes.append(f"The Van Ingen comparison is left out: {exc}")
    diagnosis = effect = None
    if diagnose:
        say(f"report: diagnosing {names[diagnose]}")
        diagnosis = run_diagnosis(campaign, identified.candidates[diagnose], options=options, max_rounds=1,
                                  states=False, n_jobs=jobs)
        best = best_effect(diagnosis)
        if best is not None:
            effect = (best, *fit_with_effect(identified, diagnose, best, campaign, out, options))
    return ReportFits(names, tuple(notes), identified, van_ingen, diagnose, diagnosis, effect)


def report(campaign: Campaign | str | os.PathLike, out: str | os.PathLike = "results", *, starts: int = 4,
           seed: int = 0, covariance: str = DEFAULT_COVARIANCE, bounds: Bounds = None, jobs: int = 0,
           diagnose: str | None = "Cm", models: tuple[str, ...] = (), story: list[str] | None = None,
           progress: Progress = None, segment: str | None = None) -> ReportOutcome:
    """Figures and one self-contained HTML page for a campaign, as ``structsearch report`` writes them in
    ``out`` (``diagnose=None``: no gap breakdown). Needs matplotlib."""
    from ..reporting.page import build, require_figures
    started = time.perf_counter()
    campaign = as_campaign(campaign, segment)
    options = fit_options(starts, seed, covariance, bounds, campaign)
    check_box_names(options.parameter_boxes, search_candidates("all"))
    require_figures()
    out = Path(out)
    fits = fit_report_models(campaign, out, options, jobs=process_count(jobs), diagnose=diagnose,
                             models=tuple(models), progress=progress)
    res = build(campaign, out, fits, options=options, story=story)
    return ReportOutcome(res["html"], res["figures"], res["notes"], time.perf_counter() - started)
