"""``report``: the fits a campaign report shows (the structures the user's search ranked first, fitted as a
consistent set for the figures and each on its own lift model for the answer; the Van Ingen model set; a
diagnosis and its best effect), then the page (:func:`structsearch.reporting.page.build`, which fits nothing).
With neither a search ranking in the output directory nor ``models``, the report runs the search first (with its
own settings) so that what it shows is the winners on this campaign, never the thesis' structures by default."""
from __future__ import annotations

import os
import time
from pathlib import Path

from ..data.campaign import Campaign
from ..data.coefficients import coefficient
from ..data.errors import DataError, DeclarationError
from ..fitting.fitter import Fitter
from ..fitting.lift_fit import LiftFit
from ..fitting.options import check_box_names
from .commands import search, search_candidates
from .settings import as_campaign
from .settings import Settings, command_fitter, fit_options
from .results import ReportOutcome


def fit_report_models(fitter: Fitter, out: Path, *, diagnose: str | None = "Cm", models: tuple[str, ...] = (),
                      searched: str | None = None):
    """The :class:`~structsearch.reporting.page.ReportFits` of a report in ``out`` (the search's winners in
    ``out/ranking.csv`` or ``models``; fitted with ``fitter``)."""
    from ..diagnosis.diagnose import DIAGNOSE, diagnose as run_diagnosis
    from ..flight.reference import VAN_INGEN_MODEL_NAMES
    from ..reporting.page import ReportFits, best_effect
    from ..reporting.choice import chosen_models
    from ..thesis_study.model_set import fit_model_set, fit_with_effect
    say, campaign = fitter.say, fitter.campaign
    quiet = fitter.quiet()
    choice = chosen_models(out, models, searched, campaign)
    notes = list(choice.notes)
    if set(choice.winners) != {"CL", "CD", "Cm"}:   # no set to draw: the first screen and the rankings only
        say(f"report: fitting {', '.join(c.name for c in choice.winners.values())}")
        return ReportFits(choice.names, tuple(notes), None, None, answers=answer_fits(quiet, choice, None),
                          source=choice.source, verdicts=choice.verdicts)
    say(f"report: fitting {', '.join(c.name for c in choice.shown.values())} and the Van Ingen structures")
    identified = fit_model_set("identified", choice.shown, quiet)
    answers = answer_fits(quiet, choice, identified)
    try:
        van_ingen = fit_model_set("Van Ingen", VAN_INGEN_MODEL_NAMES, quiet)
    except (DeclarationError, DataError) as exc:  # e.g. a column the campaign lacks
        van_ingen = None
        notes.append(f"The Van Ingen comparison is left out: {exc}")
    diagnosis = effect = None
    if diagnose:
        say(f"report: diagnosing {choice.shown[diagnose].name}")
        # the report's own options (not the diagnose command's): its cache serves the baseline fitted above
        diagnosis = run_diagnosis(quiet, identified.candidates[diagnose], DIAGNOSE.but(max_rounds=1, state_level=False))
        best = best_effect(diagnosis)
        if best is not None:
            effect = (best, *fit_with_effect(identified, diagnose, best, quiet))
    return ReportFits(choice.names, tuple(notes), identified, van_ingen, diagnose, diagnosis, effect,
                      answers=answers, source=choice.source, verdicts=choice.verdicts)


def answer_fits(fitter: Fitter, choice, identified) -> dict:
    """Each coefficient's winner with its fit and the lift fit whose states it reads: (candidate, result, lift)
    (lift None for the lift winner). A winner the figures' set holds is not fitted again."""
    out = {}
    for coef, c in choice.winners.items():
        if identified is not None and identified.candidates[coef] == c:
            out[coef] = (c, identified.summaries[coef], None if coefficient(coef).owns_states else identified.lift)
            continue
        if coefficient(coef).owns_states:
            result, lift = fitter.fit_one(c), None
        else:
            lift_c = choice.lifts[coef]
            lift = (identified.lift if identified is not None and identified.candidates["CL"] == lift_c
                    else LiftFit(lift_c, fitter.fit_one(lift_c)))
            result = fitter.with_lifts({lift_c.name: lift}).fit_one(c)
        if result.failed:
            raise DeclarationError(f"report: fitting {c.name} failed: {result.error}")
        out[coef] = (c, result, lift)
    return out


def report(campaign: Campaign | str | os.PathLike, out: str | os.PathLike = "results", *,
           settings: Settings = Settings(), diagnose: str | None = "Cm", models: tuple[str, ...] = (),
           story: list[str] | None = None, gaps=None) -> ReportOutcome:
    """Figures and one self-contained HTML page for a campaign, as ``structsearch report`` writes them in
    ``out`` (``diagnose=None``: no gap breakdown); fits are cached under ``settings.cache`` (default ``out``).
    Without ``out/ranking.csv`` and ``models``, the search runs first (writing its ranking to ``out``).
    ``gaps``: per coefficient a diagnosis of the simulator's model (the demo's story), whose gap story the first
    screen gives.
    Needs matplotlib."""
    from ..reporting.page import build, require_figures
    started = time.perf_counter()
    campaign = as_campaign(campaign, settings.segment, settings.reference_point)
    options = fit_options("report", settings, campaign)
    check_box_names(options.parameter_boxes, search_candidates("all"))
    require_figures()
    out = Path(out)
    searched = None
    if not models and not (out / "ranking.csv").exists():
        search(campaign, "all", settings=settings, out=out)
        searched = f"ranked first by the search this report ran (its settings; ranking in {out / 'ranking.csv'})"
    with command_fitter("report", campaign, settings, out) as fitter:
        fits = fit_report_models(fitter, out, diagnose=diagnose, models=tuple(models), searched=searched)
    read_story = None
    # the demo's story, when this report is of the demo's own campaign (OUT/campaign): its first screen gives the
    # gaps; a story beside another campaign is of other data and is not shown
    if gaps is None and story is None and campaign.directory is not None \
            and Path(campaign.directory).resolve() == (out / "campaign").resolve():
        read_story = read_story_gaps(out)
        if read_story is not None:
            story, gaps = read_story
    res = build(campaign, out, fits, options=options, story=story, gaps=gaps)
    notes = list(res["notes"]) + ([f"the simulator's gap story is read from {out / 'story.json'} (written by the "
                                   "demo for this campaign)"] if read_story is not None else [])
    return ReportOutcome(res["html"], res["figures"], notes, time.perf_counter() - started)


def read_story_gaps(out: Path):
    """The story's lines and diagnoses (coefficient -> Diagnosis) from ``out/story.json``, or None without one; a
    story.json that is not the demo's document is one error naming the file."""
    from ..data.reading import inside, load_json
    from ..diagnosis.results import Diagnosis
    path = Path(out) / "story.json"
    if not path.exists():
        return None
    doc = load_json(inside(out, "story.json", str(path)))
    try:
        lines = [str(line) for line in doc["lines"]]
        gaps = {str(c): Diagnosis.from_dict(d) for c, d in doc["diagnoses"].items()}
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise DataError(f"not a story written by the demo ({type(exc).__name__}: {exc})", source=str(path)) from None
    return lines, gaps
