"""``structsearch discover`` end to end (docs/interfaces.md 6.2 and 6.6) and its bad input."""
import csv
import json

import pytest

PATH_KEYS = {"move", "structure", "mse_validation", "mse_cv", "test", "p_value", "shrink", "where"}
FINAL_KEYS = {"name", "spec", "mse_validation", "mse_cv", "admissible", "reasons"}


@pytest.fixture(scope="module")
def data_dir(campaign_on_disk):
    return str(campaign_on_disk(seed=5, scale=0.1, slow_errors=0.0).directory)


@pytest.mark.slow
def test_discover_writes_the_path_and_a_spec_that_fit_accepts(data_dir, run_cli, tmp_path):
    out = tmp_path / "o"
    proc = run_cli("discover", "--data", data_dir, "--coefficient", "CD", "--from", "CD-I", "--out", out,
                   "--max-steps", "2", "--starts", "1", "--jobs", "1", "--trace", tmp_path / "trace.json")
    assert proc.returncode == 0, proc.stderr
    # every step's fits are tasks in the trace, a call per step; bench --trace reads it (every parent in it)
    from structsearch.experiments.trace_bench import read_trace
    trace = read_trace(tmp_path / "trace.json")
    assert sum(e["kind"] == "call" for e in trace) >= 2 and any(e["kind"] != "call" for e in trace)
    doc = json.loads((out / "discover.json").read_text())
    assert doc["coefficient"] == "CD" and doc["start"]["name"] == "CD-I"
    assert len(doc["steps"]) <= 2 and doc["structures_fitted"] >= len(doc["path"]) + 1
    # the fields docs/interfaces.md 6.6 adds
    assert {"start_mse_validation", "start_mse_cv", "comparison", "steps", "stopped", "structures_fitted",
            "noise_floor", "at_floor", "terms"} <= set(doc)
    assert "CL**2" in doc["terms"]["terms"].values() and doc["terms"]["coefficient"] == "CD"
    assert doc["path"], "CD-I is far above the floor on this campaign: some move is adopted"
    previous = doc["start_mse_validation"]
    for p in doc["path"]:
        assert PATH_KEYS | {"kind", "effect"} <= set(p), p
        assert p["structure"]["coefficient"] == "CD" and p["test"]["threshold"] > 0
        assert p["p_value"] == p["test"]["p_value"]
        assert p["shrink"] is None or 0.0 <= p["shrink"] <= 1.0
        previous = p["mse_validation"]
    final = doc["final"]
    assert FINAL_KEYS <= set(final)
    assert final["name"] == (doc["path"][-1]["structure"]["name"] if doc["path"] else "CD-I")
    assert final["mse_validation"] == pytest.approx(previous)
    assert isinstance(final["admissible"], bool) and final["admissible"] == (not final["reasons"])
    # the files next to it: the Markdown, one CSV row per adopted move, the spec file the JSON names
    text = (out / "discover.md").read_text()
    assert text.startswith("# Structure discovery for CD")
    assert "```\nCD = " in text   # the final structure as an equation
    with open(out / "path.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["move"] for r in rows] == [p["move"] for p in doc["path"]]
    spec = out / "CD_discovered.toml"
    assert final["spec"] == str(spec) and spec.is_file()
    # fit accepts the spec and fits the structure the search found
    proc = run_cli("fit", "--data", data_dir, "--model", spec, "--out", tmp_path / "fit", "--starts", "1")
    assert proc.returncode == 0, proc.stderr
    fitted = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert fitted["model"] == final["name"]
    assert set(final["structure"]["regressors"]) <= set(fitted["params"])
    assert fitted["mse"]["validation"] == pytest.approx(final["mse_validation"], rel=1e-6)


def _refused(run_cli, args, out):
    proc = run_cli("discover", *args, "--out", out, "--max-steps", "1", "--starts", "1", "--jobs", "1", "--quiet")
    assert proc.returncode != 0
    errors = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(errors) == 1 and errors[0].startswith("structsearch discover: error:"), proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (out / "discover.json").exists()
    return errors[0]


def test_a_term_file_that_does_not_parse_is_refused(data_dir, run_cli, tmp_path):
    terms = tmp_path / "terms.toml"
    terms.write_text('[terms]\nCD_broken = "alpha +* (de"\n')
    line = _refused(run_cli, ["--data", data_dir, "--coefficient", "CD", "--from", "CD-I", "--terms", terms],
                    tmp_path / "o")
    assert str(terms) in line and "'CD_broken'" in line
    terms.write_text("[terms\n")
    line = _refused(run_cli, ["--data", data_dir, "--coefficient", "CD", "--terms", terms], tmp_path / "o")
    assert str(terms) in line and "not valid TOML" in line


def test_a_term_on_a_missing_column_is_refused(data_dir, run_cli, tmp_path):
    terms = tmp_path / "terms.toml"
    terms.write_text('[terms]\nCD_alpha3 = "alpha**3"\nCD_flap = "flap_angle*alpha"\n')
    line = _refused(run_cli, ["--data", data_dir, "--coefficient", "CD", "--from", "CD-I", "--terms", terms],
                    tmp_path / "o")
    assert str(terms) in line and "'CD_flap'" in line and "flap_angle" in line


def test_a_start_of_another_coefficient_is_refused(data_dir, run_cli, tmp_path):
    line = _refused(run_cli, ["--data", data_dir, "--coefficient", "CD", "--from", "CL-VI"], tmp_path / "o")
    assert "CL-VI" in line and "CD" in line
    line = _refused(run_cli, ["--data", data_dir, "--coefficient", "CD", "--from", "CD-nonesuch"], tmp_path / "o")
    assert "CD-nonesuch" in line


@pytest.mark.parametrize("excess, se, within, verdict", [
    (0.001, 0.002, True, "yes"),      # inside the bar
    (0.05, 0.01, False, "no"),        # worse by more than the bar
    (-0.086, 0.011, True, "better"),  # below the reference by more than the bar: not "within noise"
    (-0.005, 0.002, True, "yes"),     # below, but inside the 1 % floor of the bar
    (float("nan"), None, None, "-"),
])
def test_the_comparison_says_better_where_the_discovered_structure_is_below_the_bar(excess, se, within, verdict):
    from types import SimpleNamespace
    from structsearch.reporting.discovery_doc import noise_verdict
    assert noise_verdict(SimpleNamespace(excess=excess, excess_se=se, within_noise=within)) == verdict
