"""A simulator as the baseline of `diagnose` (docs/interfaces.md 7.6): the simulator's coefficient along the flight,
read from a campaign column or computed by JSBSim at the recorded states, is a fixed offset, and the gap (flight
minus simulator) is diagnosed by the same structure search."""
import dataclasses

import numpy as np
import pytest

from structsearch.api.settings import Settings
from structsearch.data.campaign import read_campaign, write_campaign
from structsearch.data.errors import DataError, DeclarationError
from structsearch.diagnosis import offset

FAST = Settings(starts=1, jobs=1)


def _jsbsim():
    return pytest.importorskip("jsbsim", reason="the JSBSim baseline needs the jsbsim package (the test extra has it)")


def _with_column(campaign, name, values):
    return dataclasses.replace(campaign, data=campaign.data.with_columns({**campaign.data.columns, name: values}))


@pytest.fixture(scope="module")
def on_disk(campaign_on_disk):
    return read_campaign(campaign_on_disk(0, 0.05).directory)


def test_the_gap_is_flight_minus_simulator_and_the_search_starts_from_a_bias(on_disk):
    rng = np.random.default_rng(3)
    sim = 0.9 * on_disk.data["CL_true"] + 0.01 * rng.standard_normal(on_disk.data.n_samples)
    campaign = _with_column(on_disk, "CL_sim", sim)
    baseline = offset.column_baseline(campaign, "CL", "CL_sim")
    assert baseline.source == "column CL_sim" and np.array_equal(baseline.values, sim)
    gap = offset.gap_campaign(campaign, baseline)
    assert np.array_equal(gap.data["CL"], campaign.data["CL"] - sim)
    # the offset is no measured signal: its column leaves the gap's campaign; the others stay as they were
    assert "CL_sim" not in gap.data
    for name in ("CD", "Cm", "alpha", "q", "t"):
        assert np.array_equal(gap.data[name], campaign.data[name])
    assert [m.id for m in gap.maneuvers] == [m.id for m in campaign.maneuvers]
    start = offset.start_structure(baseline)
    assert start.regressors == (("CL_bias", "1"),) and not start.states and start.name == "column CL_sim"
    record = offset.simulator_record(campaign, baseline, 0.002)
    train = campaign.split("train")
    assert record["mse"]["train"] == pytest.approx(np.mean((train["CL"] - 0.9 * train["CL_true"]) ** 2), rel=0.2)
    own = np.concatenate([campaign.data["CL"][s] - sim[s] for s, m in zip(campaign.data.segment_slices(),
                                                                          campaign.maneuvers) if m.split == "train"])
    assert record["mse"]["train"] == pytest.approx(np.mean(own ** 2), rel=1e-12)
    assert record["bias"] == {"name": "CL_bias", "value": 0.002} and record["kind"] == "column"


def test_a_missing_or_bad_baseline_column_is_one_error_naming_file_column_and_row(on_disk):
    with pytest.raises(DataError, match=r"campaign\.toml.*column 'CL_sim'"):
        offset.column_baseline(on_disk, "CL", "CL_sim")
    with pytest.raises(DeclarationError, match="measured coefficient itself"):
        offset.column_baseline(on_disk, "CL", "CL")
    with pytest.raises(DeclarationError, match="needs --coefficient"):
        offset.column_baseline(on_disk, None, "CL_sim")
    values = np.array(on_disk.data["CL"], float)
    k = int(on_disk.data.bounds[2]) + 7
    for bad in (np.nan, np.inf):
        values[k] = bad
        with pytest.raises(DataError) as err:
            offset.column_baseline(_with_column(on_disk, "CL_sim", values.copy()), "CL", "CL_sim")
        message = str(err.value)
        assert on_disk.maneuvers[2].file in message and "column 'CL_sim'" in message and "row 7" in message
        assert "\n" not in message


@pytest.mark.slow
def test_a_simulator_missing_an_effect_is_diagnosed_by_that_effect(on_disk):
    """A campaign the default simulator did not make: a simulator whose C_L lacks the elevator term (1.5 de) of
    the flight. The gap is that term plus the measurement noise; the search adopts elevator and closes the gap."""
    from structsearch.api import diagnose
    truth = on_disk.data["CL_true"]
    campaign = _with_column(on_disk, "CL_sim", truth - 1.5 * on_disk.data["de"])
    d = diagnose(campaign, coefficient="CL", baseline_column="CL_sim", settings=FAST, max_steps=1, beam=1)
    assert d.baseline == "column CL_sim" and d.simulator["source"] == "column CL_sim"
    assert d.rounds[0].adopted == "elevator"
    assert d.closes(0, d.rounds[0].effects[0]) > 0.9
    assert d.explained
    assert not d.baseline_reasons     # a zero bias is no reason against the simulator
    doc = d.to_dict()
    assert doc["simulator"]["bias"]["name"] == "CL_bias" and "fixed offset" in doc["simulator"]["baseline"]
    assert "state_level" not in doc


@pytest.fixture(scope="module")
def van_ingen_export(on_disk, tmp_path_factory):
    """Van Ingen's CL-I, CD-I and Cm-I fitted on the training maneuvers and exported as a JSBSim aircraft, with
    structsearch's own prediction of the same fit at every recorded sample."""
    _jsbsim()
    from structsearch.api.exporting import _model_names, _predictor, exported_model, fitted_from_data
    from structsearch.api.results import campaign_record
    from structsearch.export.write import write_export
    fitted = fitted_from_data(on_disk, _model_names("CL-I,CD-I,Cm-I"), FAST)
    out = tmp_path_factory.mktemp("van_ingen") / "jsbsim"
    write_export(exported_model(fitted, on_disk, campaign_record(on_disk)), "jsbsim", out)
    return out, _predictor(fitted, None)(on_disk.data)


def test_the_exported_aircraft_computes_structsearch_s_prediction_at_the_recorded_states(on_disk, van_ingen_export):
    from structsearch.export.jsbsim_baseline import jsbsim_baseline
    out, ours = van_ingen_export
    for coefficient in ("CL", "CD", "Cm"):
        # the export directory and its aircraft directory name the same aircraft
        for target in (str(out), str(next((out / "aircraft").iterdir()))):
            b = jsbsim_baseline(target, on_disk, coefficient)
            assert b.source == "jsbsim:structsearch_CL-I" and b.kind == "jsbsim"
            assert np.max(np.abs(b.values - ours[coefficient])) < 1e-9, coefficient
    assert "alpha_dot" in b.detail["inputs"] and b.detail["property"] == "structsearch/Cm"


def test_only_aircraft_exported_by_structsearch_are_driven(on_disk, tmp_path):
    _jsbsim()
    from structsearch.diagnosis.offset import simulator_target
    from structsearch.export.jsbsim_baseline import jsbsim_baseline
    with pytest.raises(DeclarationError, match="not an aircraft exported by structsearch.*--baseline-column"):
        jsbsim_baseline("c172x", on_disk, "CL")
    with pytest.raises(DeclarationError, match="could not load the aircraft 'no_such_plane'"):
        jsbsim_baseline("no_such_plane", on_disk, "CL")
    with pytest.raises(DeclarationError, match="no JSBSim aircraft here"):
        jsbsim_baseline(str(tmp_path), on_disk, "CL")
    with pytest.raises(DeclarationError, match="no such directory"):
        jsbsim_baseline(str(tmp_path / "gone" / "x"), on_disk, "CL")
    for bad in ("c172x", "jsbsim:", "xplane:c172x"):
        with pytest.raises(DeclarationError, match="give jsbsim:NAME_OR_DIR"):
            simulator_target(bad)


@pytest.mark.slow
def test_closed_loop_van_ingen_through_jsbsim(on_disk, van_ingen_export):
    """Closed loop: CL-I, CD-I and Cm-I exported to JSBSim and diagnosed with --simulator give the story of the
    same fit written as a column (same moves, same shares), and start where the direct diagnosis of CL-I, CD-I and
    Cm-I starts (same baseline MSE; the bias zero). The direct diagnosis refits the baseline's parameters with each
    move, the simulator's are fixed: its moves are those of the fixed model (docs/guide/diagnose.md)."""
    from structsearch.api import diagnose
    out, ours = van_ingen_export
    for coefficient, model in (("CL", "CL-I"), ("CD", "CD-I"), ("Cm", "Cm-I")):
        sim = diagnose(on_disk, coefficient=coefficient, simulator=f"jsbsim:{out}", settings=FAST, max_steps=2)
        column = diagnose(_with_column(on_disk, "sim", ours[coefficient]), coefficient=coefficient,
                          baseline_column="sim", settings=FAST, max_steps=2)
        assert [r.adopted for r in sim.rounds] == [r.adopted for r in column.rounds]
        for a, b in zip(sim.rounds, column.rounds):
            assert a.mse.validation == pytest.approx(b.mse.validation, rel=1e-6)
            assert [e.name for e in a.effects] == [e.name for e in b.effects]
        direct = diagnose(on_disk, model, settings=FAST, max_steps=1)
        assert sim.mse.validation == pytest.approx(direct.mse.validation, rel=1e-6)
        assert abs(sim.simulator["bias"]["value"]) < 1e-9
        assert sim.simulator["mse"]["validation"] == pytest.approx(direct.mse.validation, rel=1e-6)


@pytest.fixture(scope="module")
def sim_column_on_disk(on_disk, tmp_path_factory):
    """The small campaign with a simulator column that lacks the flight's elevator term, written to disk."""
    data = tmp_path_factory.mktemp("sim_column") / "campaign"
    write_campaign(_with_column(on_disk, "CL_sim", on_disk.data["CL_true"] - 1.5 * on_disk.data["de"]), data)
    return data


@pytest.mark.slow
def test_the_command_line_diagnoses_a_simulator_column(sim_column_on_disk, run_cli, tmp_path):
    data = sim_column_on_disk
    out = tmp_path / "diag"
    ok = run_cli("diagnose", "--data", data, "--baseline-column", "CL_sim", "--coefficient", "CL", "--max-steps", "1",
                 "--beam", "1", "--starts", "1", "--jobs", "1", "--out", out, "--quiet")
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.startswith("CL column CL_sim: best effect elevator")
    assert "Baseline: the simulator column CL_sim" in (out / "diagnosis.md").read_text()


def test_the_command_line_refuses_bad_simulator_baselines_in_one_line(sim_column_on_disk, run_cli, tmp_path):
    data = sim_column_on_disk
    bad = [
        (("--baseline-column", "CL_nope", "--coefficient", "CL"), "column 'CL_nope'"),
        (("--baseline-column", "CL_sim"), "needs --coefficient"),
        (("--baseline-column", "CL_sim", "--model", "CL-I", "--coefficient", "CL"), "one baseline"),
        (("--simulator", "c172x", "--coefficient", "CL"), "jsbsim:NAME_OR_DIR"),
        (("--simulator", f"jsbsim:{tmp_path / 'nowhere'}", "--coefficient", "CL"), "no such directory"),
    ]
    for args, words in bad:
        r = run_cli("diagnose", "--data", data, *args, "--out", tmp_path / "x", "--quiet")
        assert r.returncode == 2, (args, r.stderr)
        assert words in r.stderr and len(r.stderr.strip().splitlines()) == 1, (args, r.stderr)
