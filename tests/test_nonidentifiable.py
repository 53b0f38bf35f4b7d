"""Identifiability instead of crashes: named parameters, NaN standard deviations, no LinAlgError."""
import dataclasses

import numpy as np
import pytest

from structsearch.data.flightdata import FlightData
from structsearch.engine.identifiability import RANK_RTOL, rank_reasons
from structsearch import SeparableModel
from structsearch.engine.stallmodel import StallModel
from structsearch.reporting.fit_report import fit_report


def _noisy(data, sigma=0.01, seed=3):
    cols = dict(data.columns)
    cols["CL"] = cols["CL"] + sigma * np.random.default_rng(seed).standard_normal(len(cols["CL"]))
    return FlightData(cols, data.starts, data.names, data.source, data.constants)


@pytest.fixture(scope="module")
def saturated_fit(noise_free_lift):
    """A second state whose break point lies beyond every angle of attack flown (X_w = 1 throughout)."""
    _, data = noise_free_lift
    assert data["alpha"].max() < 0.45
    model = StallModel.declare(
        "two-states", "CL", states={"ss": "U", "w": "S"},
        regressors={"CL0": "1", "CL_KL_ss": "K_L(X_ss)", "CL_Xw": "X_w", "CL_qstar": "qstar", "CL_de": "de"},
        bounds={"a_star_w": (0.6, 0.8), "a1_w": (30.0, 60.0)})
    return model.fit(_noisy(data))


def test_saturated_state_names_its_parameters(saturated_fit):
    why = saturated_fit.not_identifiable
    assert not saturated_fit.identifiable
    for name in ("a1_w", "a_star_w"):
        assert "X_w stays above 0.999 on every sample" in why[name]
        assert "a1_w and a_star_w cannot be identified" in why[name]
    # with X_w = 1 its regressor is the constant column: CL_Xw and the intercept cannot be told apart
    assert "CL_Xw and CL0 cannot be separated" in why["CL_Xw"] and why["CL0"] == why["CL_Xw"]
    assert set(why) == {"a1_w", "a_star_w", "CL_Xw", "CL0"}


def test_saturated_state_gives_nan_not_zero(saturated_fit):
    for name in saturated_fit.names:
        sd = saturated_fit.stderr[name]
        if name in saturated_fit.not_identifiable:
            assert np.isnan(sd) and np.isnan(saturated_fit.p_values[name])
        else:
            assert np.isfinite(sd) and sd > 0, name
    doc = saturated_fit.to_dict()
    assert doc["identifiable"] is False and set(doc["not_identifiable"]) == set(saturated_fit.not_identifiable)
    assert "X_w stays above 0.999" in fit_report(saturated_fit)


def test_identified_part_keeps_its_statistics(saturated_fit, noise_free_lift):
    """The covariance of the identifiable parameters is that of the model without the saturated state."""
    _, data = noise_free_lift
    reduced = StallModel.declare("one-state", "CL", states={"ss": "U"},
                                 regressors={"CL0": "1", "CL_KL_ss": "K_L(X_ss)", "CL_qstar": "qstar",
                                             "CL_de": "de"})
    fit = reduced.fit(_noisy(data))
    for name in ("tau1_ss", "a_star_ss", "CL_KL_ss", "CL_de"):
        assert saturated_fit.params[name] == pytest.approx(fit.params[name], rel=1e-3)
        assert saturated_fit.stderr[name] == pytest.approx(fit.stderr[name], rel=0.05), name


def test_constant_regressor_named_with_the_intercept(noise_free_lift):
    _, data = noise_free_lift
    model = StallModel.declare("m", "CL", states={"ss": "U"},
                               regressors={"CL0": "1", "CL_KL": "K_L(X_ss)", "CL_cg": "x_cg/x_cg"})
    fit = model.fit(data)
    assert set(fit.not_identifiable) == {"CL0", "CL_cg"}
    assert "CL0 and CL_cg are collinear" in fit.not_identifiable["CL_cg"]
    assert np.isnan(fit.stderr["CL0"]) and np.isnan(fit.stderr["CL_cg"])
    assert np.isfinite(fit.stderr["CL_KL"])


def test_collinear_regressors_in_ols(noise_free_lift):
    _, data = noise_free_lift
    model = StallModel.declare("m", "CL", regressors={"a": "alpha", "b": "de", "c": "2*alpha - 3*de"})
    fit = model.fit(data)
    assert set(fit.not_identifiable) == {"a", "b", "c"}
    assert "a, b and c are collinear" in fit.not_identifiable["a"]
    # the fitted values are still the least-squares ones
    direct = np.linalg.lstsq(np.column_stack([data["alpha"], data["de"]]), data["CL"], rcond=None)[0]
    assert fit.rss == pytest.approx(float(np.sum((data["CL"] - np.column_stack(
        [data["alpha"], data["de"]]) @ direct) ** 2)), rel=1e-9)


def test_rank_reasons_on_known_jacobians():
    rng = np.random.default_rng(0)
    base = rng.standard_normal((200, 3))
    assert rank_reasons(base, ["a", "b", "c"]) == {}
    dup = np.column_stack([base, 2.0 * base[:, 1]])
    why = rank_reasons(dup, ["a", "b", "c", "d"])
    assert set(why) == {"b", "d"} and "b and d are collinear" in why["b"]
    zero = np.column_stack([base, np.zeros(200)])
    assert set(rank_reasons(zero, ["a", "b", "c", "z"])) == {"z"}
    # just inside the limit: a direction 100 times stronger than the limit stays identifiable
    near = np.column_stack([base, base[:, 0] + 100 * RANK_RTOL * rng.standard_normal(200)])
    assert rank_reasons(near, ["a", "b", "c", "n"]) == {}
    beyond = np.column_stack([base, base[:, 0] + 0.01 * RANK_RTOL * rng.standard_normal(200)])
    assert set(rank_reasons(beyond, ["a", "b", "c", "n"])) == {"a", "n"}


@pytest.fixture(scope="module")
def exponential_fit():
    rng = np.random.default_rng(5)
    x = np.linspace(0.0, 4.0, 300)
    y = 2.0 * np.exp(-1.3 * x) + 0.5 + 0.01 * rng.standard_normal(300)
    return SeparableModel({"c": "exp(-k*x)", "d": "1"}, variables=["x"]).fit(
        {"x": x}, y, start={"k": 1.0}, bounds={"k": (0.5, 1.3 + 0.1)}, covariance="white")


def test_indefinite_covariance_is_flagged_not_repaired(exponential_fit):
    cov = exponential_fit.covariance.copy()
    s = np.sqrt(cov[0, 0] * cov[1, 1])
    cov[0, 1] = cov[1, 0] = 1.5 * s  # |correlation| 1.5: positive variances, indefinite matrix
    broken = dataclasses.replace(exponential_fit, covariance=cov)
    assert exponential_fit.covariance_psd and not broken.covariance_psd
    assert broken.stderr["k"] == pytest.approx(np.sqrt(cov[0, 0]))
    assert "INDEFINITE" in fit_report(broken) and broken.to_dict()["covariance_psd"] is False


@pytest.mark.parametrize("inside,flag", [(4e-7, "lower"), (1e-6 * 0.8, "lower"), (0.99e-3, "lower"), (2e-3, None)])
def test_at_bound_is_relative_to_the_range(exponential_fit, inside, flag):
    """k's box is [0.5, 1.4]: within 1e-3 of the range (PRACTICAL_BOUND_FRACTION) is at the bound, the solver's stops
    short of it (4e-7 of the range) among them; its standard deviation is shrunk below that reach here, so that
    the fraction alone decides."""
    from structsearch.engine.estimates import PRACTICAL_BOUND_FRACTION
    assert PRACTICAL_BOUND_FRACTION == 1e-3
    lo, hi = exponential_fit.lower[0], exponential_fit.upper[0]
    values = exponential_fit.values.copy()
    values[0] = lo + inside * (hi - lo)
    moved = dataclasses.replace(exponential_fit, values=values, covariance=exponential_fit.covariance * 1e-8)
    assert moved.stderr["k"] < 1e-4 * (hi - lo)
    assert moved.at_bound == ({"k": flag} if flag else {})


@pytest.mark.parametrize("standard_deviations,flag", [(0.99, "upper"), (3.0, None)])
def test_an_estimate_within_its_standard_deviation_of_a_bound_is_at_it(standard_deviations, flag):
    """A converged fit whose optimum lies inside the box, the upper bound ``standard_deviations`` of its own standard
    deviation away: within one it is at the bound (the data do not place it inside the box), at three it is an
    interior optimum (both far beyond 1e-3 of the box)."""
    rng = np.random.default_rng(5)
    x = np.linspace(0.0, 4.0, 300)
    y = 2.0 * np.exp(-1.3 * x) + 0.5 + 0.01 * rng.standard_normal(300)
    model = SeparableModel({"c": "exp(-k*x)", "d": "1"}, variables=["x"])
    free = model.fit({"x": x}, y, start={"k": 1.0}, bounds={"k": (0.5, 3.0)}, covariance="white")
    k, se = free.params["k"], free.stderr["k"]
    edge = k + standard_deviations * se
    boxed = model.fit({"x": x}, y, start={"k": 1.1}, bounds={"k": (1.0, edge)}, covariance="white")
    assert boxed.converged and boxed.params["k"] == pytest.approx(k, rel=1e-7)
    assert edge - boxed.params["k"] > 5 * 1e-3 * (edge - 1.0)     # the fraction of the box is not what flags it
    assert boxed.at_bound == ({"k": flag} if flag else {})
    assert free.at_bound == {}


def test_a_fit_that_did_not_converge_reports_no_statistics(noise_free_lift):
    """An optimizer stopped by its evaluation budget: the estimates are where it stopped, and no standard deviation,
    p-value, interval or correlation is reported, each with the reason, in the summary, the JSON and the
    candidate's admissibility."""
    import json
    from structsearch.data.atomic import json_ready
    from structsearch.engine.scores import R2Summary
    from structsearch.fitting.candidate_result import CandidateResult, SplitScores
    from structsearch.grid_search.admissibility import AdmissibilityRules, Reason, reasons
    model, data = noise_free_lift
    stopped = model.fit(_noisy(data), max_nfev=2)
    assert not stopped.converged
    why = f"the optimizer did not converge: {stopped.message}"
    assert stopped.withheld == why and not stopped.identifiable
    for table in (stopped.stderr, stopped.p_values, stopped.white_stderr):
        assert all(np.isnan(v) for v in table.values())
    assert np.isnan(stopped.conf_int().to_numpy()).all() and np.isnan(stopped.covariance).all()
    off_diagonal = stopped.correlation[~np.eye(stopped.n_params, dtype=bool)]
    assert np.isnan(off_diagonal).all() and stopped.high_correlations == []
    assert stopped.not_identifiable == dict.fromkeys(stopped.names, why)
    assert stopped.wald_test([stopped.names[-1]]).reason.endswith(why)
    text = str(stopped.summary())
    assert why in text and "NOT CONVERGED" in text and "no statistics: not converged" in text
    doc = json.loads(json.dumps(json_ready(stopped.to_dict()), allow_nan=False))
    assert doc["statistics_withheld"] == why and set(doc["stderr"].values()) == {None}
    assert set(doc["p_values"].values()) == {None}
    scores = SplitScores(stopped.mse, (stopped.mse,), (stopped.n_samples,), R2Summary(0.9, 0.9, 0.9, 0.9))
    cand = CandidateResult.from_fit(name="S", grid="g", coefficient="CL", lift=None, result=stopped, train=scores,
                                    validation=scores, seconds=0.1)
    back = CandidateResult.from_json(json.loads(json.dumps(cand.to_json(), allow_nan=False)))
    assert back == cand and back.estimates.withheld == why and np.isnan(back.estimates.stderr["CL0"])
    said = reasons(back, None, AdmissibilityRules())
    assert [Reason.of(r) for r in said if Reason.of(r) is not Reason.AT_BOUND] == [Reason.NOT_CONVERGED], said
    assert "no standard deviations" in said[0] and why in str(back.summary())
    # nor is it refined: there is no t-test or interval to judge a move by
    from structsearch.fitting.candidates import Candidate
    from structsearch.grid_search.refinement import refine
    done = refine(Candidate("S", "g", "CL", (("CL0", "1"),)), back, lambda c: pytest.fail("no move is fitted"))
    assert done.steps == () and why in done.stopped
