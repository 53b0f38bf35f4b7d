"""The demo's orchestration (``structsearch demo``): simulate the default campaign (or reuse it), search every
grid, write the tables, tell the Van Ingen story, compute the thesis' comparison tables and write the report.
Prints nothing: ``say`` receives the lines the command prints on stdout, ``progress`` those on stderr."""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from .api.commands import write_search_tables
from .api.results import Ranking, ReportOutcome
from .data.campaign import Campaign
from .diagnosis.story import Story
from .fitting.fitter import Meter
from .grid_search.admissibility import MAX_CORRELATION

Lines = Callable[[str], None]


def simulated_as(directory: Path) -> dict | None:
    """How the campaign in ``directory`` was simulated (seed, scale, ...), or None if there is none."""
    from .data.errors import StructSearchError
    from .data.reading import load_toml
    toml = directory / "campaign.toml"
    if not toml.exists():
        return None
    try:
        doc = load_toml(toml)
    except StructSearchError:
        return {"manifest": "unreadable"}
    return {k: doc.get(k) for k in ("seed", "scale", "withheld", "slow_errors", "extras", "flights")}


@dataclass(frozen=True)
class DemoOutcome:
    """What the demo made: the campaign, the search, the story, the study and the report (None without
    matplotlib), and the seconds each stage took."""

    out: Path
    campaign: Campaign
    ranking: Ranking
    story: Story                    # the Van Ingen story
    story_markdown: Path
    study_files: list[Path]
    report: ReportOutcome | None
    seconds: dict[str, float]

    def to_dict(self) -> dict:
        return {"out": str(self.out), "ranking": self.ranking.to_dict(), "story": self.story.to_dict(),
                "study_files": [str(p) for p in self.study_files],
                "report": None if self.report is None else self.report.to_dict(), "seconds": dict(self.seconds)}


def demo_campaign(out: Path, scale: float, say: Lines) -> Campaign:
    """The demo's campaign (seed 0 at ``scale``) in ``out/campaign``: reused when it was simulated so, else
    simulated again."""
    from .data.campaign import read_campaign, write_campaign
    from .flight.flighttest import build_campaign
    camp_dir = out / "campaign"
    wanted = {"seed": 0, "scale": float(scale), "withheld": "none", "slow_errors": 1.0, "extras": False,
              "flights": None}
    found = simulated_as(camp_dir)
    if found == wanted:
        say(f"reusing the simulated campaign in {camp_dir}")
        return read_campaign(camp_dir)
    if found is not None:
        say(f"{camp_dir} holds another campaign ({', '.join(f'{k} = {v}' for k, v in found.items())}); "
            "simulating it again")
    say(f"simulating the default flight-test campaign (seed 0, scale {scale}) ...")
    write_campaign(build_campaign(seed=0, scale=scale), camp_dir)
    return read_campaign(camp_dir)


def demo(out: str | Path = "results", *, jobs: int = 0, starts: int = 4, scale: float = 1.0,
         max_correlation: float = MAX_CORRELATION, say: Lines | None = None,
         winners: Callable[[Ranking], None] | None = None, progress: Lines | None = None,
         meter: Meter | None = None) -> DemoOutcome:
    """``structsearch demo``: every artefact in ``out``. ``winners`` is called with the search's ranking when it
    is done (the command prints each grid's winner there); ``meter`` is told of every candidate fitted (the
    command's progress bar). Over earlier results (a checkout's committed ``results/``) the files whose answers
    are the same are kept byte for byte and one line says so (:mod:`structsearch.experiments.unchanged`)."""
    from .experiments.unchanged import keep_unchanged, restore, snapshot
    aside = snapshot(Path(out))
    try:
        outcome = _demo(Path(out), jobs=jobs, starts=starts, scale=scale, max_correlation=max_correlation,
                        say=say or (lambda m: None), winners=winners, progress=progress, meter=meter)
    except BaseException:
        if aside is not None:   # interrupted or failed: the earlier results go back, the copy goes
            import shutil
            try:
                restore(Path(out), aside)
            finally:
                shutil.rmtree(aside, ignore_errors=True)
        raise
    if aside is not None:
        (say or (lambda m: None))(keep_unchanged(Path(out), aside).line(Path(out)))
    return outcome


def _demo(out: Path, *, jobs: int, starts: int, scale: float, max_correlation: float, say: Lines,
          winners: Callable[[Ranking], None] | None, progress: Lines | None, meter: Meter | None) -> DemoOutcome:
    """The demo's run (:func:`demo`), every file written into ``out``."""
    from .api.settings import Settings, command_fitter
    from .diagnosis.story import console_lines, van_ingen_story
    from .reporting import figures
    from .reporting.diagnosis_doc import write_story
    from .reporting.study_doc import write as write_study
    from .grid_search.pipeline import search
    from .thesis_study.study import run_study
    t0 = time.perf_counter()
    campaign = demo_campaign(out, scale, say)
    t_sim = time.perf_counter() - t0
    settings = Settings(starts=starts, jobs=jobs, progress=progress, meter=meter)
    n_jobs = settings.processes
    with command_fitter("demo", campaign, settings, out) as fitter:
        result = search(fitter, "all", max_correlation=max_correlation)
    ranking = Ranking(result.grids, result.seconds, result.refinements)
    write_search_tables(ranking, campaign, out)
    total = time.perf_counter() - t0
    if winners is not None:
        winners(ranking)
    say(f"campaign: {len(campaign.maneuvers)} maneuvers, {campaign.data.n_samples} samples "
        f"({t_sim:.0f} s); search of {sum(len(r) for r in result.grids.values())} candidates on {n_jobs} "
        f"process(es): {total - t_sim:.0f} s; total {total:.0f} s")
    say(f"tables and ranking.csv in {out}")
    t1 = time.perf_counter()
    # the story's diagnoses use the diagnose command's defaults (2 starts), not the search's --starts
    with command_fitter("diagnose", campaign, Settings(jobs=jobs, progress=progress, meter=meter), out) as fitter:
        story = van_ingen_story(fitter)
    _, story_md = write_story(story, out, f"structsearch demo --out {out}"
                              + (f" --scale {scale:g}" if scale != 1.0 else ""))
    t_story = time.perf_counter() - t1
    say(f"the story, Van Ingen's simulator model against the flight data ({t_story:.0f} s; {story_md}):")
    for line in console_lines(story):   # short, a line a round (story.md has the story's long lines)
        say(f"  {line}")
    t2 = time.perf_counter()
    with command_fitter("study", campaign, settings, out) as fitter:
        study = run_study(fitter)
    written = write_study(study, out / "study", f"structsearch study --data {out / 'campaign'} --out "
                          f"{out / 'study'} --cache {out}" + (f" --starts {starts}" if starts != 4 else ""),
                          figures=figures.plt is not None)
    t_study = time.perf_counter() - t2
    say(f"the thesis' comparison tables: {len(written)} files in {out / 'study'} ({t_study:.0f} s)")
    seconds = {"simulate": t_sim, "search": total - t_sim, "story": t_story, "study": t_study}
    if figures.plt is None:
        say("no figures: the report needs matplotlib (pip install 'structsearch[figures]')")
        return DemoOutcome(out, campaign, ranking, story, story_md, written, None, seconds)
    from .api.report import report
    page = report(campaign, out, settings=settings, story=list(story.lines), gaps=story.diagnoses)
    seconds["report"] = page.seconds
    return DemoOutcome(out, campaign, ranking, story, story_md, written, page, seconds)
