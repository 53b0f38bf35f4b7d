"""`structsearch compare`: two output directories compared as answers (decisions equal, numbers within tolerance)."""
import json
import shutil

import pytest

from structsearch.experiments.reproducibility import Tolerances, compare_outputs

RANKING = """grid,model,rank,mse_validation,gap,admissible,reasons,nfev,message
lift,CL-VI,1,0.00321476353,0,True,,10,`ftol` termination condition is satisfied.
lift,CL-V,2,0.003214834374,1.3e-17,False,|rho(CL0; CL_a)| = 0.952 > 0.95,12,`xtol` termination condition is satisfied.
"""
STORY = {"diagnoses": {"CL": {"explained": True, "floor_source": "CL-I + elevator", "noise_floor": 0.0032194573,
                              "rounds": [{"adopted": "elevator", "mse": 0.004}, {"adopted": None, "mse": 0.0032}],
                              "seconds": 12.5}}}


@pytest.fixture
def two_runs(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    (a / "ranking.csv").write_text(RANKING)
    (a / "story.json").write_text(json.dumps(STORY))
    shutil.copytree(a, b)
    return a, b


def _edit(path, old, new):
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new))


def test_identical_runs_are_the_same(two_runs):
    found = compare_outputs(*two_runs)
    assert found.same and found.files == ("ranking.csv", "story.json")


def test_rounding_and_run_fields_are_not_differences(two_runs):
    a, b = two_runs
    _edit(b / "ranking.csv", "0.00321476353", "0.00321476354")          # 3e-9 relative
    _edit(b / "ranking.csv", "1.3e-17", "-2.1e-17")                      # zero up to rounding
    _edit(b / "ranking.csv", "= 0.952 >", "= 0.953 >")                   # printed on a rounding boundary
    _edit(b / "ranking.csv", ",10,`ftol`", ",2,`gtol`")                   # how the optimizer got there
    _edit(b / "story.json", "12.5", "99.0")                                # wall time
    assert compare_outputs(a, b).same


@pytest.mark.parametrize("old,new,kind", [
    (",1,0.00321476353", ",2,0.00321476353", "decision"),    # rank
    ("0,True,", "0,False,", "decision"),                      # admissible
    ("0.00321476353", "0.00331476353", "number"),             # 3e-2 relative
    ("CL0; CL_a", "CL0; CL_de", "decision"),                  # another reason
])
def test_a_changed_decision_or_number_is_named(two_runs, old, new, kind):
    a, b = two_runs
    _edit(b / "ranking.csv", old, new)
    found = compare_outputs(a, b)
    assert not found.same and {d.kind for d in found.differences} == {kind}
    assert all(d.file == "ranking.csv" for d in found.differences)


def test_a_changed_story_is_named(two_runs):
    a, b = two_runs
    _edit(b / "story.json", '"elevator"', '"pitch_rate"')
    _edit(b / "story.json", '"explained": true', '"explained": false')
    found = compare_outputs(a, b)
    assert {d.where for d in found.decisions} == {"/diagnoses/CL/explained", "/diagnoses/CL/rounds[0]/adopted"}


def test_a_missing_file_is_a_difference_and_the_tolerance_is_an_option(two_runs):
    a, b = two_runs
    (b / "story.json").unlink()
    assert [d.where for d in compare_outputs(a, b).differences] == ["file"]
    _edit(a / "ranking.csv", "0.00321476353", "0.00321576353")      # 3e-4 relative
    shutil.copy(a / "story.json", b / "story.json")
    assert compare_outputs(a, b).same
    assert not compare_outputs(a, b, Tolerances(rtol=1e-6)).same


def test_the_command_exits_1_on_a_difference_and_writes_json(two_runs, run_cli, tmp_path):
    a, b = two_runs
    same = run_cli("compare", a, b)
    assert same.returncode == 0 and "the same answers" in same.stdout
    _edit(b / "ranking.csv", "0,True,", "0,False,")
    differ = run_cli("compare", a, b, "--json", tmp_path / "cmp.json")
    assert differ.returncode == 1 and "admissible" in differ.stdout
    assert json.loads((tmp_path / "cmp.json").read_text())["same"] is False
    missing = run_cli("compare", a, tmp_path / "nowhere")
    assert missing.returncode == 2 and "not a directory" in missing.stderr


def test_a_path_into_the_output_directory_names_where_it_ran_not_what_it_found(tmp_path):
    """discover.json names the spec file it wrote: under each run's own directory; another file is a decision."""
    a, b = tmp_path / "first", tmp_path / "second"
    for root, spec in ((a, "Cm_discovered.toml"), (b, "Cm_discovered.toml")):
        root.mkdir()
        (root / "discover.json").write_text(json.dumps({"final": {"spec": str(root / spec)}}))
    assert compare_outputs(a, b).same
    (b / "discover.json").write_text(json.dumps({"final": {"spec": str(b / "CD_discovered.toml")}}))
    found = compare_outputs(a, b)
    assert [d.kind for d in found.differences] == ["decision"]


def test_a_directory_named_relative_and_absolute_gives_the_same_answers(tmp_path, monkeypatch, run_cli):
    """A run stores its files' paths as it named them (``results/discover_Cm/Cm_discovered.toml``, relative to
    where it ran): the same directory compared with itself, named relative and absolute, from its parent or from
    elsewhere, is the same answers; a path to another file under it is still a decision."""
    run = tmp_path / "work" / "results"
    (run / "discover_Cm").mkdir(parents=True)
    (run / "discover_Cm" / "Cm_discovered.toml").write_text("")
    (run / "discover_Cm" / "Other.toml").write_text("")
    document = {"final": {"spec": "results/discover_Cm/Cm_discovered.toml"}}
    (run / "discover_Cm" / "discover.json").write_text(json.dumps(document))
    monkeypatch.chdir(tmp_path / "work")
    assert compare_outputs("results", run).same and compare_outputs(run, "results").same
    monkeypatch.chdir(run)
    assert compare_outputs(".", run).same
    cli = run_cli("compare", "results", run, cwd=tmp_path / "work")
    assert cli.returncode == 0 and "the same answers" in cli.stdout, cli.stdout
    copy = tmp_path / "copy"
    shutil.copytree(run, copy)
    document["final"]["spec"] = "results/discover_Cm/Other.toml"
    (copy / "discover_Cm" / "discover.json").write_text(json.dumps(document))
    assert [d.kind for d in compare_outputs(run, copy).differences] == ["decision"]
