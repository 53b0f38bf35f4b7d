"""What a user reads is true: the getting-started page describes the pitch winner as its spec declares it, a
one-start fit says where its other starts came from, a candidate the campaign cannot fit by its nature is skipped
with a line (not reported failed), thesis_stderr.md is written only for the thesis' aircraft, ``fit`` does not
write into the demo's results/ unasked, long console lines are wrapped (nothing cut), and the ranking tables give
the gap to best as the console does, a signed percentage."""
from __future__ import annotations

import re
import tomllib
from pathlib import Path
from types import SimpleNamespace

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _regressors(path: Path, name: str) -> dict[str, str]:
    for entry in tomllib.loads(path.read_text())["entry"]:
        if entry.get("name") == name:
            return dict(entry["regressors"])
    raise AssertionError(f"{name} not in {path}")


def _spoken(expression: str) -> str:
    """A regressor as the prose writes it: (1 - X_w)*CL -> (1 - X_w) C_L."""
    return expression.replace("*CL", " C_L").replace("CL", "C_L")


def test_getting_started_describes_the_pitch_winner_as_its_spec_declares_it():
    """The committed refined structure Cm-LVIIr5-auto against the declared Cm-XXXIIIr: what it swaps and keeps."""
    winner = set(_regressors(ROOT / "results" / "refined_pitch.toml", "Cm-LVIIr5-auto").values())
    from structsearch.fitting.specs import find_candidate
    final = {e for _, e in find_candidate("Cm-XXXIIIr").regressors}
    added, removed = sorted(winner - final), sorted(final - winner)
    kept = sorted(e for e in final & winner if "(1 - X_" in e)
    text = " ".join((ROOT / "docs" / "getting-started.md").read_text().split())
    assert f"Cm-XXXIIIr with {' and '.join(added)} in place of {' and '.join(map(_spoken, removed))}" in text
    for expression in kept:
        assert f"keeps {_spoken(expression)}" in text


def test_a_one_start_fit_says_where_its_other_starts_came_from(campaign_on_disk):
    """Settings(starts=1) solves from the start asked for and the starts the fit adds (its quasi-steady stage's
    estimates, the declared start after them, a contained structure's optimum): the summary names both."""
    import structsearch as ss
    f = ss.fit(campaign_on_disk(0, 0.05), "CL-VI", settings=ss.Settings(starts=1))
    line = next(line for line in str(f.result.summary()).splitlines() if "starts reaching the best cost" in line)
    m = re.search(r"(\d+) of (\d+)(?: \((\d+) asked for and (\d+) the fit adds)?", line)
    reached, used = int(m[1]), int(m[2])
    assert 1 <= reached <= used
    if used > 1:
        assert int(m[3]) == 1 and int(m[3]) + int(m[4]) == used, line


def test_a_candidate_needing_the_reference_point_is_skipped_not_failed(tmp_path, campaign_on_disk, run_cli):
    """On a campaign without [aircraft] reference_point a pitch candidate about the fixed point is skipped with
    one line saying what it needs; the grid's line counts no failure."""
    import shutil
    campaign = tmp_path / "camp"
    shutil.copytree(campaign_on_disk(0, 0.05).directory, campaign)
    toml = campaign / "campaign.toml"
    toml.write_text("\n".join(line for line in toml.read_text().splitlines()
                              if not line.startswith("reference_point")) + "\n")
    grid = tmp_path / "tiny.toml"
    grid.write_text('name = "tiny"\ncoefficient = "Cm"\nprefix = "T-"\nlift = "CL-I"\n\n'
                    '[[entry]]\nname = "T-cg"\nregressors = { Cm0 = "1", Cm_de = "de", Cm_CL = "CL", '
                    'Cm_xcgCL = "x_cg/cbar*CL" }\n\n'
                    '[[entry]]\nname = "T-fixed"\nmoment_reference = "fixed"\n'
                    'regressors = { Cm0 = "1", Cm_de = "de", Cm_CL = "CL" }\n')
    proc = run_cli("search", "--data", campaign, "--grid", grid, "--starts", "1", "--out", tmp_path / "out",
                   "--jobs", "1", "--quiet")
    assert proc.returncode == 0, proc.stderr
    assert "failed" not in proc.stdout, proc.stdout
    assert re.search(r"^  skipped T-fixed: C_m about the fixed reference point needs \[aircraft\] reference_point",
                     proc.stdout, re.M), proc.stdout
    # the table a person reads gives the gap to best as the console does: a signed percentage
    table = (tmp_path / "out" / "tiny.md").read_text().splitlines()
    bars = [i for i, ch in enumerate(table[0]) if ch == "|"]     # the padded columns' edges (a reason has bars too)
    edges = next((a, b) for a, b in zip(bars, bars[1:]) if table[0][a + 1:b].strip() == "gap to best")
    cell = table[2][edges[0] + 1:edges[1]].strip()
    assert cell == "0%" or re.fullmatch(r"[-+][0-9.e+-]+%", cell), table[:3]


def test_thesis_stderr_is_for_the_thesis_aircraft_only(simulated_campaign):
    """The comparison with the Citation's standard deviations: not for another aircraft, with a note saying why."""
    from structsearch.flight.reference import FINAL_MODEL_NAMES
    from structsearch.thesis_study.thesis_estimator import other_aircraft, thesis_estimator_fits
    assert other_aircraft(simulated_campaign(0, 0.05)) is None
    transport = simulated_campaign(0, 0.05, aircraft="transport")
    note = other_aircraft(transport)
    assert note.startswith("thesis_stderr.md not written") and "Citation II" in note
    fitted = {"all": [SimpleNamespace(name=n, failed=False) for n in FINAL_MODEL_NAMES.values()]}
    assert thesis_estimator_fits(fitted, transport) == {}


def test_fit_does_not_default_to_the_demos_results():
    from structsearch.cli import build_parser
    args = build_parser().parse_args(["fit", "--data", "camp", "--model", "CL-VI"])
    assert Path(args.out) != Path("results") and args.out == "fit-results"
    assert build_parser().parse_args(["fit", "--data", "c", "--model", "CL-VI", "--out", "x"]).out == "x"


def test_a_long_console_line_is_wrapped_not_cut():
    from structsearch.fitting.fitter import CONSOLE_WIDTH, console_line
    line = "  skipped Cm-XXXIIIf: " + "C_m about the fixed reference point needs a key " * 6
    wrapped = console_line(line).split("\n")
    assert max(map(len, wrapped)) <= CONSOLE_WIDTH and " ".join(w.strip() for w in wrapped) == line.strip()


def test_the_gap_to_best_reads_as_the_console_prints_it():
    """The console says "+10.7%"; the tables said 0.107 (the CSV keeps the fraction for programs)."""
    from structsearch.reporting.tables import signed_percent
    assert signed_percent(0.107) == "+10.7%" and signed_percent(-0.0004) == "-0.04%"
    assert signed_percent(1.3e-17) == "0%" and signed_percent(0.0123, sign=False) == "1.2%"
    # the report's ranking tables read the CSV's fractions and show them so too
    from structsearch.reporting.page_html import csv_table
    html = csv_table(ROOT / "results" / "pitch.csv", 5, ("model", "gap to best"))
    gaps = re.findall(r"<td>([^<]*)</td>", html)[1::2]
    assert gaps[0] == "0%" and all(re.fullmatch(r"[-+][0-9.]+%|0%", g) for g in gaps), gaps


def test_a_structure_a_search_reached_is_named_by_its_path():
    """The story's pitch path (five moves, 145 characters) was named "Cm-I [04152628]", a digest that says nothing
    of what the structure holds; a path up to a console line's width keeps its words."""
    import dataclasses
    from structsearch.discovery.moves import child_name
    from structsearch.fitting.specs import find_candidate
    path = ("Cm-I + lift CL-I -> CL-story + cp_shift + elevator + replace Cm_alpha by Cm_CL = CL and Cm_xcgCL = "
            "x_cg/cbar*CL")
    parent = dataclasses.replace(find_candidate("Cm-I"), name=path)
    name = child_name(parent, "add Cm_Xde_2 = X*de", parent.regressors, parent.states, parent.lift)
    assert name == path + " + add Cm_Xde_2 = X*de" and "[" not in name
