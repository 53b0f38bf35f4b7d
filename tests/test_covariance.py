"""Covariance formulas: Monte Carlo checks (thesis Table 8.2 style) and an independent dense implementation."""
import numpy as np
import pytest
from scipy.linalg import block_diag, toeplitz

from structsearch.data.flightdata import FlightData
from structsearch.engine.statistics import autocovariance, colored_covariance, lag_weights, white_covariance
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
    fits = [model.fit(_with_noise(base, clean, 1000 + i, 0.9, 0.03), start=start) for i in range(N_REFITS)]
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
    fits = [model.fit(_with_noise(base, clean, 50 + i, 0.95, 0.02)) for i in range(N_REFITS)]
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
