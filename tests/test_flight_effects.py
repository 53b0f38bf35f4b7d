"""Flight effects (structsearch.fitting.flight_effects): parsing, coding, recovery of known per-flight offsets,
identifiability, the warning, JSON."""
from __future__ import annotations

import argparse

import numpy as np
import pytest

from structsearch.data.errors import DataError, DeclarationError
from structsearch.data.flightdata import from_segments
from structsearch.fitting.candidate_fit import fit_candidate
from structsearch.fitting.candidate_result import CandidateResult
from structsearch.fitting.candidates import Candidate
from structsearch.fitting.enumeration import expand
from structsearch.fitting.flight_effects import FlightCoding, design, parse_effects
from structsearch.fitting.options import FitOptions

CBAR = 2.0
PITCH = (("Cm0", "1"), ("Cm_CL", "CL"), ("Cm_xcgCL", "x_cg/cbar*CL"), ("Cm_de", "de"))
TRUE = {"Cm0": 0.05, "Cm_CL": 3.0, "Cm_xcgCL": -1.2, "Cm_de": -0.7}


def campaign(seed: int, n_flights: int = 6, per_flight: int = 4, cg_moves: bool = True, cg_error_sd: float = 0.02,
             intercept_sd: float = 0.0, noise: float = 2e-3, n: int = 300):
    """A synthetic pitch campaign (not the simulator's): Cm = Cm0 + Cm_CL CL + Cm_xcgCL x/cbar CL + Cm_de de with the
    true cg x, recorded as x + e_f (flight f's cg error), plus flight f's offset b_f; x moves within a flight
    (fuel burn) when ``cg_moves``. Returns the data, the cg errors and the offsets per flight."""
    rng = np.random.default_rng(seed)
    errors = rng.normal(0, cg_error_sd, n_flights)
    offsets = rng.normal(0, intercept_sd, n_flights) if intercept_sd else np.zeros(n_flights)
    segments, names, flights = [], [], []
    for f in range(n_flights):
        x0 = rng.uniform(7.0, 7.3)
        for m in range(per_flight):
            t = np.arange(n) * 0.01
            cl = 0.5 + 0.4 * np.sin(rng.uniform(1, 3) * t + rng.uniform(0, 6)) + 0.1 * rng.standard_normal(n)
            x = np.full(n, x0 - (0.02 * m + 0.05 * t / t[-1] if cg_moves else 0.0))
            de = 0.05 * rng.standard_normal(n)
            cm = (TRUE["Cm0"] + TRUE["Cm_CL"] * cl + TRUE["Cm_xcgCL"] * x / CBAR * cl + TRUE["Cm_de"] * de
                  + offsets[f] + noise * rng.standard_normal(n))
            segments.append({"t": t, "CL": cl, "x_cg": x + errors[f], "de": de, "Cm": cm, "alpha": 0.1 + 0 * t})
            names.append(f"m{f}_{m}")
            flights.append(f"F{f + 1}")
    data = from_segments(segments, names=names, flights=flights, constants={"cbar": CBAR})
    return data, errors, offsets


def pitch(effects=()) -> Candidate:
    return Candidate("Cm-test", "pitch", "Cm", PITCH, flight_effects=tuple(effects))


def fit(data, effects=(), options_effects=(), folds=0):
    return fit_candidate(pitch(effects), data, data, None,
                         FitOptions(cv_folds=folds, flight_effects=tuple(options_effects)))


# ----- declarations ----------------------------------------------------------------------------------------
def test_parse_effects_accepts_known_names_and_refuses_the_rest():
    assert parse_effects(["x_cg", "intercept"], "w") == ("x_cg", "intercept")
    assert parse_effects(None, "w") == ()
    with pytest.raises(DeclarationError, match="did you mean 'x_cg'"):
        parse_effects(["xcg"], "spec.toml [[entry]] #1")
    with pytest.raises(DeclarationError, match="named twice"):
        parse_effects(["x_cg", "x_cg"], "w")
    with pytest.raises(DeclarationError, match="is a list of names"):
        parse_effects("x_cg", "w")


def test_a_spec_entry_declares_flight_effects():
    doc = {"name": "pitch", "coefficient": "Cm", "prefix": "Cm-", "entry": [
        {"name": "Cm-A", "regressors": dict(PITCH), "flight_effects": ["x_cg", "intercept"]},
        {"name": "Cm-B", "regressors": dict(PITCH)}]}
    grid = expand(doc, "g.toml")
    assert grid["Cm-A"].flight_effects == ("x_cg", "intercept") and grid["Cm-B"].flight_effects == ()
    assert Candidate.from_dict(grid["Cm-A"].to_dict()) == grid["Cm-A"]
    assert "flight_effects" not in grid["Cm-B"].to_dict()   # a candidate without them keeps its record


@pytest.mark.parametrize("entry, message", [
    ({"regressors": {"Cm0": "1", "Cm_CL": "CL"}, "flight_effects": ["x_cg"]}, "no regressor reads x_cg"),
    ({"regressors": {"a": "x_cg*CL", "b": "x_cg*de"}, "flight_effects": ["x_cg"]}, "2 regressors read x_cg"),
    ({"regressors": {"Cm0": "1"}, "flight_effects": ["cg"]}, "unknown flight effect 'cg'"),
    ({"regressors": {"Cm0": "1"}, "flight_effect": ["intercept"]}, "did you mean 'flight_effects'"),
])
def test_a_bad_flight_effects_entry_is_one_clear_error(entry, message):
    doc = {"name": "pitch", "coefficient": "Cm", "entry": [{"name": "Cm-A", **entry}]}
    with pytest.raises(DeclarationError, match=message) as err:
        expand(doc, "g.toml")
    assert "g.toml [[entry]] #1" in str(err.value)


def test_the_option_refuses_an_unknown_name():
    from structsearch.cli.parser import _flight_effects
    assert _flight_effects("x_cg, intercept") == ("x_cg", "intercept")
    with pytest.raises(argparse.ArgumentTypeError, match="known: intercept, x_cg"):
        _flight_effects("x_cg,thrust")


# ----- coding ----------------------------------------------------------------------------------------------
def test_sum_to_zero_codes_and_unseen_flights():
    data, _, _ = campaign(0, n_flights=3, per_flight=2, n=20)
    coding = FlightCoding.of(data.select([0, 1, 2, 3, 4, 5]))
    assert coding.labels == ("F1", "F2", "F3") and coding.columns == ("flight_code_1", "flight_code_2")
    coded = coding.coded(data)
    rows = {f: np.array([coded[c][data.starts[2 * i]] for c in coding.columns]) for i, f in enumerate(coding.labels)}
    assert rows["F1"].tolist() == [1, 0] and rows["F2"].tolist() == [0, 1] and rows["F3"].tolist() == [-1, -1]
    # a flight the training maneuvers do not hold: code 0, the mean flight
    unseen = FlightCoding(("F1", "F2")).coded(data)
    assert np.all(unseen["flight_code_1"][data.starts[4]:] == 0)


def test_fewer_than_two_flights_or_none_recorded_is_refused():
    data, _, _ = campaign(0, n_flights=2, per_flight=2, n=20)
    with pytest.raises(DataError, match="at least two flights"):
        FlightCoding.of(data.select([0, 1]))
    unrecorded = from_segments([{k: v[s] for k, v in data.columns.items()} for s in data.segment_slices()],
                               names=data.names, constants=dict(data.constants))
    with pytest.raises(DataError, match="records none"):
        FlightCoding.of(unrecorded)
    result = fit(data.select([0, 1]), ["intercept"])
    assert result.failed and "at least two flights" in result.error


def test_the_cg_column_is_the_finite_difference_sensitivity_of_the_cg_term():
    from structsearch.fitting.models import build_model
    data, _, _ = campaign(1, n_flights=3, per_flight=1, n=50)
    d = design(("x_cg",), PITCH, data)
    model = d.model(build_model(pitch()))
    coded = d.coding.coded(data)
    column = model.bind(coded).regression_matrix(np.zeros(0))[:, len(PITCH)]
    h = 1e-4
    term = model.regressors[2]
    shifted = [coded.with_columns({**coded.columns, "x_cg": coded["x_cg"] + s}) for s in (h, -h)]
    fd = (term.value(shifted[0], {}, coded.n_samples) - term.value(shifted[1], {}, coded.n_samples)) / (2 * h)
    np.testing.assert_allclose(column, fd * coded["flight_code_1"], rtol=1e-7, atol=1e-10)


# ----- recovery and identifiability ------------------------------------------------------------------------
def test_known_cg_offsets_and_intercepts_are_recovered():
    data, errors, offsets = campaign(2, intercept_sd=0.01)
    r = fit(data, ["x_cg", "intercept"])
    assert not r.failed, r.error
    fe = r.flight_effects
    cg, icpt = fe.effects
    # delta_f corrects the recorded cg: -(e_f - mean e) (the mean goes to Cm_CL, the model's mean flight)
    truth = -(errors - errors.mean())
    z = (np.array(cg.cg_offsets) - truth) / np.array(cg.cg_stderr)
    assert np.all(np.abs(z) < 4), z
    assert np.max(np.abs(np.array(cg.cg_offsets) - truth)) < 2e-3        # metres, against errors of 2 cm
    z = (np.array(icpt.offsets) - (offsets - offsets.mean())) / np.array(icpt.stderr)
    assert np.all(np.abs(z) < 4), z
    assert abs(sum(icpt.offsets)) < 1e-12 and cg.reason is None
    # the aerodynamic parameters are reported apart from the offsets, and cover their truth
    e = r.estimates
    assert set(e.params) == set(TRUE)
    assert abs(e.params["Cm_xcgCL"] - TRUE["Cm_xcgCL"]) < 4 * e.stderr["Cm_xcgCL"]
    assert fe.reference == "F6" and fe.flights[-1] == "F6"


def test_the_effect_takes_the_cg_errors_out_of_the_cg_term():
    data, _, _ = campaign(2, cg_error_sd=0.05)
    plain, with_effect = fit(data), fit(data, ["x_cg"])
    miss = {k: abs(r.estimates.params["Cm_xcgCL"] - TRUE["Cm_xcgCL"]) for k, r in (("plain", plain),
                                                                                 ("effect", with_effect))}
    assert miss["effect"] < 4 * with_effect.estimates.stderr["Cm_xcgCL"] and miss["effect"] < miss["plain"] / 10
    assert plain.warnings and "without flight effects" in plain.warnings[0]
    assert not with_effect.warnings


def test_a_cg_constant_within_each_flight_is_named_unidentifiable():
    data, _, _ = campaign(3, cg_moves=False)
    r = fit(data, ["x_cg"])
    cg = r.flight_effects.effects[0]
    assert cg.reason and "constant within every training flight" in cg.reason
    assert np.all(np.isnan(cg.offsets)) and np.all(np.isnan(cg.cg_stderr))
    assert "Cm_xcgCL" in r.estimates.not_identifiable
    assert any(w.startswith("not identifiable") for w in r.flight_effects.warnings)


def test_few_flights_warn_and_an_option_effect_that_does_not_apply_is_skipped():
    data, _, _ = campaign(4, n_flights=3)
    lift = Candidate("CL-lin", "lift", "CL", (("CL0", "1"), ("CL_de", "de")))
    r = fit_candidate(lift, data.with_columns({**data.columns, "CL": data["Cm"]}), data, None,
                      FitOptions(cv_folds=0, flight_effects=("x_cg", "intercept")))
    fe = r.flight_effects
    assert [e.effect for e in fe.effects] == ["intercept"]
    assert fe.skipped[0][0] == "x_cg" and "no regressor reads x_cg" in fe.skipped[0][1]
    assert any(w.startswith("few flights") for w in fe.warnings)


def test_cross_validation_predicts_an_unseen_flight_with_zero_offset():
    data, _, _ = campaign(5, n_flights=6, per_flight=3, intercept_sd=0.02)
    r = fit(data, ["intercept"], folds=3)
    assert r.cv is not None and np.isfinite(r.cv.mse) and r.cv_method == "refit"
    # the folds hold maneuvers of flights they train on: the offsets help the held-out maneuvers
    assert r.cv.mse < fit(data, folds=3).cv.mse


# ----- reported apart, and as JSON ---------------------------------------------------------------------------
def test_json_round_trip_and_fit_document():
    from structsearch.reporting.documents import fit_document
    data, _, _ = campaign(6)
    r = fit(data, options_effects=["x_cg"])
    back = CandidateResult.from_json(r.to_json())
    assert back.flight_effects == r.flight_effects or back.flight_effects.to_dict() == r.flight_effects.to_dict()
    doc = fit_document(r, None)
    assert set(doc["params"]) == set(TRUE)
    assert doc["flight_effects"]["effects"][0]["effect"] == "x_cg"
    assert len(doc["flight_effects"]["effects"][0]["cg_offsets_m"]) == 6
    assert "flight effects" in str(r.summary())


@pytest.mark.slow
def test_on_a_simulated_campaign_with_flight_errors_the_cg_offsets_are_named_confounded(simulated_campaign):
    """The simulator flies each loading at one cg, so the x_cg effect cannot be told from Cm_xcgCL (named), while
    the intercept effect is estimated for every flight."""
    from structsearch.experiments.calibration import TRUTH, campaign_flights
    from structsearch.thesis_study.thesis_estimator import fit_final_models
    c = simulated_campaign(7, 0.05, flights=campaign_flights(0.05))
    train, val = c.split("train"), c.split("validation")
    finals = fit_final_models(train, val, FitOptions(n_starts=1, cv_folds=0, flight_effects=("x_cg", "intercept")),
                              {k: dict(v) for k, v in TRUTH.items()})
    cm, lift = finals["Cm"][1], finals["CL"][1]
    cg, icpt = cm.flight_effects.effects
    assert "constant within every training flight" in cg.reason and "Cm_xcgCL" in cm.estimates.not_identifiable
    assert np.all(np.isfinite(icpt.stderr)) and len(icpt.flights) == len(set(train.flights))
    assert [e.effect for e in lift.flight_effects.effects] == ["intercept"]       # the lift model reads no x_cg
    assert lift.flight_effects.skipped[0][0] == "x_cg"
