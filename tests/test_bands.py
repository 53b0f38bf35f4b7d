"""Uncertainty bands (issue 29): the delta method's arithmetic, each point's effective maneuvers, the static
curve's Jacobian against finite differences, Monte Carlo coverage, and what a band says where it cannot be
estimated."""
import numpy as np
import pytest
from scipy import stats

from structsearch.engine.bands import band, output_variance, point_effective_maneuvers, quantile
from structsearch.engine.sandwich import effective_maneuvers

from conftest import assert_matches_finite_difference


def test_output_variance_is_the_diagonal_of_j_c_jt_and_nan_where_an_unknown_parameter_acts():
    rng = np.random.default_rng(1)
    j = rng.standard_normal((7, 3))
    a = rng.standard_normal((3, 3))
    c = a @ a.T
    np.testing.assert_allclose(output_variance(j, c), np.diag(j @ c @ j.T), rtol=1e-12)
    c_nan = c.copy()
    c_nan[2, :] = c_nan[:, 2] = np.nan
    j[:3, 2] = 0.0    # the unknown parameter does not act on the first three points
    var = output_variance(j, c_nan)
    np.testing.assert_allclose(var[:3], np.diag(j[:3, :2] @ c[:2, :2] @ j[:3, :2].T), rtol=1e-12)
    assert np.all(np.isnan(var[3:]))   # never a zero-width band where it cannot be estimated


def test_quantiles_and_band_widths():
    assert quantile(0.95, np.inf) == pytest.approx(stats.norm.ppf(0.975))
    np.testing.assert_allclose(quantile(0.95, [1.0, 10.0]), stats.t.ppf(0.975, [1.0, 10.0]))
    with pytest.raises(ValueError, match="level"):
        quantile(1.5, 3.0)
    b = band(np.array([1.0, 2.0]), np.eye(2), np.diag([0.04, 0.09]), np.array([0.0, 0.16]), 0.95, np.inf)
    z = stats.norm.ppf(0.975)
    np.testing.assert_allclose(b.confidence_half_width, z * np.array([0.2, 0.3]))
    np.testing.assert_allclose(b.prediction_high - b.estimate, z * np.array([0.2, 0.5]))
    assert set(b.to_dict()) == {"estimate", "confidence_low", "confidence_high", "prediction_low",
                                "prediction_high"}


def test_a_points_effective_maneuvers_for_a_unit_gradient_are_the_parameters_own():
    rng = np.random.default_rng(5)
    g, n = 6, 80
    bounds = np.arange(0, g * n + 1, n)
    jac = np.column_stack([np.ones(g * n), rng.standard_normal(g * n), np.repeat(rng.standard_normal(g), n)])
    residual = rng.standard_normal(g * n)
    for kind in ("cluster", "hac-maneuver"):
        own = effective_maneuvers(jac, jac * residual[:, None], bounds, kind)
        points = point_effective_maneuvers(jac, residual, bounds, kind, np.eye(3))
        np.testing.assert_allclose(points, own, rtol=1e-10)
        # a combination is informed by at least as few maneuvers as G allows and at least one
        mixed = point_effective_maneuvers(jac, residual, bounds, kind, rng.standard_normal((5, 3)))
        assert np.all((mixed >= 1.0 - 1e-12) & (mixed <= g + 1e-12))


def test_the_confidence_band_of_a_linear_model_covers_its_truth_at_the_level():
    """Monte Carlo: y = Phi c + noise, OLS with its white covariance; the 95 % band of Phi(x) c at five
    points covers the truth in 95 % of 400 seeded draws (binomial 99.9 % range)."""
    rng = np.random.default_rng(29)
    x = np.linspace(-1, 1, 200)
    phi = np.column_stack([np.ones_like(x), x, x ** 2])
    coef = np.array([0.3, -1.0, 0.5])
    grid = np.column_stack([np.ones(5), np.linspace(-1, 1, 5), np.linspace(-1, 1, 5) ** 2])
    truth = grid @ coef
    hits = []
    for _ in range(400):
        y = phi @ coef + 0.2 * rng.standard_normal(len(x))
        c_hat, *_ = np.linalg.lstsq(phi, y, rcond=None)
        s2 = np.sum((y - phi @ c_hat) ** 2) / (len(x) - 3)
        cov = s2 * np.linalg.inv(phi.T @ phi)
        b = band(grid @ c_hat, grid, cov, np.full(5, s2), 0.95, len(x) - 3)
        hits.append((truth >= b.confidence_low) & (truth <= b.confidence_high))
    coverage = np.mean(hits, axis=0)
    lo, hi = stats.binom.ppf([0.0005, 0.9995], 400, 0.95) / 400
    assert np.all((coverage >= lo) & (coverage <= hi)), coverage


@pytest.fixture(scope="module")
def fitted_finals(simulated_campaign):
    from structsearch.experiments.calibration import TRUTH
    from structsearch.fitting.options import FitOptions
    from structsearch.thesis_study.thesis_estimator import fit_final_models
    campaign = simulated_campaign(seed=3, scale=0.1)
    train, val = campaign.split("train"), campaign.split("validation")
    finals = fit_final_models(train, val, FitOptions(n_starts=1, cv_folds=0), {c: dict(TRUTH[c]) for c in TRUTH})
    return train, finals


@pytest.mark.parametrize("coefficient", ["CL", "CD", "Cm"])
def test_the_static_curves_jacobian_is_its_finite_difference(fitted_finals, coefficient):
    from structsearch.fitting.bands import static_evaluation
    from structsearch.fitting.lift_fit import LiftFit
    train, finals = fitted_finals
    cand, fit = finals[coefficient]
    lift = LiftFit(*finals["CL"]) if cand.lift else None
    alpha, out, jac, names, held = static_evaluation(cand, fit.estimates.params, train, lift)
    assert len(alpha) == len(out) == jac.shape[0] and jac.shape[1] == len(names)
    assert alpha[0] == pytest.approx(train["alpha"].min()) and alpha[-1] == pytest.approx(train["alpha"].max())
    assert "V" in held and "CL" not in held

    def curve(values):
        return static_evaluation(cand, dict(zip(names, values)), train, lift, jacobian=False)[1]
    x = np.array([fit.estimates.params[n] for n in names])
    # the tolerance from the differences' own truncation and rounding errors: a fixed fraction of each column's
    # scale missed by 2e-9 on another BLAS kernel, where the steep sigmoid's curvature dominates the error
    assert_matches_finite_difference(jac, curve, x, rel=1e-5)
    # a static curve does not move with the lags, the pitch rate or the elevator: those columns are zero
    for n in names:
        if n.startswith(("tau1", "tau2")) or n.endswith(("_qstar", "_de")):
            assert not np.any(jac[:, names.index(n)]), n


def test_static_bands_of_the_final_models(fitted_finals):
    from structsearch.fitting.bands import static_bands
    from structsearch.fitting.lift_fit import LiftFit
    train, finals = fitted_finals
    lift = LiftFit(*finals["CL"])
    for coefficient, (cand, fit) in finals.items():
        b = static_bands(cand, fit, train, lift if cand.lift else None)
        band_ = b.band
        assert np.all(band_.confidence_low <= band_.estimate) and np.all(band_.estimate <= band_.confidence_high)
        # the prediction band holds the confidence band and the residual noise
        assert np.all(band_.prediction_low < band_.confidence_low)
        assert np.all(band_.prediction_high > band_.confidence_high)
        # per-maneuver covariance (the default): each point's dof from its effective maneuvers, at least 1
        assert np.all(band_.dof >= 1.0) and len(set(np.round(band_.dof, 6))) > 1
        doc = b.to_dict()
        assert doc["level"] == 0.95 and set(doc["static"]) >= {"alpha", "conditions", coefficient}
        assert len(doc["static"][coefficient]["dof"]) == len(doc["static"]["alpha"])
        # the noise variance of each alpha bin is the training residual's there: positive, larger in the stall
        noise = np.array([v for _, _, v in b.noise_bins])
        assert np.all(noise > 0) and noise[-1] > noise[0]


def test_the_static_jacobian_stays_finite_where_a_state_is_fully_stalled(fitted_finals):
    """With a steep stall-strip state (a1_ss = 3000) X_ss underflows to 0 beyond the stall; the regressor's value
    then uses the clipped state, which does not move, so its derivative is 0 there (not d sqrt(X)/dX at the
    floor, ~1e150, times a rounding-level dX)."""
    from structsearch.fitting.bands import static_evaluation
    train, finals = fitted_finals
    cand, fit = finals["CL"]
    params = dict(fit.estimates.params, a1_ss=3000.0)
    alpha, out, jac, names, _ = static_evaluation(cand, params, train)
    assert np.all(np.isfinite(jac)) and np.max(np.abs(jac)) < 1e6
    stalled = alpha > params["a_star_ss"] + 0.15
    assert stalled.any() and not np.any(jac[stalled, names.index("a_star_ss")])


def test_trace_bands_follow_a_validation_maneuver(fitted_finals, simulated_campaign):
    from structsearch.fitting.bands import trace_bands
    from structsearch.fitting.lift_fit import LiftFit
    from structsearch.fitting.models import predict_candidate
    train, finals = fitted_finals
    val = simulated_campaign(seed=3, scale=0.1).split("validation")
    one = val.select([0])
    lift = LiftFit(*finals["CL"])
    for coefficient, (cand, fit) in finals.items():
        use = lift if cand.lift else None
        b = trace_bands(cand, fit, train, one, use)
        assert len(b.estimate) == one.n_samples
        np.testing.assert_allclose(b.estimate, predict_candidate(cand, fit.estimates.params, one, use), rtol=1e-10,
                                   atol=1e-12)
        assert np.all(b.confidence_low <= b.estimate) and np.all(b.prediction_high > b.confidence_high)
        assert np.all(b.dof >= 1.0)


def test_bands_of_a_drag_structure_without_a_c_l_term(fitted_finals):
    """A drag structure fed a lift model's states but no C_L term (a discovered one): its grid still gets the lift
    model's C_L column, which the lift prediction replaces."""
    import dataclasses
    from structsearch.fitting.bands import static_bands
    from structsearch.fitting.candidate_fit import fit_candidate
    from structsearch.fitting.lift_fit import LiftFit
    from structsearch.fitting.options import FitOptions
    train, finals = fitted_finals
    cand = finals["CD"][0]
    no_cl = dataclasses.replace(cand, name="CD without CL", regressors=tuple(
        (n, e) for n, e in cand.regressors if "CL" not in e))
    lift = LiftFit(*finals["CL"])
    fit = fit_candidate(no_cl, train, train, lift, FitOptions(n_starts=1, cv_folds=0))
    b = static_bands(no_cl, fit, train, lift)
    assert np.all(np.isfinite(b.band.estimate)) and "CL" not in b.held


def test_a_point_without_degrees_of_freedom_has_no_band():
    """NaN dof (no maneuver's share computable): a NaN band, never the normal quantile's."""
    b = band(np.array([1.0, 2.0]), np.eye(2), np.diag([0.04, 0.09]), np.array([0.01, 0.01]), 0.95,
             np.array([np.nan, 5.0]))
    assert np.isnan(b.confidence_low[0]) and np.isnan(b.prediction_high[0])
    assert np.isfinite(b.confidence_low[1]) and b.confidence_half_width[1] == pytest.approx(
        stats.t.ppf(0.975, 5.0) * 0.3)


def test_parameter_draws_have_the_estimates_mean_and_covariance_and_hold_what_cannot_be_estimated():
    from structsearch.engine.bands import parameter_draws
    values = np.array([1.0, -2.0, 0.5])
    cov = np.array([[0.04, 0.018, np.nan], [0.018, 0.09, np.nan], [np.nan, np.nan, np.nan]])
    draws = parameter_draws(values, cov, 20_000, seed=1)
    assert draws.shape == (20_000, 3) and np.all(draws[:, 2] == 0.5)
    np.testing.assert_allclose(draws[:, :2].mean(axis=0), values[:2], atol=4 * 0.3 / np.sqrt(20_000))
    np.testing.assert_allclose(np.cov(draws[:, :2].T), cov[:2, :2], rtol=0.05)
    # the same seed, the same draws
    np.testing.assert_array_equal(parameter_draws(values, cov, 5, seed=7), parameter_draws(values, cov, 5, seed=7))
    with pytest.raises(ValueError, match="at least 2"):
        parameter_draws(values, cov, 1, seed=0)


def test_sampled_limits_are_null_where_a_draw_is_not_finite():
    from structsearch.engine.bands import sampled_limits
    samples = np.random.default_rng(0).standard_normal((1000, 3))
    samples[5, 1] = np.inf
    low, high = sampled_limits(samples, 0.95)
    assert np.isnan(low[1]) and np.isnan(high[1])
    np.testing.assert_allclose([low[0], high[0]], [-1.96, 1.96], atol=0.15)


def test_sampling_agrees_with_the_delta_method_where_the_curve_is_linear(fitted_finals):
    """A drag or pitch structure on its lift model's states is linear in its own parameters: parameter sampling
    must give the delta method's band (at the normal quantile) up to Monte Carlo error; the lift curve is not."""
    from structsearch.fitting.bands import static_bands
    from structsearch.fitting.lift_fit import LiftFit
    train, finals = fitted_finals
    lift = LiftFit(*finals["CL"])
    for coefficient in ("CD", "Cm"):
        cand, fit = finals[coefficient]
        b = static_bands(cand, fit, train, lift, samples=400, seed=2)
        ratio = b.sampled.ratio_to_delta
        # the 2.5 % and 97.5 % quantiles of 400 normal draws: within ~10 % of the exact ones
        assert np.nanmedian(ratio) == pytest.approx(1.0, abs=0.06) and np.nanmax(np.abs(ratio - 1)) < 0.2, coefficient
        doc = b.to_dict()["static"][coefficient]["sampled"]
        assert doc["draws"] == 400 and doc["seed"] == 2 and len(doc["confidence_low"]) == len(b.alpha)
