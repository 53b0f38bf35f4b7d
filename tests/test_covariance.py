"""Covariance formulas: Monte Carlo checks (thesis Table 8.2 style) and an independent dense implementation."""
import numpy as np
import pytest
from scipy import stats
from scipy.linalg import block_diag, toeplitz

from structsearch.data.flightdata import FlightData
from structsearch.engine.separation import static_separation
from structsearch.engine.statistics import (andrews_bandwidth, autocovariance, cluster_covariance, cluster_meat,
                                            colored_covariance, effective_maneuvers, hac_covariance,
                                            kernel_weights, lag_weights, reference_dof, white_covariance)
from structsearch.engine.stallmodel import StallModel
from structsearch.flight.synthetic import ar1_noise, campaign

N_REFITS = 200
TRUTH = {"tau1": 0.3, "tau2": 0.1, "a1": 30.0, "a_star": 0.2, "CL0": 0.2, "CL_KL": 5.0, "CL_de": -0.4}


def _with_noise(base, clean, seed, phi, sigma):
    rng = np.random.default_rng(seed)
    noise = np.concatenate([ar1_noise(rng, sl.stop - sl.start, phi, sigma) for sl in base.segment_slices()])
    cols = dict(base.columns)
    cols["CL"] = clean + noise
    return FlightData(cols, base.starts, base.names, base.source, base.constants)


@pytest.fixture(scope="module")
def monte_carlo():
    model = StallModel.declare("CL-II+de", "CL", states={"": "U"},
                               regressors={"CL0": "1", "CL_KL": "K_L(X)", "CL_de": "de"})
    base = campaign({"dynamic": 2, "deep-dynamic": 1, "quasi-steady": 1}, duration=40.0, seed=21)
    clean = model.predict(base, TRUTH)
    start = {k: TRUTH[k] for k in model.nonlinear_names}
    fits = [model.fit(_with_noise(base, clean, 1000 + i, 0.9, 0.03), start=start, covariance="colored")
            for i in range(N_REFITS)]
    return model, fits


def test_colored_covariance_matches_monte_carlo_spread(monte_carlo):
    model, fits = monte_carlo
    estimates = np.array([f.values for f in fits])
    spread = estimates.std(axis=0, ddof=1)
    colored = np.array([[f.stderr[n] for n in f.names] for f in fits])
    # the typical reported standard deviation, and the one of a single fit
    assert np.all(np.abs(colored.mean(axis=0) / spread - 1) < 0.2), colored.mean(axis=0) / spread
    assert np.all(np.abs(colored[0] / spread - 1) < 0.2), colored[0] / spread
    # the estimates scatter around the truth (no bias beyond the spread)
    truth = np.array([TRUTH[n] for n in fits[0].names])
    assert np.all(np.abs(estimates.mean(axis=0) - truth) < 3 * spread / np.sqrt(N_REFITS) + 1e-3 * np.abs(truth))


def test_white_covariance_underestimates_colored_noise(monte_carlo):
    _, fits = monte_carlo
    spread = np.array([f.values for f in fits]).std(axis=0, ddof=1)
    white = np.array([[f.white_stderr[n] for n in f.names] for f in fits]).mean(axis=0)
    assert np.all(white / spread < 0.5), white / spread


def test_ols_colored_covariance_monte_carlo():
    """Eq. 22: OLS with AR(1) residuals."""
    model = StallModel.declare("lin", "CL", regressors={"c0": "1", "ca": "alpha", "cd": "de", "cq": "qstar"})
    base = campaign({"quasi-steady": 2, "dynamic": 2}, duration=30.0, seed=5)
    clean = model.predict(base, {"c0": 0.2, "ca": 5.0, "cd": -0.4, "cq": 8.0})
    fits = [model.fit(_with_noise(base, clean, 50 + i, 0.95, 0.02), covariance="colored") for i in range(N_REFITS)]
    spread = np.array([f.values for f in fits]).std(axis=0, ddof=1)
    colored = np.array([[f.stderr[n] for n in f.names] for f in fits]).mean(axis=0)
    white = np.array([[f.white_stderr[n] for n in f.names] for f in fits]).mean(axis=0)
    assert np.all(np.abs(colored / spread - 1) < 0.2), colored / spread
    assert np.all(white / spread < 0.5)


def test_fft_sandwich_equals_dense_toeplitz():
    rng = np.random.default_rng(12)
    bounds = np.array([0, 150, 400])
    m, p = 400, 4
    jac = rng.standard_normal((m, p))
    residual = np.concatenate([ar1_noise(rng, 150, 0.8, 1.0), ar1_noise(rng, 250, 0.8, 1.0)])
    for max_lag in (0, 7, "full"):
        cov, lags = colored_covariance(jac, residual, bounds, max_lag)
        # independent: autocovariance by direct sums, dense block-diagonal Toeplitz
        lam = np.zeros(lags + 1)
        for s, e in zip(bounds[:-1], bounds[1:]):
            r = residual[s:e]
            for k in range(min(lags, e - s - 1) + 1):
                lam[k] += r[:len(r) - k] @ r[k:]
        lam = lam / m * lag_weights(lags, max_lag)
        blocks = []
        for s, e in zip(bounds[:-1], bounds[1:]):
            col = np.zeros(e - s)
            n = min(lags + 1, e - s)
            col[:n] = lam[:n]
            blocks.append(toeplitz(col))
        big = block_diag(*blocks)
        a_inv = np.linalg.inv(jac.T @ jac)
        dense = a_inv @ jac.T @ big @ jac @ a_inv
        assert np.allclose(cov, dense, rtol=1e-10, atol=1e-14), max_lag
    assert np.allclose(autocovariance(residual, bounds, 3)[0], residual @ residual / m)


def test_white_covariance_is_s2_inverse_normal_matrix():
    rng = np.random.default_rng(13)
    jac = rng.standard_normal((100, 3)) * [1.0, 1e3, 1e-3]
    residual = rng.standard_normal(100)
    expect = residual @ residual / 97 * np.linalg.inv(jac.T @ jac)
    assert np.allclose(white_covariance(jac, residual), expect, rtol=1e-10)


# ----- HAC sandwich -------------------------------------------------------------------------------
def _dense_hac(jac, residual, bounds, weights_of_lag):
    """sum over maneuvers of sum_t sum_s w(|t-s|) g_t g_s^T, by an explicit double loop."""
    g = jac * residual[:, None]
    meat = np.zeros((jac.shape[1], jac.shape[1]))
    for s, e in zip(bounds[:-1], bounds[1:]):
        for i in range(s, e):
            for j in range(s, e):
                w = weights_of_lag(abs(i - j))
                if w:
                    meat += w * np.outer(g[i], g[j])
    a_inv = np.linalg.inv(jac.T @ jac)
    m, p = jac.shape
    return a_inv @ meat @ a_inv * m / (m - p)


def _qs(x):
    """Andrews (1991) quadratic-spectral kernel as printed there."""
    if x == 0:
        return 1.0
    y = 6 * np.pi * x / 5
    return 25 / (12 * np.pi ** 2 * x ** 2) * (np.sin(y) / y - np.cos(y))


@pytest.mark.parametrize("kind,bandwidth", [("hac", 6.5), ("hac-qs", 4.0), ("hac", None), ("hac-qs", None),
                                            ("hac-maneuver", None), ("hac", 95.0)])
def test_hac_equals_a_dense_double_sum(kind, bandwidth):
    rng = np.random.default_rng(31)
    bounds = np.array([0, 60, 140, 150])
    m, p = 150, 3
    jac = rng.standard_normal((m, p)) + np.linspace(0, 2, m)[:, None]
    residual = ar1_noise(rng, m, 0.7, 1.0) * np.linspace(0.2, 2.0, m)  # heteroscedastic and coloured
    cov, b = hac_covariance(jac, residual, bounds, kind, bandwidth)
    if bandwidth is not None:
        assert b == bandwidth
    if kind == "hac-maneuver":
        assert b == 80  # the longest maneuver: every lag inside it carries weight
    kernel = (lambda j: max(1 - j / b, 0.0)) if kind != "hac-qs" else (lambda j: _qs(j / b))
    assert np.allclose(cov, _dense_hac(jac, residual, bounds, kernel), rtol=1e-9, atol=1e-14)


def test_full_window_bartlett_sums_equal_the_dense_double_sum_per_maneuver():
    """The running-sum form (used when the bandwidth covers every maneuver) against the double sum."""
    from structsearch.engine.statistics import bartlett_maneuver_sums
    rng = np.random.default_rng(8)
    bounds = np.array([0, 7, 57, 58, 130])
    g = rng.standard_normal((130, 3)) + 2.0 * np.sin(np.arange(130) / 9.0)[:, None]
    b = 75.0
    sums = bartlett_maneuver_sums(g, bounds, b)
    diagonals = bartlett_maneuver_sums(g, bounds, b, diagonal=True)
    for i, (s, e) in enumerate(zip(bounds[:-1], bounds[1:])):
        dense = sum((1 - abs(t - u) / b) * np.outer(g[t], g[u]) for t in range(s, e) for u in range(s, e))
        assert np.allclose(sums[i], dense, rtol=1e-11, atol=1e-11)
        assert np.allclose(diagonals[i], np.diag(dense), rtol=1e-11, atol=1e-11)
    with pytest.raises(ValueError, match="shorter than maneuver"):
        bartlett_maneuver_sums(g, bounds, 50.0)


def test_quadratic_spectral_weights_match_andrews():
    w = kernel_weights("quadratic-spectral", 3.0, 40)
    assert np.allclose(w, [_qs(j / 3.0) for j in range(41)], rtol=1e-12, atol=1e-15)
    assert np.allclose(kernel_weights("bartlett", 4.0, 6), [1, 0.75, 0.5, 0.25, 0, 0, 0])


def test_andrews_bandwidth_for_an_ar1_score():
    rng = np.random.default_rng(8)
    rho, n = 0.7, 200_000
    scores = ar1_noise(rng, n, rho, 1.0)[:, None]
    alpha1 = 4 * rho ** 2 / ((1 - rho) ** 2 * (1 + rho) ** 2)   # sigma cancels for one column
    alpha2 = 4 * rho ** 2 / (1 - rho) ** 4
    bounds = np.array([0, n])
    assert andrews_bandwidth(scores, bounds, "bartlett") == pytest.approx(1.1447 * (alpha1 * n) ** (1 / 3), rel=0.05)
    assert andrews_bandwidth(scores, bounds, "quadratic-spectral") == pytest.approx(
        1.3221 * (alpha2 * n) ** (1 / 5), rel=0.05)


def test_hac_is_positive_semidefinite_on_oscillating_residuals():
    """Buffet-like residuals: a narrow-band oscillation whose amplitude grows along the maneuver."""
    rng = np.random.default_rng(4)
    m = 3000
    t = np.arange(m) * 0.01
    jac = np.column_stack([np.ones(m), t, np.sin(0.7 * t), rng.standard_normal(m)])
    residual = np.sin(2 * np.pi * 12 * t + rng.uniform(0, 6)) * (0.1 + t / 30) + 0.01 * rng.standard_normal(m)
    for kind in ("hac", "hac-qs", "hac-maneuver"):
        for bandwidth in (None, 3.0, 40.0, 500.0):
            cov, _ = hac_covariance(jac, residual, np.array([0, 1200, m]), kind, bandwidth)
            eig = np.linalg.eigvalsh(cov)
            assert eig.min() >= -1e-12 * eig.max(), (kind, bandwidth, eig)


@pytest.fixture(scope="module")
def heteroscedastic_monte_carlo():
    """OLS on flight-like kinematics; AR(1) noise whose level grows with flow separation (buffet)."""
    model = StallModel.declare("lin", "CL", regressors={"c0": "1", "ca": "alpha", "cd": "de", "cq": "qstar"})
    base = campaign({"quasi-steady": 2, "dynamic": 2}, duration=30.0, seed=5)
    clean = model.predict(base, {"c0": 0.2, "ca": 5.0, "cd": -0.4, "cq": 8.0})
    level = 0.005 + 0.05 * (1 - static_separation(base["alpha"], 30.0, 0.2))
    estimates, stderr = [], {k: [] for k in ("colored", "hac", "hac-qs")}
    for i in range(N_REFITS):
        rng = np.random.default_rng(50 + i)
        noise = np.concatenate([ar1_noise(rng, sl.stop - sl.start, 0.95, 1.0) for sl in base.segment_slices()])
        data = FlightData({**base.columns, "CL": clean + noise * level}, base.starts, base.names, base.source,
                          base.constants)
        for kind in stderr:
            fit = model.fit(data, covariance=kind)
            stderr[kind].append([fit.stderr[n] for n in fit.names])
        estimates.append(fit.values)
    spread = np.array(estimates).std(axis=0, ddof=1)
    return {k: np.array(v) / spread for k, v in stderr.items()}


@pytest.mark.parametrize("kind", ["hac", "hac-qs"])
def test_hac_matches_monte_carlo_spread_under_heteroscedastic_noise(heteroscedastic_monte_carlo, kind):
    ratio = heteroscedastic_monte_carlo[kind]
    assert np.all(np.abs(ratio.mean(axis=0) - 1) < 0.15), ratio.mean(axis=0)


def test_stationary_sandwich_misjudges_heteroscedastic_noise(heteroscedastic_monte_carlo):
    """The reason HAC exists: the Toeplitz estimate assumes one noise level for the whole record."""
    ratio = heteroscedastic_monte_carlo["colored"].mean(axis=0)
    assert np.max(np.abs(ratio - 1)) > 0.3, ratio


def test_cluster_meat_sums_scores_per_maneuver():
    rng = np.random.default_rng(8)
    scores, bounds = rng.standard_normal((50, 3)), np.array([0, 10, 25, 50])
    sums = [scores[s:e].sum(axis=0) for s, e in zip(bounds[:-1], bounds[1:])]
    dense = sum(np.outer(v, v) for v in sums) * 3 / 2
    assert np.allclose(cluster_meat(scores, bounds), dense, rtol=1e-12)


def test_cluster_covariance_sees_a_maneuver_level_error():
    """Each maneuver carries its own sensor bias (a constant error) on top of white noise: the clustered
    sandwich matches the Monte Carlo spread, a short-memory HAC does not."""
    rng_design = np.random.default_rng(21)
    g, n = 40, 60
    bounds = np.arange(0, g * n + 1, n)
    x = rng_design.standard_normal((g * n, 2)) + np.repeat(rng_design.standard_normal((g, 2)), n, axis=0)
    jac = np.column_stack([np.ones(g * n), x])
    estimates, sd = [], {"cluster": [], "hac": []}
    for i in range(400):
        rng = np.random.default_rng(300 + i)
        y = jac @ np.array([0.1, 1.0, -0.5]) + np.repeat(0.3 * rng.standard_normal(g), n) \
            + 0.5 * rng.standard_normal(g * n)
        coef, *_ = np.linalg.lstsq(jac, y, rcond=None)
        residual = y - jac @ coef
        estimates.append(coef)
        sd["cluster"].append(np.sqrt(np.diag(cluster_covariance(jac, residual, bounds))))
        sd["hac"].append(np.sqrt(np.diag(hac_covariance(jac, residual, bounds, "hac")[0])))
    spread = np.std(estimates, axis=0, ddof=1)
    cluster = np.mean(sd["cluster"], axis=0) / spread
    assert np.all(np.abs(cluster - 1) < 0.15), cluster
    assert np.mean(sd["hac"], axis=0)[1] / spread[1] < 0.8


def test_hac_maneuver_intervals_cover_slow_heteroscedastic_errors():
    """Slow errors (a random walk inside each maneuver, the simulator's drift) whose level differs
    between maneuvers, 8 maneuvers: estimate +- t_{G-1} x the hac-maneuver standard deviation covers
    the truth about 95 % of the time, while Andrews' data-driven bandwidth cuts the slow part off."""
    rng_design = np.random.default_rng(22)
    g, n = 8, 200
    bounds = np.arange(0, g * n + 1, n)
    x = rng_design.standard_normal((g * n, 1)) + np.repeat(rng_design.standard_normal((g, 1)), n, axis=0)
    jac = np.column_stack([np.ones(g * n), x])
    level = np.repeat(rng_design.uniform(0.5, 2.0, g), n)
    truth = np.array([0.1, 1.0])
    hits = {"hac-maneuver": [], "hac": []}
    for i in range(400):
        rng = np.random.default_rng(900 + i)
        walk = np.cumsum(rng.standard_normal((g, n)), axis=1).ravel() / np.sqrt(n)
        y = jac @ truth + level * (walk + 0.5 * rng.standard_normal(g * n))
        coef, *_ = np.linalg.lstsq(jac, y, rcond=None)
        residual = y - jac @ coef
        for kind in hits:
            effective = effective_maneuvers(jac, jac * residual[:, None], bounds, kind)
            dof = [reference_dof(kind, g * n, 2, e) for e in effective]
            sd = np.sqrt(np.diag(hac_covariance(jac, residual, bounds, kind)[0]))
            hits[kind].append(np.abs(coef - truth) <= stats.t.ppf(0.975, dof) * sd)
    coverage = {k: np.mean(v, axis=0) for k, v in hits.items()}
    assert np.all((coverage["hac-maneuver"] > 0.91) & (coverage["hac-maneuver"] < 0.99)), coverage
    assert np.all(coverage["hac"] < 0.85), coverage


def test_effective_maneuvers_count_the_maneuvers_that_inform_a_parameter():
    """Equal maneuvers: G; a column that only one maneuver excites: 1 (Satterthwaite's formula)."""
    rng = np.random.default_rng(5)
    g, n = 6, 50
    bounds = np.arange(0, g * n + 1, n)
    ones = np.ones(g * n)
    local = np.zeros(g * n)
    local[2 * n:3 * n] = rng.standard_normal(n)
    local[2 * n:3 * n] -= local[2 * n:3 * n].mean()   # orthogonal to the constant: A is diagonal
    jac = np.column_stack([ones, local])
    scores = jac * np.tile(rng.standard_normal(n), g)[:, None]   # every maneuver the same residual
    for kind in ("cluster", "hac-maneuver"):
        effective = effective_maneuvers(jac, scores, bounds, kind)
        assert effective[1] == pytest.approx(1.0, rel=1e-9)
    # column 0 alone: every maneuver carries the same share
    assert effective_maneuvers(jac[:, :1], scores[:, :1], bounds, "cluster")[0] == pytest.approx(g)


def test_the_scaled_factor_from_a_pivoted_projection_is_the_direct_one():
    """An OLS fit takes the column-scaled factor from its pivoted QR (p x p work): R^-1 R^-T, singular values
    and the covariance equal those of a direct QR of the scaled regressors, for columns of very different
    sizes and a nearly collinear pair."""
    from scipy.linalg import qr as direct_qr
    from structsearch.engine.snls import project
    from structsearch.engine.statistics import inverse_factor, scaled_factor_from_qr
    rng = np.random.default_rng(8)
    base = rng.standard_normal((4000, 5))
    phi = np.column_stack([base[:, 0] * 1e3, base[:, 1], base[:, 1] + 1e-3 * base[:, 2], base[:, 3] * 1e-4,
                           np.ones(4000)])
    proj = project(phi, rng.standard_normal(4000))
    assert proj.rank == 5 and not np.array_equal(proj.columns, np.arange(5))  # pivoting reordered
    r, scale = scaled_factor_from_qr(phi, proj.r, proj.columns)
    norms = np.linalg.norm(phi, axis=0)
    direct = direct_qr(phi / norms, mode="r")[0][:5]
    assert np.allclose(scale, norms, rtol=1e-14)
    assert np.allclose(np.abs(r), np.abs(direct), rtol=1e-9, atol=1e-12)
    a, b = inverse_factor(phi, (r, scale)), inverse_factor(phi)
    assert np.allclose(a @ a.T, b @ b.T, rtol=1e-9)
    assert np.allclose(np.linalg.svd(r, compute_uv=False), np.linalg.svd(direct, compute_uv=False), rtol=1e-10)
