"""Issue 43: the report opens with the answer (the user's search's rank-1 structure of each coefficient, with its
numbers and its validation R^2), resolves the search's refined structures and never swaps in the thesis' final
structures; its tables print numbers to their digits and no "nan" without a reason."""
import re
from html.parser import HTMLParser

import numpy as np
import pytest
from conftest import fitter_for

from structsearch.data.campaign import read_campaign, write_campaign
from structsearch.fitting.options import FitOptions
from structsearch.fitting.specs import find_candidate
from structsearch.flight.flighttest import build_campaign
from structsearch.grid_search.refinement import _refined


class _Text(HTMLParser):
    """The text a browser shows: no tags, no head (its title), scripts or styles."""

    def __init__(self):
        super().__init__()
        self.parts, self.hidden = [], 0

    def handle_starttag(self, tag, attrs):
        self.hidden += tag in ("head", "script", "style")

    def handle_endtag(self, tag):
        self.hidden -= tag in ("head", "script", "style")

    def handle_data(self, data):
        if not self.hidden:
            self.parts.append(data)


def visible_text(page: str) -> str:
    parser = _Text()
    parser.feed(page)
    return " ".join(" ".join(parser.parts).split())


# A search whose winners are not the thesis' finals (CL-VI, CD-IXr, Cm-XXXIIIr): a lift winner other than the
# lift model the drag and pitch winners read, and a pitch winner the refinement reached.
REFINED = _refined(find_candidate("Cm-XXXI"), ["Cm_qstar"], "r-auto")
RANKING = ("grid,model,rank,lift\nlift,CL-II,1,-\nlift,CL-VI,2,-\ndrag,CD-IX,1,CL-VI\n"
           f"pitch,{REFINED.name},1,CL-VI\npitch,Cm-XXXI,2,CL-VI\n")


@pytest.fixture(scope="module")
def page_of_a_search(tmp_path_factory):
    """The page (without its figures: they cost most and say nothing of the choice) of a report on a campaign
    whose ranking is RANKING."""
    from structsearch.api.report import fit_report_models
    from structsearch.reporting.page_html import render_html
    from structsearch.reporting.refined import write_refined
    root = tmp_path_factory.mktemp("search")
    write_campaign(build_campaign(seed=3, scale=0.05), root / "c")
    campaign = read_campaign(root / "c")
    out = root / "out"
    out.mkdir()
    (out / "ranking.csv").write_text(RANKING)
    write_refined(out, {"pitch": [REFINED]})
    fitter = fitter_for(campaign, out / "cache", FitOptions(n_starts=1, cv_folds=0))
    fits = fit_report_models(fitter, out, diagnose=None)
    page = render_html(campaign, out, fits, fits.identified, fits.van_ingen, [], list(fits.notes), None)
    return fits, page


def test_the_first_screen_names_the_searchs_winners(page_of_a_search):
    fits, page = page_of_a_search
    first = visible_text(page)[:1000]
    for name in ("CL-II", "CD-IX", REFINED.name):
        assert name in first
    assert "CL-VI" not in first.split("CD-IX")[0]   # the lift answer is the lift winner, not its states' model
    assert "CD-IXr" not in first and "Cm-XXXIIIr" not in first
    assert "validation R^2" in first
    r2 = fits.answers["CL"][1].validation.r2.pooled
    assert f"{r2:.4g}" in first
    # the pitch winner is shown with the lift model it reads (fitted too), and a note says so
    assert fits.answers["Cm"][0] == REFINED and fits.answers["Cm"][2].name == "CL-VI"
    assert "takes its separation states from CL-VI" in page


def test_the_answer_writes_equations_rounded_to_their_uncertainty(page_of_a_search):
    fits, page = page_of_a_search
    text = visible_text(page)
    assert "CL = (" in text and " ± " in text
    # no estimate with more digits than its standard deviation carries
    for est, sd in re.findall(r"\((-?[\d.]+) ± ([\d.]+)\)", text):
        assert len(est.split(".")[-1]) == len(sd.split(".")[-1]) if "." in sd else "." not in est
    assert not re.search(r"\d\.\d{9,}", visible_text(page))


def test_numbers_round_to_their_uncertainty():
    from structsearch.reporting.numbers import estimate_text, share
    assert estimate_text(0.123456, 0.00346) == "0.1235 ± 0.0035"
    assert estimate_text(12345.6, 123.0) == "12350 ± 120"
    assert estimate_text(-0.000012345, 0.0000031) == "-1.23e-5 ± 0.31e-5"
    assert estimate_text(1.5, float("nan")) == "1.5"
    assert estimate_text(-0.0001, 0.5) == "0.00 ± 0.50"
    assert share(-0.001) == "< 0.5%" and share(0.0) == "0%" and share(-0.5, signed=True) == "-50%"
    assert share(0.25, signed=True) == "+25%"


def test_no_doubled_words_or_minus_zero_in_figure_titles():
    from structsearch.reporting.figures import after_move, gap_change_words, gap_titles
    assert after_move("add Cm_K21_ss = K2(X_ss, 1)") == "after add Cm_K21_ss = K2(X_ss, 1)"
    assert after_move("Cm_K21_ss") == "after adding Cm_K21_ss"
    g = {"baseline": "Cm-X", "model": "Cm-X + add Cm_KS_ss = KS(X_ss)", "mse_before": 1.5e-4, "mse_after": 1.4e-4}
    for title in gap_titles(g, "add Cm_KS_ss = KS(X_ss)") + gap_titles({**g, "model": "Cm-Y"}, "Cm_KS_ss"):
        assert not re.search(r"\b(\w+) \1\b", title) and "adding add" not in title
        assert title.count("add") <= 1
    before = np.array([[1.0, 2.0], [np.nan, 4.0]])
    for after in (before * (1 - 1e-4), before * (1 + 1e-4), before):
        words = gap_change_words(before, after)
        assert "-0%" not in words and "+0%" not in words


def _diagnosis(at_floor: bool):
    """A diagnosis made by hand whose baseline is at the noise floor (every share of the gap undefined) or not,
    with one failed move."""
    from structsearch.diagnosis.results import Diagnosis, EffectRow, Round, TrainValidation, Unexplained
    mse = 1.0 if at_floor else 2.0
    effects = (EffectRow("add a = alpha", None, 0.99 * mse, 0.99 * mse, None, 0.5, {"phase": "stall"}, False, "m + a"),
               EffectRow("add b = q", error="fitting b failed: singular"))
    first = Round("Cm-X", TrainValidation(mse, mse), 1.0, "saturated library model", 1.0, 0.1, (), effects,
                  at_floor, 0.0, 0.01, None, None, 1.0, mse - 1.0)
    return Diagnosis(coefficient="Cm", baseline="Cm-X", noise_floor=1.0, floor_source="saturated library model",
                     noise_floor_library=1.0, explained=at_floor, final_excess_over_floor=0.0, final_excess_se=0.01,
                     rounds=(first,), final_model="Cm-X", final_mse=mse,
                     unexplained=Unexplained(None if at_floor else 1.0, 0, 0.0), seconds=1.0)


@pytest.mark.parametrize("at_floor", [True, False])
def test_no_nan_in_the_diagnosis_table_without_its_reason(at_floor):
    from structsearch.reporting.answer import gap_story
    from structsearch.reporting.page_html import diagnosis_html
    d = _diagnosis(at_floor)
    text = visible_text(diagnosis_html(d.to_dict()))
    assert "nan" not in text.lower()
    assert "fitting b failed: singular" in text and "not estimable" in text
    assert ("no gap for a move to close" in text) == at_floor
    story = gap_story(d)
    assert len(story) == 3 and not any("nan" in line.lower() or "-0%" in line for line in story)


def test_a_refined_spec_round_trips_and_a_tampered_one_is_refused(tmp_path):
    """The search writes the structures its refinement reached (refined_<grid>.toml, listed in its manifest);
    they read back as the same candidates, and a file changed since is refused, naming it."""
    from structsearch.api.commands import refined_structures
    from structsearch.api.results import Ranking
    from structsearch.data.errors import StructSearchError
    from structsearch.grid_search.refinement import Refinement
    from structsearch.reporting.refined import load_refined
    from structsearch.reporting.tables import write_tables
    lift = _refined(find_candidate("CL-VI"), ["CL0"], "r-auto")
    simpler = _refined(find_candidate("CL-I"), [], "r-auto", {"": "Q"})
    pitch = [REFINED, _refined(find_candidate("Cm-XXXI"), ["Cm_qstar", "Cm_CT"], "r2-auto")]
    steps = {"lift": [Refinement("CL-VI", ((lift, None),), "done"), Refinement("CL-I", ((simpler, None),), "d")],
             "pitch": [Refinement("Cm-XXXI", tuple((c, None) for c in pitch), "done")]}
    write_tables({}, tmp_path, None, refined_structures(Ranking({}, {}, steps)))
    assert load_refined(tmp_path) == {c.name: c for c in [lift, simpler] + pitch}
    assert "refined_pitch.toml" in (tmp_path / "search_manifest.json").read_text()
    path = tmp_path / "refined_pitch.toml"
    path.write_text(path.read_text().replace('"Cm_CT" = "CT"', '"Cm_CT" = "__import__(os)"'))
    with pytest.raises(StructSearchError, match="refined_pitch.toml"):
        load_refined(tmp_path)
    (tmp_path / "search_manifest.json").unlink()   # no manifest: the file is still parsed, never evaluated
    with pytest.raises(StructSearchError, match="refined_pitch.toml"):
        load_refined(tmp_path)


@pytest.mark.slow
def test_a_report_after_a_search_opens_with_its_winners(tmp_path):
    """End to end: simulate, search every grid, report; the first screen names each grid's rank-1 structure (on a
    small campaign they are refined ones and not the thesis' finals) and the refined ones resolve as themselves."""
    import csv
    from test_report_cli import run_cli
    data, out = tmp_path / "c", tmp_path / "out"
    assert run_cli("simulate", "--out", str(data), "--seed", "3", "--scale", "0.05").returncode == 0
    proc = run_cli("search", "--data", str(data), "--grid", "all", "--starts", "1", "--out", str(out), "--quiet")
    assert proc.returncode == 0, proc.stderr
    winners = {r["grid"]: r["model"] for r in csv.DictReader((out / "ranking.csv").open()) if r["rank"] == "1"}
    proc = run_cli("report", "--data", str(data), "--out", str(out), "--starts", "1", "--diagnose", "none",
                   "--quiet")
    assert proc.returncode == 0, proc.stderr
    first = visible_text((out / "report.html").read_text())[:1000]
    for grid in ("lift", "drag", "pitch"):
        assert winners[grid] in first, (grid, winners[grid], first)
    assert "the report shows the final structures" not in proc.stdout


def test_the_first_screen_gives_every_coefficients_verdict_and_simulator_gap():
    """Each coefficient's row carries the search's verdict and, where the demo's story diagnosed the simulator's
    model, its gap story; the title reads "identified models" only when every coefficient has an answer."""
    from types import SimpleNamespace

    from structsearch.reporting.answer import answer_html, verdict_text
    from structsearch.reporting.page_html import page_title
    near = {"status": "admissible", "tolerance": 0.25, "best_fit": "A", "best_admissible": "B", "cost": 0.1,
            "best_fit_reasons": ["x"]}
    far = {"status": "none_admissible_near", "tolerance": 0.25, "best_fit": "A", "best_admissible": "B",
           "cost": 1.137, "best_fit_reasons": ["Kirchhoff term CL_KL_w = -4.14 is not positive"]}
    assert verdict_text(near) == "Admissible (+10.0 % above the best fit A, within 25 %)."
    text = verdict_text(far)
    assert text.startswith("No admissible structure within 25 % of the best fit. The best fit, A, is not admissible")
    assert "CL_KL_w = -4.14" in text and "B, fits +113.7 % worse" in text and "not an answer" in text
    assert page_title({"CL": near, "CD": near}) == "identified models"
    assert page_title({"CL": far, "CD": near}) == "search results, no admissible structure near the best fit for CL"
    # a lift-only search shown beside the thesis' drag and pitch: they have no verdict, and the title says so
    assert page_title({"CL": near}, ["CL", "CD", "Cm"]) == "search results, CD, Cm shown without a search's verdict"
    assert page_title({"CL": near, "CD": near, "Cm": near}, ["CL", "CD", "Cm"]) == "identified models"
    # a row per coefficient: the verdict, then the simulator's gap where a story diagnosed it
    c = find_candidate("CL-I")
    result = SimpleNamespace(estimates=SimpleNamespace(params={}, stderr={}, names=()), comparison=SimpleNamespace(mse=1.0),
                             validation=SimpleNamespace(r2=SimpleNamespace(pooled=0.9, mean=0.9, min=0.8)), cv=None,
                             mse_validation=1.0, n_params=7)
    page = visible_text(answer_html({"CL": (c, result, None)}, "ranked first", None, None, {"CL": far},
                                    {"CL": _diagnosis(False)}))
    assert "The models shown" in page and "No admissible structure within 25 %" in page
    assert "The simulator's gap: its model Cm-X against the flight data." in page and "Where it misses" in page


def test_a_value_and_its_deviation_never_wrap_apart_nor_a_number_inside_a_cell():
    """Equations wrap between terms, never inside one ("(estimate ± std. dev.)*factor", a factor with spaces of
    its own such as "(1 - X_ss)*CL"); table cells break only a word that cannot fit its column (a number keeps
    its digits together)."""
    from structsearch.reporting.answer import _unbroken
    from structsearch.reporting.page_html import STYLE
    text = _unbroken("CD = (0.0204 ± 0.0027)*CL**2 + (-1.2e-5 ± 0.3e-5)*alpha")
    assert text == ("<span class='value'>CD = (0.0204 ± 0.0027)*CL**2</span> + "
                    "<span class='value'>(-1.2e-5 ± 0.3e-5)*alpha</span>")
    text = _unbroken("Cm = (0.1 ± 0.01) - (0.05 ± 0.01)*(1 - X_ss)*CL\ndX/dt = (X0(alpha - tau2*alpha_dot) - X)/tau1")
    assert "<span class='value'>(0.05 ± 0.01)*(1 - X_ss)*CL</span>" in text and text.count("\n") == 1
    assert "<span class='value'>dX/dt = (X0(alpha - tau2*alpha_dot) - X)/tau1</span>" in text
    assert ".value{white-space:nowrap}" in STYLE and "overflow-wrap:anywhere" not in STYLE


def test_the_equations_are_mathematics_on_the_page_with_nothing_fetched():
    """Each answer's equations as MathML (a browser renders it offline), one block per equation of the structure,
    without a namespace address; the text equations with the estimates stay below it."""
    pytest.importorskip("latex2mathml")
    from structsearch.reporting.answer import mathml
    from structsearch.reporting.equations import latex_equations
    c = find_candidate("CL-VI")
    block = mathml(c)
    assert block.startswith("<div class='math'>") and block.count("<math display=\"block\">") == len(latex_equations(c))
    assert "http" not in block and "<msub><mi>C</mi><mi>L</mi></msub>" in block


def test_the_first_screen_names_the_effects_adopted_never_one_that_costs():
    """A look-ahead move listed first in round 1 that raises the validation MSE (closes -23 % of the gap), and an
    effect adopted in round 2 that closes most of it: the gap story's line names the adopted effect with its share
    of the first round's gap, and not the move that costs."""
    from structsearch.diagnosis.results import Diagnosis, EffectRow, Round, TrainValidation, Unexplained
    from structsearch.reporting.answer import gap_story
    floor = 1.0
    ahead = EffectRow("lift CL-I -> CL-story", None, 2.23, 2.23, None, 1.0, {}, False, "m + lift")
    cheap = EffectRow("second_state", None, 1.5, 1.5, None, 1e-9, {}, False, "m + state")
    shift = EffectRow("cp_shift", None, 1.27, 1.27, None, 1e-9, {}, False, "m + state + cp")
    first = Round("Cm-I", TrainValidation(2.0, 2.0), floor, "saturated", floor, 0.1, (), (ahead, cheap), False, 1.0,
                  0.1, 1e-9, "second_state", floor, 1.0)
    second = Round("Cm-I + second_state", TrainValidation(1.5, 1.5), floor, "saturated", floor, 0.1, (), (shift,),
                   False, 0.5, 0.1, 1e-9, "cp_shift", floor, 0.5)
    d = Diagnosis(coefficient="Cm", baseline="Cm-I", noise_floor=floor, floor_source="saturated",
                  noise_floor_library=floor, explained=False, final_excess_over_floor=0.27, final_excess_se=0.05,
                  rounds=(first, second), final_model="Cm-I + cp", final_mse=1.27,
                  unexplained=Unexplained(0.27, 0, 0.0), seconds=1.0)
    line = gap_story(d)[1]
    assert line == "Which effect: adopted second_state (closes 50% of the gap), then cp_shift (closes 23% of the gap)."
    assert "CL-story" not in line


def test_a_report_beside_the_demos_story_gives_its_gaps_on_the_first_screen(tmp_path, monkeypatch):
    """``structsearch report`` of the demo's campaign (OUT/campaign) reads the story the demo wrote beside the
    ranking: every coefficient the story diagnosed gets its gap on the first screen (before, only the demo's own call passed them, and a
    report made afterwards said "Gap story: not diagnosed in this report" for C_L and C_D). A story.json that is
    not the demo's is one error naming the file."""
    import json
    import shutil
    from pathlib import Path

    import importlib

    import structsearch.reporting.page as page
    api_report = importlib.import_module("structsearch.api.report")   # the package names the function report
    from structsearch.data.errors import DataError
    results = Path(__file__).resolve().parents[1] / "results"
    shutil.copy(results / "story.json", tmp_path / "story.json")
    (tmp_path / "ranking.csv").write_text("grid,name\n")   # the report does not search: a ranking is there
    lines, gaps = api_report.read_story_gaps(tmp_path)
    assert sorted(gaps) == ["CD", "CL", "Cm"] and lines == json.loads((results / "story.json").read_text())["lines"]
    built = {}

    def build(campaign, out, fits, options=None, story=None, gaps=None):
        built.update(story=story, gaps=gaps)
        return {"html": out / "report.html", "figures": [], "notes": []}
    monkeypatch.setattr(page, "build", build)
    monkeypatch.setattr(page, "require_figures", lambda: None)
    monkeypatch.setattr(api_report, "fit_report_models", lambda *a, **k: None)
    write_campaign(build_campaign(seed=3, scale=0.05), tmp_path / "campaign")
    outcome = api_report.report(read_campaign(tmp_path / "campaign"), tmp_path)
    assert sorted(built["gaps"]) == ["CD", "CL", "Cm"] and built["story"] == lines
    assert any("story.json" in note for note in outcome.notes)
    # a report of another campaign made in that folder does not show the demo's story (it is of other data)
    write_campaign(build_campaign(seed=4, scale=0.05), tmp_path / "other")
    built.clear()
    outcome = api_report.report(read_campaign(tmp_path / "other"), tmp_path)
    assert built["gaps"] is None and not any("story.json" in note for note in outcome.notes)
    (tmp_path / "story.json").write_text('{"lines": [], "diagnoses": {"CL": {"coefficient": 3}}}')
    with pytest.raises(DataError, match="story.json.*not a story written by the demo"):
        api_report.read_story_gaps(tmp_path)
