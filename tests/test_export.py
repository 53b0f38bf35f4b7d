"""`structsearch export`: the model card, the JSBSim files, and JSBSim itself computing what structsearch computes
(docs/interfaces.md 7.6)."""
import json
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from structsearch.data.errors import DeclarationError
from structsearch.engine.separation import SeparationState, evaluate_state
from structsearch.engine.stallmodel import StallModel
from structsearch.export.card import CoefficientModel, ExportedModel, StateModel
from structsearch.export.check import RATIO_TOLERANCE, STATIC_TOLERANCE, check
from structsearch.export.jsbsim_files import aerodynamics_xml, system_xml
from structsearch.export.write import write_export

DEMO = "CL-VI,CD-IXr,Cm-XXXIIIr"


def _jsbsim():
    return pytest.importorskip("jsbsim", reason="the JSBSim checks need the jsbsim package (the test extra has it)")


@pytest.fixture(scope="module")
def demo_export(campaign_on_disk, tmp_path_factory):
    """The demo's final models fitted on a small simulated campaign and exported as JSBSim files with the check."""
    _jsbsim()
    from structsearch.api.exporting import export
    from structsearch.api.settings import Settings
    campaign = campaign_on_disk(0, 0.05)
    out = tmp_path_factory.mktemp("export") / "jsbsim"
    return export(campaign=campaign.directory, models=DEMO, fmt="jsbsim", out=out, check=True,
                  settings=Settings(starts=1, jobs=1)), out, campaign


def test_jsbsim_equals_structsearch_on_the_demo_models(demo_export):
    """The issue's target: 1e-9 on static points, 1 % of the residual sd on every maneuver (states included)."""
    res, out, campaign = demo_export
    doc = json.loads((out / "check.json").read_text())
    assert doc["passed"] and res.check.passed
    assert set(doc["coefficients"]) == {"CL", "CD", "Cm"}
    for name, c in doc["coefficients"].items():
        assert c["static_max_abs_diff"] <= STATIC_TOLERANCE, name
        assert set(c["maneuvers"]) == {m.id for m in campaign.maneuvers}
        for m in c["maneuvers"].values():
            assert m["residual_sd"] > 0 and m["ratio"] == pytest.approx(m["max_abs_diff"] / m["residual_sd"])
            assert m["ratio"] <= RATIO_TOLERANCE
    states = doc["states"]
    assert set(states) == {"X_ss", "X_w"}
    assert all(s["max_abs_diff"] < 1e-9 for s in states.values())
    # the discretisation difference a Tustin lag_filter would make is stated, and it is not rounding
    assert states["X_ss"]["lag_filter_max_abs_diff"] > 1e-8 and "lag_filter_max_abs_diff" not in states["X_w"]


def test_the_xml_files_are_well_formed_with_one_function_per_axis_and_term(demo_export):
    res, out, _ = demo_export
    aero = ET.parse(out / "aerodynamics.xml").getroot()
    assert aero.tag == "aerodynamics"
    axes = {a.get("name"): a for a in aero.findall("axis")}
    assert set(axes) == {"LIFT", "DRAG", "PITCH"}
    for c, axis in zip(res.model.coefficients, ("LIFT", "DRAG", "PITCH")):
        functions = axes[axis].findall("function")
        assert [f.get("name").split("/")[-1] for f in functions] == [p for p, _ in c.terms]
        for f in functions:
            assert f.find("description").text.strip()
            factors = [p.text for p in f.find("product").findall("property")]
            assert factors[:2] == ["aero/qbar-psf", "metrics/Sw-sqft"]
            assert ("metrics/cbarw-ft" in factors) == (axis == "PITCH")
            assert (f.get("apply_at_cg") == "true") == (axis != "PITCH")
    totals = [f.get("name") for f in aero.findall("function")]
    assert totals.index("structsearch/CL") < totals.index("structsearch/terms/CD0")   # drag reads C_L
    system = ET.parse(out / "systems" / "structsearch_states.xml").getroot()
    channels = {c.get("name"): c for c in system.findall("channel")}
    assert channels["structsearch inputs"].get("execute") == "structsearch/fill-inputs"
    outputs = [f.get("name") for f in channels["structsearch separation states"].findall("fcs_function")]
    assert "structsearch/X_ss" in outputs and "structsearch/X_w" in outputs
    assert "structsearch/lag/X_ss/previous" in outputs and "structsearch/lag/X_w/previous" not in outputs  # w is S
    craft = ET.parse(next((out / "aircraft").glob("*/*.xml"))).getroot()
    assert craft.find("aerodynamics").get("file") == "../../aerodynamics.xml"
    assert float(craft.find("metrics/wingarea").text) == res.model.aircraft["S"]


def test_the_model_card_round_trips_and_says_what_a_simulator_needs(demo_export, tmp_path):
    res, _, campaign = demo_export
    path = write_export(res.model, "json", tmp_path)[0]
    doc = json.loads(path.read_text())
    assert ExportedModel.from_dict(doc).to_dict() == doc
    assert doc["equations"][0].startswith("CL = CL0 + CL_KL_ss*K_L(X_ss)")
    assert any(line.startswith("tau1_ss*dX_ss/dt + X_ss = ") for line in doc["equations"])
    lift = doc["coefficients"][0]
    cov = lift["covariance"]
    assert len(cov["matrix"]) == len(cov["names"]) and "a_star_ss" in cov["names"] and "CL0" in cov["names"]
    assert np.allclose(np.diag(cov["matrix"])[cov["names"].index("CL0")] ** 0.5,
                       next(t["stderr"] for t in lift["terms"] if t["parameter"] == "CL0"))
    assert {s["symbol"]: (s["kind"], s["form"]) for s in doc["states"]} == {"X_ss": ("U", "tanh"),
                                                                          "X_w": ("S", "tanh")}
    train = campaign.split("train")
    assert doc["validity"]["alpha_rad"] == [float(train["alpha"].min()), float(train["alpha"].max())]
    assert 0.1 < doc["validity"]["Mach"][0] < doc["validity"]["Mach"][1] < 0.5
    assert len(doc["data"]["digest"]) == 16 and doc["data"]["maneuvers"]["train"]


def _symbolic_model() -> ExportedModel:
    """Every construct of the expression grammar and every helper, in a lift and a pitch model (pitch reads C_L)."""
    lift = ["1", "alpha", "alpha**2", "qstar", "de", "K_L(X_ss)", "K_D(X_w)", "1 - X_v", "spline", "pos(alpha - 0.1)",
            "max_half(X_ss)*de", "tanh(3*alpha)", "exp(alpha)", "log(V)", "abs(de)", "sin(alpha)*cos(alpha)",
            "tan(alpha/2)", "sqrt(V)/V", "V**-2*1000", "CT", "x_cg/cbar", "alpha**(3/2)", "2**alpha", "pi*alpha/b"]
    pitch = ["1", "CL", "CL**2", "(1 - X_ss)*CL", "K2(X_ss, 1/2)", "K2(X_w, 2)", "KS(X_w)", "X_v*de"]
    rng = np.random.default_rng(3)
    terms = lambda prefix, texts: tuple((f"{prefix}{i}", t) for i, t in enumerate(texts))   # noqa: E731
    coefficients = tuple(CoefficientModel(c, c + "-test", terms(c + "_", texts),
                                          {f"{c}_{i}": float(rng.normal()) for i in range(len(texts))})
                         for c, texts in (("CL", lift), ("Cm", pitch)))
    states = (StateModel("ss", "U", {"tau1_ss": 0.4, "tau2_ss": 0.3, "a1_ss": 25.0, "a_star_ss": 0.2}),
              StateModel("w", "S", {"a1_w": 30.0, "a_star_w": 0.3}),
              StateModel("v", "Q", {"tau2_v": 0.1, "a1_v": 20.0, "a_star_v": 0.25}))
    aircraft = {"S": 30.0, "cbar": 2.013, "b": 15.75, "mass": 5000.0, "Iyy": 32000.0, "x_cg": 7.1, "trim_h_m": 3000.0,
                "trim_V_mps": 80.0, "de_range_rad": 0.4, "max_thrust_N": 20000.0}
    return ExportedModel(coefficients, states, aircraft, {"alpha_rad": [0.05, 0.4]}, {"source": "test"})


def _engine_prediction(model: ExportedModel):
    """structsearch's engine on the same model: the lift model, then pitch reading its output as CL."""
    states = {s.name: s.kind for s in model.states}
    fixed = {k: v for s in model.states for k, v in s.params.items()}

    def predict(data):
        out = {}
        for c in model.coefficients:
            m = StallModel.declare(c.model, c.coefficient, dict(c.terms), states=states, fixed=fixed)
            cols = dict(data.columns, CL=out["CL"]) if "CL" in out else data.columns
            out[c.coefficient] = m.predict(data.with_columns(cols), {**fixed, **c.params})
        for s in model.states:
            out[s.symbol] = evaluate_state(SeparationState(s.name, s.kind), s.base(), data["alpha"],
                                           data["alpha_dot"], data["t"], data.bounds, sensitivities=False)[0]
        return out
    return predict


def test_every_construct_of_the_grammar_computes_the_same_in_jsbsim(simulated_campaign, tmp_path):
    """Sums, products, quotients, powers (numeric and symbolic), every helper and math function, constants,
    columns and S/Q/U states: written as JSBSim functions and run by JSBSim, equal to the engine's values."""
    _jsbsim()
    from structsearch.export.aircraft import aircraft_name
    model = _symbolic_model()
    data = simulated_campaign(0, 0.05).data.select([0, 2, 4])
    write_export(model, "jsbsim", tmp_path)
    report = check(model, tmp_path, aircraft_name(model), data, _engine_prediction(model))
    for name, c in {**report.coefficients, **report.states}.items():
        scale = 1.0 + float(np.max(np.abs(_engine_prediction(model)(data)[name])))
        assert c["static_max_abs_diff"] <= 1e-12 * scale and c["max_abs_diff"] <= 1e-12 * scale, (name, c)


@pytest.mark.parametrize("text,words", [
    ("alpha*(-1)**(1/2)", "is not a finite real number"),
    ("flap*alpha", "no source for the column 'flap'"),
    ("CD*alpha", "reads the measured CD"),
])
def test_a_term_jsbsim_cannot_compute_is_one_error_naming_it(text, words):
    model = _symbolic_model()
    lift = model.coefficients[0]
    bad = CoefficientModel("CL", "CL-bad", lift.terms + (("CL_bad", text),), {**lift.params, "CL_bad": 1.0})
    broken = ExportedModel((bad, model.coefficients[1]), model.states, model.aircraft, model.validity, model.data)
    with pytest.raises(DeclarationError) as info:
        aerodynamics_xml(broken)
    message = str(info.value)
    assert "CL-bad: term CL_bad" in message and words in message and "\n" not in message
    assert system_xml(broken)      # the states' system does not read the term


def test_only_the_tanh_form_is_exported():
    with pytest.raises(DeclarationError, match="static form 'goman' cannot be exported"):
        StateModel("w", "S", {"a1_w": 30.0, "a_star_w": 0.3}, form="goman")


@pytest.mark.parametrize("change, words", [
    ({"moment_reference": "fixed"}, "fixed reference point cannot be exported"),
    ({"flight_effects": ("intercept",)}, "per-flight offsets"),
    ({"forms": (("w", "goman"),)}, "static form 'goman' cannot be exported"),
])
def test_what_an_export_cannot_write_is_one_error_never_another_model(change, words):
    """A pitch model about a fixed point, one with per-flight offsets, or a lift model with another static form is
    refused before anything is written (an export that dropped the transfer, the offsets or the form would compute
    another model in the simulator)."""
    import dataclasses
    from structsearch.api.exporting import Fitted, exported_model
    from structsearch.fitting.specs import find_candidate
    lift, pitch = find_candidate("CL-VI"), find_candidate("Cm-XXXIIIr")
    if "forms" in change:
        lift = dataclasses.replace(lift, **change)
    else:
        pitch = dataclasses.replace(pitch, **change)
    values = {p: 0.1 for p in lift.state_parameters + tuple(n for n, _ in lift.regressors)}
    values.update({"k_e_w": 30.0, "x_star_w": 0.5})
    fitted = [Fitted(lift, values, {}), Fitted(pitch, {n: 0.1 for n, _ in pitch.regressors}, {})]
    with pytest.raises(DeclarationError, match=words):
        exported_model(fitted, None, {})


def test_fly_stall_trims_the_example_aircraft_and_stalls_it(demo_export, tmp_path):
    """The example aircraft trims in JSBSim and flies past the wing's separation: alpha beyond a*_w, X_w falls."""
    res, out, _ = demo_export
    csv = tmp_path / "stall.csv"
    report = tmp_path / "stall.md"
    run = subprocess.run([sys.executable, str(out / "fly_stall.py"), "--csv", str(csv), "--report", str(report)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    rows = np.genfromtxt(csv, delimiter=",", names=True)
    text = report.read_text()
    crossing = rows["alpha_deg"][np.argmax(rows["X_w"] < 0.5)]
    assert f"X_w falls through 0.5 at alpha {crossing:.2f} deg" in text      # the report reads the flight
    assert f"largest C_L {rows['CL'].max():.3f}" in text and "| t | alpha_deg | CL |" in text
    a_star_w = res.model.states[1].params["a_star_w"]
    assert np.degrees(a_star_w) < rows["alpha_deg"].max() < np.degrees(a_star_w) + 5
    assert rows["X_w"].min() < 0.5 < rows["X_w"][0] and rows["X_ss"].min() < 0.01
    assert rows["CL"].max() > rows["CL"][-1]           # C_L rose to its maximum and fell with the separation


@pytest.mark.slow
def test_the_command_line_exports_a_fit_directory_and_refuses_bad_requests(campaign_on_disk, run_cli, tmp_path):
    _jsbsim()
    camp = campaign_on_disk(0, 0.05).directory
    fit = run_cli("fit", "--data", camp, "--model", "CD-IXr", "--out", tmp_path / "fit", "--starts", "1")
    assert fit.returncode == 0, fit.stderr
    card = run_cli("export", "--fit", tmp_path / "fit", "--format", "json", "--out", tmp_path / "card")
    assert card.returncode == 0, card.stderr
    doc = json.loads((tmp_path / "card" / "model.json").read_text())
    assert [c["model"] for c in doc["coefficients"]] == ["CL-VI", "CD-IXr"]
    assert doc["coefficients"][1]["covariance"] is not None and doc["coefficients"][0]["covariance"] is None
    assert "lift model's estimates only" in doc["coefficients"][0]["covariance_note"]
    # the lift model's residual sd, which the drag fit does not record, is recomputed from its estimates
    lift_fit = json.loads((tmp_path / "fit" / "fit.json").read_text())["lift"]
    assert lift_fit["params"]["CL0"] == doc["coefficients"][0]["terms"][0]["value"]
    assert doc["coefficients"][0]["residual_sd"] > 0
    sim = run_cli("export", "--fit", tmp_path / "fit", "--format", "jsbsim", "--out", tmp_path / "sim", "--check")
    assert sim.returncode == 0, sim.stderr
    assert "check: passed" in sim.stdout and (tmp_path / "sim" / "check.json").exists()
    for argv, words in (
            (["--fit", tmp_path / "fit", "--format", "json", "--out", tmp_path / "x", "--check"], "--format jsbsim"),
            (["--fit", tmp_path, "--format", "json", "--out", tmp_path / "x"], "no fit.json here"),
            (["--data", camp, "--format", "json", "--out", tmp_path / "x"], "--data needs --model"),
            (["--data", camp, "--model", "CD-I,CD-IXr", "--format", "json", "--out", tmp_path / "x"], "two models of CD"),
            (["--data", camp, "--model", "CD-I,Cm-XXXIIIr", "--format", "json", "--out", tmp_path / "x"],
             "different lift models")):
        bad = run_cli("export", *argv)
        assert bad.returncode == 2 and words in bad.stderr and bad.stderr.count("\n") == 1, (argv, bad.stderr)


def test_a_joint_fit_directory_exports_with_its_joint_covariance(campaign_on_disk, tmp_path):
    """fit --joint's fit.json: every coefficient's parameters, the shared states, the joint covariance's blocks."""
    _jsbsim()
    from structsearch.api import Settings, export, fit_joint
    from structsearch.data.atomic import write_json
    campaign = campaign_on_disk(0, 0.05)
    joint = fit_joint(campaign, DEMO, settings=Settings(starts=1, jobs=1))
    write_json(tmp_path / "fit" / "fit.json", joint.to_dict())
    res = export(fit_dir=tmp_path / "fit", fmt="jsbsim", out=tmp_path / "sim", check=True)
    assert res.check.passed
    for c in res.model.coefficients:
        entry = next(e for e in joint.coefficients if e.coefficient == c.coefficient)
        assert c.params == {p: entry.params[p] for p, _ in c.terms}
        assert c.residual_sd == pytest.approx(entry.train.mse ** 0.5)
        own = [p for p, _ in c.terms]
        assert set(own) <= set(c.covariance_names)
        i = c.covariance_names.index(own[0])
        assert c.covariance[i][i] ** 0.5 == pytest.approx(entry.stderr[own[0]])
    shared = {p for s in res.model.states for p in s.params}
    assert shared == set(joint.shared)
