"""Contracts: every registered covariance kind, and both separable problems, keep the same promises."""
import json

import numpy as np
import pytest

from structsearch import SeparableModel
from structsearch.data.atomic import json_ready
from structsearch.engine.estimates import ParameterEstimates
from structsearch.engine.snls import model_jacobian
from structsearch.engine.statistics import (COVARIANCE_KINDS, KINDS, Covariances, cluster_covariance,
                                            colored_covariance, effective_maneuvers, flight_covariance,
                                            hac_covariance, white_covariance)
from structsearch.flight.reference import FINAL_LIFT, final_lift_model
from structsearch.flight.synthetic import with_coefficient

from conftest import central_difference

N_MANEUVERS, LENGTH = 8, 120


def _regression(n_maneuvers=N_MANEUVERS, seed=4):
    """y = 1 + 2x - 0.5x^2 + AR(1) noise whose level differs between maneuvers; x, y and the boundaries."""
    rng = np.random.default_rng(seed)
    m = n_maneuvers * LENGTH
    x = rng.uniform(-1.0, 1.0, m)
    noise = np.empty(m)
    for g in range(n_maneuvers):
        e = rng.standard_normal(LENGTH) * (0.05 + 0.02 * g)
        for t in range(1, LENGTH):
            e[t] += 0.6 * e[t - 1]
        noise[g * LENGTH:(g + 1) * LENGTH] = e
    boundaries = np.arange(0, m + 1, LENGTH)
    return x, 1.0 + 2.0 * x - 0.5 * x ** 2 + noise, boundaries


MODEL = SeparableModel({"a": "1", "b": "x", "c": "x**2"}, variables=["x"])


def _fit(kind, n_maneuvers=N_MANEUVERS):
    x, y, boundaries = _regression(n_maneuvers)
    return MODEL.fit({"x": x}, y, covariance=kind, segments=list(boundaries[1:-1])), x, boundaries


def _explicit(kind, jac, residual, boundaries):
    """The covariance of ``kind`` from the explicit estimator functions."""
    if kind == "colored":
        return colored_covariance(jac, residual, boundaries)[0]
    if kind == "white":
        return white_covariance(jac, residual)
    if kind == "cluster":
        return cluster_covariance(jac, residual, boundaries)
    if kind == "hac-flight":
        return flight_covariance(jac, residual, boundaries, None)[0]
    return hac_covariance(jac, residual, boundaries, kind)[0]


def test_the_registry_is_the_command_lines_list():
    assert COVARIANCE_KINDS == ("colored", "white", "hac", "hac-qs", "hac-maneuver", "cluster", "hac-flight")
    assert all(KINDS[k].name == k and KINDS[k].description for k in COVARIANCE_KINDS)


@pytest.mark.parametrize("kind", COVARIANCE_KINDS)
def test_every_kind_keeps_the_contract(kind):
    result, x, boundaries = _fit(kind)
    cov = result.covariance
    p = result.n_params
    assert np.all(np.isfinite(cov)) and np.allclose(cov, cov.T, rtol=0, atol=1e-14 * np.abs(cov).max())
    d = np.sqrt(np.diag(cov))
    assert np.linalg.eigvalsh(cov / np.outer(d, d)).min() > -1e-10
    assert all(np.isfinite(v) and v > 0 for v in result.stderr.values())
    assert result.identifiable and result.covariance_psd
    # the registry's estimate is the explicit function's
    jac = np.column_stack([np.ones_like(x), x, x ** 2])
    np.testing.assert_allclose(cov, _explicit(kind, jac, result.residuals, boundaries), rtol=1e-10, atol=0)
    # reference dof as documented: effective maneuvers - 1 for the per-maneuver kinds, m - p otherwise
    if KINDS[kind].per_maneuver:
        effective = effective_maneuvers(jac, jac * result.residuals[:, None], boundaries, kind)
        expected = [max(g - 1.0, 1.0) for g in effective]
        assert all(1.0 <= g <= N_MANEUVERS for g in effective)
    else:
        expected = [float(result.n_samples - p)] * p
    np.testing.assert_allclose(list(result.reference_dof.values()), expected, rtol=1e-12)
    assert KINDS[kind].not_estimable(N_MANEUVERS, p) is None


def test_a_kind_that_groups_by_flight_keeps_the_contract_with_flights_recorded():
    """hac-flight on maneuvers flown two by two on four flights: finite, symmetric, positive semi-definite, the
    explicit function's estimate, reference dof the effective flights - 1, a record that says flights; without
    recorded flights it is hac-maneuver to the bit."""
    x, y, boundaries = _regression()
    flights = ["F1", "F1", "F2", "F2", "F3", "F3", "F4", None]   # the last maneuver: no flight recorded
    result = MODEL.fit({"x": x}, y, covariance="hac-flight", segments=list(boundaries[1:-1]), flights=flights)
    cov = result.covariance
    d = np.sqrt(np.diag(cov))
    assert np.all(np.isfinite(cov)) and np.allclose(cov, cov.T, rtol=0, atol=1e-14 * np.abs(cov).max())
    assert np.linalg.eigvalsh(cov / np.outer(d, d)).min() > -1e-10
    jac = np.column_stack([np.ones_like(x), x, x ** 2])
    np.testing.assert_allclose(cov, flight_covariance(jac, result.residuals, boundaries, flights)[0], rtol=1e-10)
    effective = effective_maneuvers(jac, jac * result.residuals[:, None], boundaries, "hac-flight", flights=flights)
    assert all(1.0 <= g <= 5.0 for g in effective)          # five flights: four recorded, one maneuver alone
    np.testing.assert_allclose(list(result.reference_dof.values()), [max(g - 1.0, 1.0) for g in effective],
                               rtol=1e-12)
    record = result.estimates.covariance_record()
    assert record["grouped_by"] == "flights" and record["groups"] == 5
    alone = MODEL.fit({"x": x}, y, covariance="hac-flight", segments=list(boundaries[1:-1]))
    same = MODEL.fit({"x": x}, y, covariance="hac-maneuver", segments=list(boundaries[1:-1]))
    np.testing.assert_array_equal(alone.covariance, same.covariance)
    assert alone.reference_dof == same.reference_dof
    assert alone.estimates.covariance_record()["grouped_by"] == "maneuvers"


@pytest.mark.parametrize("kind", COVARIANCE_KINDS)
def test_a_kind_that_cannot_be_estimated_says_why(kind):
    """With fewer maneuvers than parameters + 1 the clustered meat is rank deficient: NaN with the reason,
    never a variance of 0; every other kind is estimable from three maneuvers."""
    result, _, _ = _fit(kind, n_maneuvers=3)
    reason = KINDS[kind].not_estimable(3, result.n_params)
    if KINDS[kind].needs_maneuvers:
        assert reason and "more maneuvers (3) than parameters + 1 (4)" in reason
        assert all(np.isnan(v) for v in result.stderr.values())
        assert result.not_identifiable == {n: reason for n in result.names}
        test = result.wald_test(["b"])
        assert np.isnan(test.p_value) and "not identifiable" in test.reason
        assert result.conf_int().isna().all().all()
    else:
        assert reason is None and result.identifiable


def test_covariances_on_a_subset_hold_the_others_as_not_estimable():
    x, y, boundaries = _regression()
    result = MODEL.fit({"x": x}, y, covariance="white", segments=list(boundaries[1:-1]))
    jac = np.column_stack([np.ones_like(x), x, x ** 2])
    keep = np.array([True, True, False])
    on = Covariances.on(jac, keep, result.residuals, boundaries, "hac-maneuver")
    assert np.isnan(on.covariance[2]).all() and np.isnan(on.covariance[:, 2]).all()
    np.testing.assert_allclose(on.covariance[:2, :2], hac_covariance(jac[:, :2], result.residuals, boundaries,
                                                                     "hac-maneuver")[0], rtol=1e-12)


# ----- both separable problems ---------------------------------------------------------------------
def _separable():
    rng = np.random.default_rng(5)
    x = np.linspace(0.0, 4.0, 300)
    y = 2.0 * np.exp(-1.3 * x) + 0.5 * np.exp(-0.2 * x) + 0.002 * rng.standard_normal(len(x))
    model = SeparableModel({"b1": "exp(-b2*x)", "b3": "exp(-b4*x)"}, variables=["x"])
    data = {"x": x}
    result = model.fit(data, y, start={"b2": 1.0, "b4": 0.3}, bounds={"b2": (0.5, 3.0), "b4": (0.05, 0.45)},
                       segments=[100, 200])

    def output(params):
        return model.bind(data).evaluate(params[:2]).phi @ params[2:]

    def jacobian(params):
        return model_jacobian(model.bind(data).evaluate(params[:2]), params[2:], 2)
    return result, output, jacobian


def _stall(small_campaign):
    model = final_lift_model()
    data = with_coefficient(small_campaign, model, FINAL_LIFT, noise_sigma=0.01, noise_phi=0.5, seed=2)
    result = model.fit(data, start={p: FINAL_LIFT[p] for p in model.nonlinear_names})
    k = len(model.nonlinear_names)

    def output(params):
        return model.bind(data).evaluate(params[:k]).phi @ params[k:]

    def jacobian(params):
        named = dict(zip(model.nonlinear_names + model.linear_names, params))
        return model.jacobian(data, named)[0]
    return result, output, jacobian


@pytest.fixture(params=["SeparableModel", "StallModel"])
def problem(request, small_campaign):
    return _separable() if request.param == "SeparableModel" else _stall(small_campaign)


def test_both_problems_give_one_vocabulary(problem):
    result, _, _ = problem
    names = result.names
    assert names == result.nonlinear_names + result.linear_names == result.estimates.names
    for statistic in ("params", "stderr", "t_values", "p_values", "reference_dof", "significant"):
        assert list(getattr(result, statistic)) == list(names), statistic
    assert result.converged and result.success is result.converged
    assert result.cov_params().shape == (len(names), len(names))
    np.testing.assert_array_equal(result.cov_params().to_numpy(), result.covariance)
    ci = result.conf_int(0.9)
    inside = (ci["lower"] < result.values) & (result.values < ci["upper"])
    assert inside[[result.stderr[n] > 0 for n in names]].all()
    one = result.wald_test([names[-1]])
    # a one-parameter Wald test is the square of the t-test and has its p-value
    assert one.statistic == pytest.approx(result.t_values[names[-1]] ** 2, rel=1e-9)
    assert one.p_value == pytest.approx(result.p_values[names[-1]], rel=1e-7)
    text = str(result.summary())
    assert all(n in text for n in names)
    assert result.summary().as_html().count("<table>") >= 2 and "\\toprule" in result.summary().as_latex()
    assert "|" in result.summary().as_markdown() and result.summary()._repr_html_() == result.summary().as_html()


def test_both_problems_jacobians_match_central_differences(problem):
    result, output, jacobian = problem
    analytic = jacobian(result.values)
    numeric = central_difference(output, result.values)
    scale = np.max(np.abs(numeric), axis=0)
    assert np.all(np.max(np.abs(analytic - numeric), axis=0) <= 1e-6 * scale)


def test_both_problems_estimates_survive_json(problem):
    result, _, _ = problem
    doc = json.loads(json.dumps(result.estimates.to_dict(), allow_nan=False))
    back = ParameterEstimates.from_dict(doc)
    assert back == result.estimates
    np.testing.assert_array_equal(back.covariance, result.covariance)
    np.testing.assert_array_equal(back.lower, result.lower)
    assert back.p_values == result.p_values and back.reference_dof == result.reference_dof
    assert json_ready(back.stderr) == json_ready(result.stderr)


def test_separable_bounds_at_declaration_and_at_fit_time():
    """Declared bounds apply; a parameter's box given at fit time wins over the declared one."""
    x = np.linspace(0.0, 4.0, 200)
    y = 2.0 * np.exp(-1.3 * x)
    declared = SeparableModel({"b1": "exp(-b2*x)"}, variables=["x"], bounds={"b2": (0.1, 1.0)})
    boxed = declared.fit({"x": x}, y, start={"b2": 0.5})
    assert boxed.at_bound == {"b2": "upper"} and boxed.upper[0] == 1.0
    free = declared.fit({"x": x}, y, start={"b2": 0.5}, bounds={"b2": (0.1, 3.0)})
    assert free.at_bound == {} and free.params["b2"] == pytest.approx(1.3, rel=1e-8)
    assert free.covariance_kind == "colored"
