"""``report``: the fits a campaign report shows (the identified and the Van Ingen model sets, a diagnosis and its
best effect), then the page (:func:`structsearch.reporting.page.build`, which fits nothing)."""
from __future__ import annotations

import os
import time
from pathlib import Path

from ..data.campaign import Campaign
from ..data.errors import DataError, DeclarationError
from ..fitting.fitter import Fitter
from ..fitting.options import check_box_names
from .commands import as_campaign, search_candidates
from .settings import Settings, command_fitter, fit_options
from .results import ReportOutcome


def fit_report_models(fitter: Fitter, out: Path, *, diagnose: str | None = "Cm", models: tuple[str, ...] = ()):
    """The :class:`~structsearch.reporting.page.ReportFits` of a report in ``out`` (the search's winners in
    ``out/ranking.csv`` or ``models``; fitted with ``fitter``)."""
    from ..diagnosis.diagnose import diagnose as run_diagnosis
    from ..flight.reference import VAN_INGEN_MODEL_NAMES
    from ..reporting.page import ReportFits, applicable_models, best_effect, chosen_models
    from ..thesis_study.model_set import fit_model_set, fit_with_effect
    say, campaign = fitter.say, fitter.campaign
    quiet = fitter.quiet()
    names, notes = chosen_models(out, models)
    names, more = applicable_models(names, campaign)
    notes += more
    say(f"report: fitting {', '.join(names.values())} and the Van Ingen structures")
    identified = fit_model_set("identified", names, quiet)
    try:
        van_ingen = fit_model_set("Van Ingen", VAN_INGEN_MODEL_NAMES, quiet)
    except (DeclarationError, DataError) as exc:  # e.g. a column the campaign lacks
        van_ingen = None
        notes.append(f"The Van Ingen comparison is left out: {exc}")
    diagnosis = effect = None
    if diagnose:
        say(f"report: diagnosing {names[diagnose]}")
        # the report's own options (not the diagnose command's): its cache serves the baseline fitted above
        diagnosis = run_diagnosis(quiet, identified.candidates[diagnose], max_rounds=1, states=False)
        best = best_effect(diagnosis)
        if best is not None:
            effect = (best, *fit_with_effect(identified, diagnose, best, quiet))
    return ReportFits(names, tuple(notes), identified, van_ingen, diagnose, diagnosis, effect)


def report(campaign: Campaign | str | os.PathLike, out: str | os.PathLike = "results", *,
           settings: Settings = Settings(), diagnose: str | None = "Cm", models: tuple[str, ...] = (),
           story: list[str] | None = None) -> ReportOutcome:
    """Figures and one self-contained HTML page for a campaign, as ``structsearch report`` writes them in
    ``out`` (``diagnose=None``: no gap breakdown); fits are cached under ``settings.cache`` (default ``out``).
    Needs matplotlib."""
    from ..reporting.page import build, require_figures
    started = time.perf_counter()
    campaign = as_campaign(campaign, settings.segment)
    options = fit_options("report", settings, campaign)
    check_box_names(options.parameter_boxes, search_candidates("all"))
    require_figures()
    out = Path(out)
    with command_fitter("report", campaign, settings, out) as fitter:
        fits = fit_report_models(fitter, out, diagnose=diagnose, models=tuple(models))
    res = build(campaign, out, fits, options=options, story=story)
    return ReportOutcome(res["html"], res["figures"], res["notes"], time.perf_counter() - started)
