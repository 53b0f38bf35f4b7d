"""The x_cg flight effect of a pitch model about the fixed reference point (structsearch.fitting.flight_effects):
its column is the known transfer's sensitivity C_N/cbar c_f and its coefficient the cg offset in metres, so it is
identified where the cg is constant within each flight (which the cg-referenced model cannot separate)."""
from __future__ import annotations

import numpy as np
import pytest

from structsearch.data.errors import DeclarationError
from structsearch.data.flightdata import from_segments
from structsearch.fitting.candidate_fit import fit_candidate
from structsearch.fitting.candidates import Candidate
from structsearch.fitting.enumeration import expand
from structsearch.fitting.flight_effects import design
from structsearch.fitting.models import build_model
from structsearch.fitting.options import FitOptions

CBAR, X_REF = 2.0, 7.1
FIXED = (("Cm0", "1"), ("Cm_CL", "CL"), ("Cm_de", "de"))
TRUE = {"Cm0": 0.05, "Cm_CL": -0.2, "Cm_de": -0.7}
CG_REFERENCED = (("Cm0", "1"), ("Cm_CL", "CL"), ("Cm_xcgCL", "x_cg/cbar*CL"), ("Cm_de", "de"))


def campaign(seed: int, n_flights: int = 6, per_flight: int = 3, cg_error_sd: float = 0.02, noise: float = 2e-3,
             n: int = 300):
    """A synthetic campaign (not the simulator's) whose C_m about the cg is a model about X_REF plus the transfer
    (x - X_REF)/cbar C_N at the true cg x, held constant within each flight (one loading each) and recorded as
    x + e_f. Returns the data and the cg errors e_f."""
    rng = np.random.default_rng(seed)
    errors = rng.normal(0, cg_error_sd, n_flights)
    segments, names, flights = [], [], []
    for f in range(n_flights):
        x = rng.uniform(6.95, 7.25)
        for m in range(per_flight):
            t = np.arange(n) * 0.01
            alpha = 0.15 + 0.12 * np.sin(rng.uniform(1, 3) * t + rng.uniform(0, 6))
            cl = 0.3 + 4.5 * (alpha - 0.1) + 0.05 * rng.standard_normal(n)
            cd = 0.02 + 0.5 * alpha ** 2
            de = 0.05 * rng.standard_normal(n)
            c_n = cl * np.cos(alpha) + cd * np.sin(alpha)
            cm = (TRUE["Cm0"] + TRUE["Cm_CL"] * cl + TRUE["Cm_de"] * de + (x - X_REF) / CBAR * c_n
                  + noise * rng.standard_normal(n))
            segments.append({"t": t, "alpha": alpha, "CL": cl, "CD": cd, "de": de, "Cm": cm,
                             "x_cg": np.full(n, x + errors[f])})
            names.append(f"m{f}_{m}")
            flights.append(f"F{f + 1}")
    data = from_segments(segments, names=names, flights=flights, constants={"cbar": CBAR, "reference_point": X_REF})
    return data, errors


def pitch(regressors=FIXED, reference="fixed", effects=()) -> Candidate:
    return Candidate("Cm-test", "pitch", "Cm", regressors, flight_effects=tuple(effects), moment_reference=reference)


def fit(data, candidate, effects=("x_cg",)):
    return fit_candidate(candidate, data, data, None, FitOptions(cv_folds=0, flight_effects=tuple(effects)))


# ----- declarations ----------------------------------------------------------------------------------------
def test_a_fixed_point_entry_declares_the_cg_effect_and_a_cg_term_beside_the_transfer_is_refused():
    entry = {"name": "Cm-F", "regressors": dict(FIXED), "moment_reference": "fixed", "flight_effects": ["x_cg"]}
    grid = expand({"name": "pitch", "coefficient": "Cm", "entry": [entry]}, "g.toml")
    assert grid["Cm-F"].flight_effects == ("x_cg",) and grid["Cm-F"].moment_reference == "fixed"
    # about the cg, a model without a cg term is still refused
    with pytest.raises(DeclarationError, match="no regressor reads x_cg"):
        expand({"name": "pitch", "coefficient": "Cm", "entry": [dict(entry, moment_reference="cg")]}, "g.toml")
    # about the fixed point, a cg term beside the transfer makes the offset's effect nonlinear
    both = dict(entry, regressors=dict(CG_REFERENCED))
    with pytest.raises(DeclarationError, match="Cm_transfer reads x_cg, and Cm_xcgCL too") as err:
        expand({"name": "pitch", "coefficient": "Cm", "entry": [both]}, "g.toml")
    assert "g.toml [[entry]] #1 (Cm-F)" in str(err.value)


def test_the_shipped_fixed_point_model_takes_the_effect():
    from structsearch.fitting.specs import find_candidate
    c = find_candidate("Cm-XXXIIIf")
    data, _ = campaign(0, n_flights=2, per_flight=1, n=20)
    d = design(("x_cg",), c.regressors, data, fixed=c.moment_reference == "fixed")
    assert d.effects == ("x_cg",) and d.known and d.cg_term == "Cm_transfer" and not d.skipped


# ----- the column ------------------------------------------------------------------------------------------
def test_the_cg_column_is_the_finite_difference_sensitivity_of_the_transfer():
    data, _ = campaign(1, n_flights=3, per_flight=1, n=50)
    d = design(("x_cg",), FIXED, data, fixed=True)
    base = build_model(pitch())
    model = d.model(base)
    coded = d.coding.coded(data)
    columns = model.bind(coded).regression_matrix(np.zeros(0))
    h = 1e-4
    shifted = [coded.with_columns({**coded.columns, "x_cg": coded["x_cg"] + s}) for s in (h, -h)]
    fd = (base.offset_value(shifted[0]) - base.offset_value(shifted[1])) / (2 * h)
    c_n = coded["CL"] * np.cos(coded["alpha"]) + coded["CD"] * np.sin(coded["alpha"])
    np.testing.assert_allclose(fd, c_n / CBAR, rtol=1e-6)   # the transfer is linear in x_cg
    for k in (1, 2):
        np.testing.assert_allclose(columns[:, len(FIXED) + k - 1], fd * coded[f"flight_code_{k}"],
                                   rtol=1e-7, atol=1e-10)


# ----- recovery and identifiability ------------------------------------------------------------------------
def test_known_cg_offsets_are_recovered_in_metres_where_the_cg_is_constant_within_each_flight():
    data, errors = campaign(2)
    r = fit(data, pitch())
    assert not r.failed, r.error
    cg = r.flight_effects.effects[0]
    assert cg.reason is None and cg.term == "Cm_transfer"
    assert cg.cg_offsets == cg.offsets and cg.cg_stderr == cg.stderr     # coefficient 1: metres directly
    # delta_f corrects the recorded cg: -(e_f - mean e) (the mean goes to Cm_CL, the model's mean flight)
    truth = -(errors - errors.mean())
    z = (np.array(cg.cg_offsets) - truth) / np.array(cg.cg_stderr)
    assert np.all(np.abs(z) < 4), z
    assert np.max(np.abs(np.array(cg.cg_offsets) - truth)) < 1e-3       # metres, against errors of 2 cm
    e = r.estimates
    assert set(e.params) == set(TRUE)
    assert abs(e.params["Cm_de"] - TRUE["Cm_de"]) < 4 * e.stderr["Cm_de"]
    assert not r.warnings
    # the same data about the cg: the offsets cannot be told from the cg term, and are named so
    about_cg = fit(data, pitch(CG_REFERENCED, "cg"))
    assert "constant within every training flight" in about_cg.flight_effects.effects[0].reason


def test_without_the_effect_a_fixed_point_fit_on_flights_warns():
    data, _ = campaign(3, n_flights=3)
    r = fit(data, pitch(), effects=())
    assert r.warnings and "through the known transfer Cm_transfer without flight effects" in r.warnings[0]


def test_the_offsets_read_as_metres_in_the_summary():
    data, _ = campaign(4, n_flights=3)
    lines = "\n".join(fit(data, pitch()).flight_effects.lines())
    assert "sensitivity of the known transfer Cm_transfer" in lines and "delta x_cg [m]" in lines


@pytest.mark.slow
def test_on_the_simulator_with_the_transfer_truth_the_per_flight_cg_errors_are_recovered(monkeypatch):
    """A campaign flown with the transfer truth on flights that share a cg error (the flights' other shared errors,
    drawn all the same, set to zero: a per-flight mass or vane error also moves C_m along C_N, and the offsets then
    carry its projection too): the offsets of Cm-XXXIIIf, on the fitted lift model's C_L, recover minus each
    flight's cg error, less their mean, within 4 standard deviations."""
    from structsearch.experiments.calibration import campaign_flights, final_models
    from structsearch.fitting.lift_fit import LiftFit
    from structsearch.fitting.specs import find_candidate
    from structsearch.flight import measurement
    from structsearch.flight.flighttest import build_campaign
    from structsearch.thesis_study.thesis_estimator import fit_final_models
    for name in ("mass", "thrust", "alpha_bias", "alpha_scale"):
        monkeypatch.setitem(measurement.FLIGHT_ERROR_SD, name, 0.0)
    seed, scale = 3, 0.3
    c = build_campaign(seed=seed, scale=scale, flights=campaign_flights(scale), cg_moment="transfer")
    train, val = c.split("train"), c.split("validation")
    names, truth = final_models("transfer")
    finals = fit_final_models(train, val, FitOptions(n_starts=1, cv_folds=0), {"CL": truth["CL"]}, {"CL": "CL-VI"})
    cm = fit_candidate(find_candidate(names["Cm"]), train, val, LiftFit(*finals["CL"]),
                       FitOptions(n_starts=1, cv_folds=0, flight_effects=("x_cg",)), start=truth["Cm"])
    assert not cm.failed, cm.error
    cg = cm.flight_effects.effects[0]
    recorded_minus_true = np.asarray(train["x_cg"]) - np.asarray(train["x_cg_true"])
    flight = np.repeat(np.array(train.flights, object), np.diff(train.bounds))
    error = np.array([recorded_minus_true[flight == f].mean() for f in cg.flights])
    assert np.std(error) > 2e-3                                   # errors of several mm to recover
    z = (np.array(cg.cg_offsets) + (error - error.mean())) / np.array(cg.cg_stderr)
    assert np.all(np.abs(z) < 4), z
    assert np.all(np.array(cg.cg_stderr) < 0.0035)                # a few mm: the flight errors' sd is 6 mm


# ----- the calibration on the transfer truth ---------------------------------------------------------------
def test_the_calibration_on_the_transfer_truth_fits_its_structure_about_the_fixed_point():
    from structsearch.experiments.calibration import TRUTH, final_models
    from structsearch.flight.aircraft import CITATION
    from structsearch.flight.reference import FINAL_PITCH
    names, truth = final_models("transfer")
    assert names == {"CL": "CL-VI", "CD": "CD-IXr", "Cm": "Cm-XXXIIIf"}
    assert "Cm_xcgCL" not in truth["Cm"] and truth["CL"] == TRUTH["CL"] and truth["CD"] == TRUTH["CD"]
    # the thesis' cg terms frozen at the reference point
    frozen = FINAL_PITCH["Cm_CL"] + FINAL_PITCH["Cm_xcgCL"] * CITATION.reference_point / CITATION.cbar
    assert truth["Cm"]["Cm_CL"] == pytest.approx(frozen, rel=1e-12)
    assert final_models("thesis") == ({"CL": "CL-VI", "CD": "CD-IXr", "Cm": "Cm-XXXIIIr"},
                                      {k: dict(v) for k, v in TRUTH.items()})
    with pytest.raises(DeclarationError, match="cg moment 'wind'"):
        final_models("wind")


def test_the_bench_options_parse_and_refuse_an_unknown_kind():
    import argparse

    from structsearch.cli.parser import _covariance_kinds
    assert _covariance_kinds("hac-maneuver, hac-flight") == ("hac-maneuver", "hac-flight")
    with pytest.raises(argparse.ArgumentTypeError, match="unknown covariance kind 'hac-man'"):
        _covariance_kinds("hac-maneuver,hac-man")
