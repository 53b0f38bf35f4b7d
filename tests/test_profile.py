"""Profile intervals of the nonlinear parameters (issue 30): the adjusted statistic equals the Wald interval to first
order, is zero at the estimate, follows the skew of a nonlinear estimator, opens at a box edge, gives NaN with a
reason where a refit fails, and reaches fit.json, fit.md and the calibration's rows."""
import json

import numpy as np
import pytest

from structsearch.engine.profile import Profiles, profile, profile_statistic
from structsearch.engine.separable import SeparableModel
from structsearch.engine.snls import Evaluation, SeparableProblem

MODEL = SeparableModel({"c": "exp(-b*x)", "c0": "1"}, variables=["x"], bounds={"b": (0.01, 20.0)})


def decay(seed: int, sd: float, maneuvers: int = 12, n: int = 40, rho: float = 0.7):
    """y = 2 exp(-1.3 x) + 0.5 + AR(1) noise in ``maneuvers`` records of ``n`` samples: coloured residuals, so that
    the per-maneuver covariance is several times the white one."""
    rng = np.random.default_rng(seed)
    x = np.tile(np.linspace(0.0, 4.0, n), maneuvers)
    e = np.zeros(maneuvers * n)
    for g in range(maneuvers):
        z = rng.standard_normal(n) * sd
        for t in range(n):
            e[g * n + t] = (rho * e[g * n + t - 1] if t else 0.0) + z[t]
    return x, 2.0 * np.exp(-1.3 * x) + 0.5 + e, list(range(n, maneuvers * n, n))


def fitted(seed: int, sd: float, covariance: str = "hac-maneuver", bounds=None):
    x, y, segments = decay(seed, sd)
    start = 1.0 if bounds is None else bounds["b"][0]
    result = MODEL.fit({"x": x}, y, start={"b": start}, covariance=covariance, segments=segments, bounds=bounds)
    return MODEL.bind({"x": x}), y, result


def test_the_profile_interval_is_the_wald_interval_where_the_model_is_linear_over_it():
    """Tiny noise: the model is linear over the interval, so the profile interval equals the Wald interval (the
    hac-maneuver one, t quantile on its dof) to a small fraction of its half width, at both levels. Without the
    variance ratio c_j (the plain likelihood ratio) it would be the white interval, sqrt(c_j) times narrower."""
    problem, y, result = fitted(1, 1e-4)
    p = profile(problem, y, result.estimates)["b"]
    assert p.variance_ratio > 2.0          # the coloured noise: the reported variance is several white ones
    for level in (0.95, 0.68):
        i = p.interval(level)
        half = 0.5 * (i.wald_high - i.wald_low)
        ci = result.conf_int(level).loc["b"]
        assert (i.wald_low, i.wald_high) == pytest.approx((ci["lower"], ci["upper"]), rel=1e-12)
        assert abs(i.low - i.wald_low) < 2e-3 * half and abs(i.high - i.wald_high) < 2e-3 * half
        assert not (i.open_low or i.open_high) and i.reason_low is None and i.reason_high is None
    # the white covariance's profile is the white Wald interval: c_j = 1, the plain likelihood ratio
    white_problem, white_y, white = fitted(1, 1e-4, covariance="white")
    w = profile(white_problem, white_y, white.estimates)["b"]
    assert w.variance_ratio == pytest.approx(1.0, rel=1e-6)
    wi = w.interval(0.95)
    assert wi.high - wi.low == pytest.approx(wi.wald_high - wi.wald_low, rel=2e-3)


def test_the_statistic_is_zero_at_the_estimate_and_the_critical_value_at_the_bounds():
    problem, y, result = fitted(0, 0.1)
    profiles = profile(problem, y, result.estimates)
    p = profiles["b"]
    i95, i68 = p.interval(0.95), p.interval(0.68)
    stat = profile_statistic(problem, y, result.estimates, "b", [p.estimate, i95.low, i95.high, i68.low, i68.high])
    assert abs(stat[0]) < 1e-6
    assert stat[1:3] == pytest.approx([i95.critical ** 2] * 2, rel=0.01)
    assert stat[3:] == pytest.approx([i68.critical ** 2] * 2, rel=0.01)
    assert i95.low < i68.low < p.estimate < i68.high < i95.high
    # the profiled points: the signed root rises through 0 at the estimate
    assert np.all(np.diff(p.values) > 0) and np.all(np.diff(p.signed_root) > 0)
    assert p.signed_root[list(p.values).index(p.estimate)] == 0.0
    assert profiles.to_dict()["parameters"]["b"]["level"] == 0.95


def test_a_skewed_estimator_gets_an_asymmetric_interval():
    """Large noise: the decay rate's estimator is skewed; the profile interval reaches further up than down, and
    both of its bounds lie above the symmetric Wald interval's."""
    problem, y, result = fitted(0, 0.3)
    p = profile(problem, y, result.estimates)["b"]
    i = p.interval(0.95)
    assert (i.high - p.estimate) / (p.estimate - i.low) > 1.15
    assert i.high > i.wald_high + 0.02 and i.low > i.wald_low + 0.02
    assert not (i.open_low or i.open_high)


def test_a_box_edge_before_the_crossing_opens_that_side():
    problem, y, result = fitted(0, 0.1)
    est, wald_low = result.params["b"], result.conf_int(0.95).loc["b", "lower"]
    edge = est - 0.5 * (est - wald_low)
    problem, y, boxed = fitted(0, 0.1, bounds={"b": (edge, 20.0)})
    assert boxed.params["b"] == pytest.approx(est, rel=1e-6)
    i = profile(problem, y, boxed.estimates)["b"].interval(0.95)
    assert i.open_low and i.low == edge and "lower edge" in i.reason_low
    assert not i.open_high and i.reason_high is None and i.high > est
    # an estimate on the edge: that side is open at once
    problem, y, on_edge = fitted(0, 0.1, bounds={"b": (est + 0.01, 20.0)})
    j = profile(problem, y, on_edge.estimates)["b"].interval(0.68)
    assert j.open_low and "estimate is on the box's lower edge" in j.reason_low and not j.open_high


class _BrokenAbove(SeparableProblem):
    """The decay problem, with a regression matrix that is not finite above ``limit``."""

    def __init__(self, problem, limit):
        self.problem, self.limit = problem, limit
        self.nonlinear_names, self.linear_names = problem.nonlinear_names, problem.linear_names

    def evaluate(self, theta):
        ev = self.problem.evaluate(theta)
        if theta[0] > self.limit:
            return Evaluation(np.full_like(ev.phi, np.nan), ev.dphi, ev.rows, ev.params)
        return ev


def test_a_failed_refit_gives_nan_with_the_reason_never_zero():
    problem, y, result = fitted(0, 0.1)
    est = result.params["b"]
    broken = _BrokenAbove(problem, est + 0.01)
    p = profile(broken, y, result.estimates)["b"]
    i = p.interval(0.95)
    assert np.isnan(i.high) and not i.open_high and "refit at b" in i.reason_high
    assert np.isfinite(i.low) and i.reason_low is None
    assert json.loads(json.dumps(p.to_dict()))["high"] is None


def test_profile_intervals_of_a_two_state_model_with_warm_started_nuisances():
    """The multi-parameter path: two decay rates, each profiled with the other refitted by the VP solve."""
    rng = np.random.default_rng(4)
    x = np.linspace(0.0, 5.0, 400)
    y = 2.0 * np.exp(-0.7 * x) + 1.0 * np.exp(-3.0 * x) + rng.standard_normal(400) * 0.01
    model = SeparableModel({"c1": "exp(-b1*x)", "c2": "exp(-b2*x)"}, variables=["x"],
                           bounds={"b1": (0.05, 2.0), "b2": (2.0, 10.0)})
    result = model.fit({"x": x}, y, start={"b1": 0.5, "b2": 4.0}, covariance="white")
    profiles = profile(model.bind({"x": x}), y, result.estimates, levels=(0.95,))
    assert profiles.names == ("b1", "b2")
    for p in profiles.parameters:
        i = p.interval(0.95)
        assert i.low < p.estimate < i.high and p.refits > 2
        half = 0.5 * (i.wald_high - i.wald_low)
        assert abs(i.low - i.wald_low) < 0.2 * half and abs(i.high - i.wald_high) < 0.2 * half
    with pytest.raises(ValueError, match="not a nonlinear parameter"):
        profile(model.bind({"x": x}), y, result.estimates, ["c1"])


def test_fit_profile_writes_the_fields(campaign_on_disk, run_cli, tmp_path):
    campaign = campaign_on_disk(seed=2, scale=0.05)   # the joint tests' campaign: flown once per process
    out = tmp_path / "fit"
    # one steady state (a1, a_star): the lightest structure with nonlinear parameters
    proc = run_cli("fit", "--data", campaign.directory, "--model", "X S", "--starts", "1", "--profile",
                   "--out", out)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((out / "fit.json").read_text(), parse_constant=lambda c: pytest.fail(c))
    prof = doc["profile"]
    assert prof["levels"] == [0.95, 0.68] and prof["covariance"] == "hac-maneuver"
    assert set(prof["parameters"]) == {"a1", "a_star"}
    for name, p in prof["parameters"].items():
        assert {"low", "high", "level", "open_low", "open_high", "wald_low", "wald_high", "reason_low",
                "reason_high", "variance_ratio", "dof", "levels"} <= set(p)
        assert p["level"] == 0.95 and set(p["levels"]) == {"0.95", "0.68"}
        lo, hi = p["low"], p["high"]
        assert lo is not None and hi is not None and lo <= p["estimate"] <= hi
        # a side is open exactly when it says why, and an open side is the box edge
        for side in ("low", "high"):
            assert (p[f"reason_{side}"] is not None) >= p[f"open_{side}"]
    text = (out / "fit.md").read_text()
    assert "## Profile intervals of the nonlinear parameters" in text and "95% Wald" in text
    # the model as an equation, in its parameters' names and with the estimates in their place
    assert "X = 0.5*(1 - tanh(a1*(alpha - a_star)))" in text
    a1, a_star = doc["params"]["a1"], doc["params"]["a_star"]
    assert f"X = 0.5*(1 - tanh({a1:.4g}*(alpha - {a_star:.4g})))" in text
    # the numbers are the fit's own: the Wald interval is estimate +- t(dof) * stderr of the same fit.json, and the
    # profile bounds are those the Python API computes on the same campaign
    from scipy import stats
    import structsearch
    api = structsearch.fit(campaign.directory, "X S", settings=structsearch.Settings(starts=1), profile=True).profile
    for name, p in prof["parameters"].items():
        assert p["estimate"] == pytest.approx(doc["params"][name], rel=1e-12)
        assert p["dof"] == pytest.approx(doc["reference_dof"][name])
        q = stats.t.ppf(0.975, doc["reference_dof"][name])
        assert p["wald_low"] == pytest.approx(doc["params"][name] - q * doc["stderr"][name], rel=1e-9)
        assert p["wald_high"] == pytest.approx(doc["params"][name] + q * doc["stderr"][name], rel=1e-9)
        mine = api[name].interval(0.95)
        assert (p["low"], p["high"]) == pytest.approx((mine.low, mine.high), rel=1e-9)


def test_fit_profile_is_refused_with_a_joint_fit(tmp_path, capsys):
    from structsearch.cli import main
    code = main(["fit", "--data", str(tmp_path / "none"), "--joint", "CL-VI,CD-IXr", "--profile", "--out",
                 str(tmp_path)])
    assert code == 2 and "--profile goes with --model" in capsys.readouterr().err


def test_a_model_without_nonlinear_parameters_has_an_empty_profile_section():
    from structsearch.reporting.profile_doc import profile_table
    text = profile_table(Profiles((), (0.95,), 1.0, 0.1, "hac-maneuver"))
    assert "no nonlinear parameter of its own" in text


def test_profile_calibration_rows_from_known_draws():
    """Coverage, misses, open sides and the Wald intervals on the same campaigns, from constructed records."""
    from structsearch.experiments.calibration import CampaignDraw
    from structsearch.experiments.calibration_profile import profile_rows
    truth = {"CL": {"tau1_ss": 0.4}}
    names = {"CL": "CL-VI"}
    # (estimate, 95 % (low, high, open_low, open_high, wald_low, wald_high), 68 % (...))
    cases = [(0.40, (0.30, 0.55, False, False, 0.25, 0.55), (0.35, 0.45, False, False, 0.33, 0.47)),
             (0.50, (0.42, 0.70, False, False, 0.35, 0.65), (0.45, 0.58, False, False, 0.43, 0.57)),   # misses low
             (0.30, (0.00, 0.45, True, False, 0.10, 0.50), (0.20, 0.38, False, False, 0.22, 0.38))]    # open low
    draws = [CampaignDraw(seed=i, samples=1, estimates={}, stderr={}, gap_p={},
                          profiles={"CL-VI": {"tau1_ss": {"estimate": e, "0.95": a, "0.68": b}}})
             for i, (e, a, b) in enumerate(cases)]
    draws.append(CampaignDraw(seed=9, samples=1, estimates={}, stderr={}, gap_p={}))   # not profiled
    (row,) = profile_rows(draws, truth, names)
    assert row.n == 3 and row.coverage95 == pytest.approx(2 / 3) and row.wald_coverage95 == 1.0
    assert row.coverage68 == pytest.approx(1 / 3) and row.wald_coverage68 == pytest.approx(1 / 3)
    assert (row.misses_low95, row.misses_high95, row.wald_misses_low95) == (1, 0, 0)
    assert row.open95 == 1 and row.open68 == 0
    assert row.asymmetry95 == pytest.approx(1.5)   # median of 1.5, 2.5, 0.5
    # calibration.json's profile and calibration.md's section from the same draws
    from types import SimpleNamespace
    from structsearch.experiments.calibration_profile import profile_dict, profile_lines
    for d in draws[:3]:
        object.__setattr__(d, "profile_seconds", 2.0)
    cal = SimpleNamespace(draws=draws, default_kind="hac-maneuver")
    doc = json.loads(json.dumps(profile_dict(cal, truth, names)))
    assert doc["campaigns"] == 3 and doc["seeds"] == [0, 1, 2] and doc["seconds_per_campaign"] == 2.0
    assert doc["pooled_coverage_95"] == pytest.approx(2 / 3) and doc["pooled_wald_coverage_95"] == 1.0
    assert doc["parameters"][0]["misses_low_95"] == 1
    text = "\n".join(profile_lines(cal, truth, names))
    assert "## Profile intervals of the nonlinear parameters" in text and "profile **0.667**, Wald 1.000" in text
    assert profile_dict(SimpleNamespace(draws=draws[3:], default_kind="hac-maneuver"), truth, names) is None


def test_the_light_default_equals_its_owner():
    from structsearch.cli import options as cli_options
    from structsearch.experiments.calibration_profile import PROFILE_CAMPAIGNS
    assert cli_options.PROFILE_CAMPAIGNS == PROFILE_CAMPAIGNS
