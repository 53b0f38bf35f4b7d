"""A simulator no one here wrote (docs/interfaces.md 8.2): one of JSBSim's own aircraft (c172p) evaluated exactly at
recorded states, term by term, as the baseline of `diagnose` (a grey box whose terms the search may rescale, drop or
replace)."""
import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest

from structsearch.data.campaign import read_campaign
from structsearch.data.errors import DataError, DeclarationError
from structsearch.diagnosis import offset
from structsearch.discovery.moves import generate, structure_key
from structsearch.discovery.terms import SimulatorTerm, library_for
from structsearch.fitting.candidates import Candidate

jsbsim = pytest.importorskip("jsbsim", reason="the JSBSim baseline needs the jsbsim package (the test extra has it)")

from structsearch.foreign.aircraft_xml import read_aircraft  # noqa: E402
from structsearch.foreign.baseline import evaluate_campaign, jsbsim_baseline, parse_inputs  # noqa: E402
from structsearch.foreign.private_copy import make_copy  # noqa: E402

FLAPS = {"fcs/flap-pos-deg": 0.0}
PITCH = {**FLAPS, "propulsion/engine/prop-induced-velocity_fps": 0.0}
ARP_X_M = 43.2 * 0.0254


def _with(campaign, **columns):
    return dataclasses.replace(campaign, data=campaign.data.with_columns({**campaign.data.columns, **columns}))


@pytest.fixture(scope="module")
def small(campaign_on_disk):
    """Two maneuvers of the small simulated campaign (its states: alpha to 0.29 rad, q to 0.1 rad/s)."""
    c = read_campaign(campaign_on_disk(0, 0.05).directory)
    return dataclasses.replace(c, maneuvers=c.maneuvers[:2], data=c.data.select([0, 1]))


def test_each_axis_sums_to_what_jsbsim_applies(small):
    """The LIFT and DRAG functions sum to JSBSim's wind-axis forces; the PITCH functions plus sim:transfer about
    JSBSim's own cg to its moment about the cg (to rounding)."""
    also = ("forces/fwz-aero-lbs", "forces/fwx-aero-lbs", "moments/m-aero-lbsft")
    for coefficient, given in (("CL", FLAPS), ("CD", FLAPS), ("Cm", PITCH)):
        aircraft, ev, record, _ = evaluate_campaign("c172p", small, coefficient, given, also=also)
        b = jsbsim_baseline("c172p", small, coefficient, given) if coefficient != "Cm" else None
        qs = ev.qbar * ev.geometry["metrics/Sw-sqft"]
        if coefficient == "CL":
            assert np.max(np.abs(b.values - ev.body["forces/fwz-aero-lbs"] / qs)) < 1e-12
        elif coefficient == "CD":
            assert np.max(np.abs(b.values - ev.body["forces/fwx-aero-lbs"] / qs)) < 1e-12
        else:
            from structsearch.foreign.baseline import terms
            parts = terms(ev, "Cm", aircraft, None)   # None: JSBSim's own cg
            own = ev.body["moments/m-aero-lbsft"] / (qs * ev.geometry["metrics/cbarw-ft"])
            assert np.max(np.abs(np.sum(list(parts.values()), axis=0) - own)) < 1e-12
            assert "sim:transfer" in parts and "sim:aero/coefficient/Cmde" in parts
    assert record["aero/alphadot-rad_sec"] == "alpha_dot" and record["fcs/elevator-pos-rad"] == "de"
    assert ev.version == jsbsim.__version__


def test_the_terms_are_the_axis_functions_and_the_record_says_what_each_input_was(small):
    b = jsbsim_baseline("c172p", small, "CL", FLAPS)
    assert b.source == "jsbsim:c172p" and b.kind == "jsbsim"
    assert list(b.terms) == [f"sim:aero/coefficient/{n}" for n in ("CLwbh", "CLDf", "CLDe", "CLadot", "CLq")]
    assert np.array_equal(b.values, np.sum(list(b.terms.values()), axis=0))
    d = b.detail
    assert d["aircraft"] == "c172p" and d["jsbsim_version"] == jsbsim.__version__
    assert d["functions"]["aero/coefficient/CLq"] == "LIFT"
    assert d["inputs"]["ic/vt-fps"] == "V" and d["inputs"]["fcs/flap-pos-deg"] == 0.0
    assert b.term_signals["sim:aero/coefficient/CLq"] == ("q",)
    assert b.term_signals["sim:aero/coefficient/CLadot"] == ("alpha_dot",)
    assert b.term_columns["sim:aero/coefficient/CLq"] == "sim__CLq"
    # CLq = 3.9 q cbar / 2V exactly (kCLge = 1 away from the ground)
    v_fps = np.asarray(small.data["V"]) / 0.3048
    assert np.allclose(b.terms["sim:aero/coefficient/CLq"], 3.9 * np.asarray(small.data["q"]) * 4.9 / (2 * v_fps),
                       rtol=1e-12, atol=1e-15)


def test_evaluation_does_not_depend_on_the_order_of_the_samples(small):
    """alpha-dot and the stall latch come from the recording, not from the frame before."""
    n = small.data.n_samples
    a = jsbsim_baseline("c172p", _with(small, x_cg=np.full(n, ARP_X_M)), "Cm", PITCH)
    reversed_ = dataclasses.replace(small, data=small.data.with_columns(
        {k: np.asarray(v)[::-1].copy() for k, v in small.data.columns.items()}))
    one = dataclasses.replace(reversed_, data=dataclasses.replace(reversed_.data, starts=np.array([0]),
                                                                  names=("all",)), maneuvers=small.maneuvers[:1])
    b = jsbsim_baseline("c172p", _with(one, x_cg=np.full(n, ARP_X_M)), "Cm", PITCH)
    # the latch runs along each maneuver: compare the functions that do not read it (the initial conditions are
    # solved from the ones before them, which leaves a rounding of the last digits)
    for name in ("sim:aero/coefficient/Cmadot", "sim:aero/coefficient/Cmq", "sim:aero/coefficient/Cmde"):
        assert np.max(np.abs(a.terms[name] - b.terms[name][::-1])) < 1e-12, name


def test_what_the_campaign_lacks_is_one_error_naming_each_property(small):
    without_h = dataclasses.replace(small, data=small.data.with_columns(
        {k: v for k, v in small.data.columns.items() if k != "h"}))
    with pytest.raises(DeclarationError) as err:
        jsbsim_baseline("c172p", without_h, "Cm")
    text = str(err.value)
    for prop in ("ic/h-sl-ft", "fcs/flap-pos-deg", "propulsion/engine/prop-induced-velocity_fps"):
        assert prop in text
    assert "--simulator-input" in text and "\n" not in text
    with pytest.raises(DeclarationError, match="does not read it"):
        jsbsim_baseline("c172p", small, "CL", {**FLAPS, "fcs/nothing": 1.0})
    with pytest.raises(DataError, match="column 'flaps'"):
        jsbsim_baseline("c172p", small, "CL", {"fcs/flap-pos-deg": "flaps"})
    with pytest.raises(DataError, match="x_cg.*structural frame"):   # the Citation's stations, not the c172p's
        jsbsim_baseline("c172p", small, "Cm", PITCH)
    n = small.data.n_samples
    at_arp = jsbsim_baseline("c172p", _with(small, x_cg=np.full(n, ARP_X_M)), "Cm", PITCH)
    aft = jsbsim_baseline("c172p", _with(small, x_cg=np.full(n, ARP_X_M + 0.1)), "Cm", PITCH)
    # a cg 0.1 m aft adds the normal force's nose-up moment C_N 0.1 m / cbar (structural frame, x aft)
    lift, drag = (jsbsim_baseline("c172p", small, c, FLAPS).values for c in ("CL", "CD"))
    alpha = np.asarray(small.data["alpha"])
    c_n = lift * np.cos(alpha) + drag * np.sin(alpha)
    assert np.allclose(aft.terms["sim:transfer"] - at_arp.terms["sim:transfer"], c_n * 0.1 / (4.9 * 0.3048),
                       rtol=1e-9, atol=1e-12)
    assert parse_inputs(["fcs/flap-pos-deg=10", "a/b=col"]) == {"fcs/flap-pos-deg": 10.0, "a/b": "col"}
    for bad in (["x"], ["=1"], ["a=nan"], ["a=1", "a=2"]):
        with pytest.raises(DeclarationError):
            parse_inputs(bad)


def test_unknown_aircraft_and_unsafe_files_are_refused(tmp_path):
    with pytest.raises(DeclarationError, match="JSBSim has no aircraft 'c172zz'.*close: c172p"):
        read_aircraft("c172zz")
    with pytest.raises(DeclarationError, match="no such directory"):
        read_aircraft(str(tmp_path / "gone" / "x"))
    plane = tmp_path / "evil"
    plane.mkdir()
    (plane / "evil.xml").write_text('<?xml version="1.0"?><!DOCTYPE x [<!ENTITY a "aaaa">]><fdm_config>&a;</fdm_config>')
    with pytest.raises(DeclarationError, match=r"evil\.xml.*document type"):
        read_aircraft(str(plane))


def test_the_private_copy_reads_the_recording_and_writes_no_files():
    aircraft = read_aircraft("c172p")
    holder = make_copy(aircraft, {"aero/coefficient/CLq": 2.0})
    try:
        xml = (Path(holder.name) / "aircraft" / "c172p" / "c172p.xml").read_text()
    finally:
        holder.cleanup()
    assert "structsearch/alphadot-rad_sec" in xml and "aero/alphadot-rad_sec" not in xml
    assert "structsearch/stall-hyst-norm" in xml and ">aero/stall-hyst-norm<" not in xml
    assert "structsearch/input/propulsion/engine/prop-induced-velocity_fps" in xml
    assert "JSBout172C.csv" not in xml
    assert "<value>2.0</value>" in xml


def test_a_scaled_function_is_that_factor_of_the_stock_one(small):
    stock = jsbsim_baseline("c172p", small, "CL", FLAPS)
    double = jsbsim_baseline("c172p", small, "CL", FLAPS, {"aero/coefficient/CLq": 2.0})
    assert np.allclose(double.terms["sim:aero/coefficient/CLq"], 2 * stock.terms["sim:aero/coefficient/CLq"],
                       rtol=1e-14, atol=1e-18)
    assert np.array_equal(double.terms["sim:aero/coefficient/CLwbh"], stock.terms["sim:aero/coefficient/CLwbh"])


def test_rescale_drop_and_replace_act_on_the_simulators_terms(small):
    start = Candidate("jsbsim:c172p", "simulator", "CL", (("CL_bias", "1"),))
    library = dataclasses.replace(library_for("CL", small.data),
                                  simulator=(SimulatorTerm("sim:aero/coefficient/CLq", "sim__CLq", ("q",)),))
    moves = {m.label: (m, c) for m, c in generate(start, library)}
    m, c = moves["rescale sim:aero/coefficient/CLq"]
    assert m.kind == "rescale" and m.new_parameters == ("sim:aero/coefficient/CLq",)
    assert c.regressors[-1] == ("sim:aero/coefficient/CLq", "sim__CLq") and not c.known
    m, dropped = moves["drop sim:aero/coefficient/CLq"]
    assert m.kind == "drop" and dropped.known == (("-sim:aero/coefficient/CLq", "-sim__CLq"),)
    assert dropped.regressors == start.regressors and structure_key(dropped) != structure_key(start)
    replaced = [k for k in moves if k.startswith("replace sim:aero/coefficient/CLq by ")]
    assert replaced and all("qstar" in k or "q" in k for k in replaced)
    # a dropped term is gone for good: no move of it from the dropped structure
    again = {mv.label for mv, _ in generate(dropped, library)}
    assert not any("sim:aero/coefficient/CLq" in k for k in again)
    # the known term enters the fit with coefficient 1
    from structsearch.fitting.models import build_model
    gap = _with(small, sim__CLq=np.full(small.data.n_samples, 0.5))
    model = build_model(dropped)
    assert np.allclose(model.target(gap.data), np.asarray(gap.data["CL"]) + 0.5)


def test_a_black_box_simulator_has_no_grey_box_terms():
    b = offset.SimulatorBaseline("CL", "column x", "column", np.zeros(3))
    assert offset.library_terms(b) == () and b.term_columns == {}


def test_a_modification_file_is_read_as_data_with_one_error_naming_file_and_entry(tmp_path):
    from structsearch.foreign.modify import read_modify
    good = tmp_path / "m.toml"
    good.write_text('[[scale]]\nfunction = "aero/coefficient/CLq"\nfactor = 2\n')
    assert read_modify(good).scales == {"aero/coefficient/CLq": 2.0} and read_modify(good).lags == ()
    for text, words in (('[[scale]]\nfunction = "a"\n', "entry 1: give exactly"),
                        ('[[scale]]\nfunction = "a"\nfactor = nan\n', "finite number"),
                        ('[[scale]]\nfunction = "a"\nfactor = true\n', "finite number"),
                        ('[[scale]]\nfunction = "a"\nfactor = 1\n[[scale]]\nfunction = "a"\nfactor = 2\n', "twice"),
                        ('[scales]\nx = 1\n', "unknown key 'scales'"), ("factor = ", "not a TOML file")):
        bad = tmp_path / "bad.toml"
        bad.write_text(text)
        with pytest.raises(DeclarationError, match=words) as err:
            read_modify(bad)
        assert str(bad) in str(err.value)


def test_a_campaign_flown_in_jsbsim_says_where_it_comes_from(tmp_path):
    from structsearch.data.campaign import write_campaign
    from structsearch.foreign.fly import fly_campaign
    with pytest.raises(Exception, match="no axis function 'aero/coefficient/CLzz'"):
        fly_campaign("c172p", {"aero/coefficient/CLzz": 2.0}, scale=0.04)
    c = fly_campaign("c172p", {"aero/coefficient/CLq": 2.0}, scale=0.04, seed=1)
    assert [m.kind for m in c.maneuvers] == ["quasi-steady", "dynamic", "deep-dynamic"]
    source = c.extra["source"]
    assert source["simulator"] == "jsbsim" and source["aircraft"] == "c172p"
    assert source["jsbsim_version"] == jsbsim.__version__ and len(source["modify"]) == 16
    back = read_campaign(write_campaign(c, tmp_path / "flown"))
    assert back.extra["source"] == source
    d = back.data
    assert {"prop_induced_fps", "x_cg", "h", "theta", "CL_true", "Cm_true"} <= set(d.columns)
    assert np.allclose(d["x_cg"], ARP_X_M, atol=0.5)        # JSBSim's cg station [m]
    assert np.max(d["alpha"]) > 0.3 and np.max(np.abs(d["q"])) > 0.3   # through the stall, with pitch rate
    assert "source = { simulator = \"jsbsim\"" in (tmp_path / "flown" / "campaign.toml").read_text()


def test_the_command_line_lists_what_the_aircraft_needs_in_one_line(campaign_on_disk, run_cli, tmp_path):
    data = campaign_on_disk(0, 0.05).directory
    r = run_cli("diagnose", "--data", data, "--simulator", "jsbsim:c172p", "--coefficient", "CL", "--out",
                tmp_path / "x", "--quiet")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "fcs/flap-pos-deg" in r.stderr and "--simulator-input" in r.stderr
    r = run_cli("diagnose", "--data", data, "--simulator", "jsbsim:c172p", "--coefficient", "CL",
                "--simulator-input", "flaps", "--out", tmp_path / "x", "--quiet")
    assert r.returncode == 2 and "PROPERTY=COLUMN" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = run_cli("simulate", "--modify", tmp_path / "m.toml", "--out", tmp_path / "y")
    assert r.returncode == 2 and "--modify goes with --jsbsim" in r.stderr


@pytest.mark.slow
def test_a_doubled_clq_flown_in_jsbsim_is_found_and_the_stock_aircraft_is_not_changed():
    """c172p flown with CLq x 2 and diagnosed against the stock c172p: the rescale of CLq is adopted, its factor
    within two standard errors of 2; flown stock, no move is adopted (docs/guide/diagnose.md has the full-scale
    figures)."""
    from structsearch.api import diagnose
    from structsearch.api.settings import Settings
    from structsearch.foreign.fly import fly_campaign
    fast = Settings(starts=1, jobs=1)
    found = diagnose(fly_campaign("c172p", {"aero/coefficient/CLq": 2.0}, scale=0.5, seed=4), coefficient="CL",
                     simulator="jsbsim:c172p", simulator_inputs=("fcs/flap-pos-deg=0",), settings=fast, max_steps=2)
    assert found.rounds[0].adopted == "rescale sim:aero/coefficient/CLq"
    term = found.simulator["terms"]["sim:aero/coefficient/CLq"]
    assert term["verdict"] == "rescaled" and abs(term["factor"] - 2.0) < 2 * term["stderr"], term
    assert found.simulator["inputs"]["fcs/flap-pos-deg"] == 0.0
    assert found.simulator["functions"]["aero/coefficient/CLq"] == "LIFT"
    stock = diagnose(fly_campaign("c172p", scale=0.5, seed=4), coefficient="CL", simulator="jsbsim:c172p",
                     simulator_inputs=("fcs/flap-pos-deg=0",), settings=fast, max_steps=2)
    assert stock.rounds[0].adopted is None
    assert all(t["verdict"] in ("kept", "zero") for t in stock.simulator["terms"].values())


def test_an_export_of_structsearch_is_driven_as_before_and_any_other_aircraft_term_by_term(tmp_path):
    from structsearch.export.jsbsim_baseline import exported_by_structsearch
    assert not exported_by_structsearch("c172p")
    plane = tmp_path / "export" / "aircraft" / "mine"
    plane.mkdir(parents=True)
    (plane / "mine.xml").write_text("<fdm_config/>")
    assert not exported_by_structsearch(str(tmp_path / "export"))
    (tmp_path / "export" / "systems").mkdir()
    (tmp_path / "export" / "systems" / "structsearch_states.xml").write_text(
        "<system><property>structsearch/fill-inputs</property></system>")
    assert exported_by_structsearch(str(tmp_path / "export")) and exported_by_structsearch(str(plane))


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs named pipes")
def test_a_modification_file_from_anyone_is_read_within_bounds(tmp_path):
    """A named pipe is refused without waiting on it; a file nested past the bound is refused before parsing."""
    from structsearch.foreign.modify import read_modify
    pipe = tmp_path / "pipe.toml"
    os.mkfifo(pipe)
    with pytest.raises(DeclarationError, match="pipe.toml.*not a regular file"):
        read_modify(pipe)
    deep = tmp_path / "deep.toml"
    deep.write_text("x = " + "[" * 500 + "]" * 500 + "\n")
    with pytest.raises(DeclarationError, match="deep.toml.*nested"):
        read_modify(deep)
