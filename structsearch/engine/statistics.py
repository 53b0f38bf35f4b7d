"""Parameter covariance and goodness of fit.

``colored`` (default) is the sandwich of the thesis' Eqs. 19 and 22,

    Cov = (F^T F)^-1 (F^T Lambda F) (F^T F)^-1,

with F = [DPhi c, Phi] the model Jacobian w.r.t. all parameters and Lambda the
Toeplitz matrix of the residual autocorrelation. Lambda is block diagonal over
maneuvers (residuals of different maneuvers are independent), and Lambda F is
computed by FFT convolution per maneuver, O(m log m). ``white`` is
s^2 (F^T F)^-1 with s^2 = RSS / (m - p).

The autocorrelation is the biased (1/m) estimate pooled over maneuvers. Using
every lag, as the thesis does, makes the estimate noisy and biased for
intercept-like columns (the sample autocovariances of a residual with zero mean
sum to zero), and truncating it abruptly can make variances negative when the
residuals oscillate (buffet). By default lags are kept up to four times the lag
from which the autocorrelation envelope stays inside the +-2/sqrt(m) white-noise
band, tapered by a Bartlett window (a positive semi-definite estimate).
``max_lag="full"`` reproduces the thesis (every lag, no taper).
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import qr, solve_triangular
from scipy.signal import fftconvolve


def autocovariance(residual: np.ndarray, bounds: np.ndarray, max_lag: int) -> np.ndarray:
    """lambda_0..lambda_max_lag, pooled over maneuvers, never across a boundary (biased, 1/m)."""
    acc = np.zeros(max_lag + 1)
    for i in range(len(bounds) - 1):
        seg = residual[int(bounds[i]):int(bounds[i + 1])]
        n = len(seg)
        nfft = 1 << int(np.ceil(np.log2(2 * n)))
        spec = np.fft.rfft(seg, nfft)
        full = np.fft.irfft(spec * np.conj(spec), nfft)
        upto = min(max_lag, n - 1)
        acc[:upto + 1] += full[:upto + 1]
    return acc / len(residual)


def choose_max_lag(residual: np.ndarray, bounds: np.ndarray, max_lag) -> int:
    """Resolve the ``max_lag`` option to a number of lags.

    Automatic rule: the first lag tau from which |rho| stays inside the
    +-2/sqrt(m) white-noise band over [tau, 2 tau] (an envelope, so oscillating
    residuals such as buffet are not cut at their first zero crossing), times four.
    """
    longest = int(np.max(np.diff(bounds))) - 1
    if max_lag == "full":
        return longest
    if max_lag is not None:
        return int(min(int(max_lag), longest))
    m = len(residual)
    lam = autocovariance(residual, bounds, longest)
    if lam[0] <= 0:
        return 0
    magnitude = np.abs(lam / lam[0])
    band = 2.0 / np.sqrt(m)
    # envelope[tau] = max |rho| over [tau, 2 tau]
    for tau in range(1, longest // 2 + 1):
        if magnitude[tau:2 * tau + 1].max() < band:
            return int(min(4 * tau, longest))
    return longest


def lag_weights(lags: int, max_lag) -> np.ndarray:
    """Bartlett taper 1 - k/(L+1), which keeps the estimate positive semi-definite; none for "full"."""
    if max_lag == "full":
        return np.ones(lags + 1)
    return 1.0 - np.arange(lags + 1) / (lags + 1.0)


def toeplitz_product(matrix: np.ndarray, lam: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Lambda @ matrix for the block-diagonal symmetric Toeplitz Lambda built from ``lam``."""
    out = np.empty_like(matrix)
    kernel_full = np.concatenate([lam[:0:-1], lam])
    for i in range(len(bounds) - 1):
        s, e = int(bounds[i]), int(bounds[i + 1])
        n = e - s
        lags = min(len(lam) - 1, n - 1)
        kernel = kernel_full[len(lam) - 1 - lags: len(lam) + lags]
        if lags == 0:
            out[s:e] = lam[0] * matrix[s:e]
        else:
            out[s:e] = fftconvolve(matrix[s:e], kernel[:, None], mode="same", axes=0)
    return out


def _inverse_factor(jac: np.ndarray) -> np.ndarray:
    """R^-1 of the thin QR of the column-scaled Jacobian, with the scaling folded back in."""
    scale = np.sqrt(np.sum(jac * jac, axis=0))
    scale[scale == 0] = 1.0
    r = qr(jac / scale, mode="r", check_finite=False)[0][: jac.shape[1]]
    r_inv = solve_triangular(r, np.eye(r.shape[0]), check_finite=False)
    return r_inv / scale[:, None]


def white_covariance(jac: np.ndarray, residual: np.ndarray) -> np.ndarray:
    m, p = jac.shape
    r_inv = _inverse_factor(jac)
    s2 = float(residual @ residual) / max(m - p, 1)
    return s2 * (r_inv @ r_inv.T)


def colored_covariance(jac: np.ndarray, residual: np.ndarray, bounds: np.ndarray, max_lag=None):
    """Toeplitz-autocorrelation sandwich; returns (covariance, number of lags used)."""
    lags = choose_max_lag(residual, bounds, max_lag)
    lam = autocovariance(residual, bounds, lags) * lag_weights(lags, max_lag)
    r_inv = _inverse_factor(jac)
    a_inv = r_inv @ r_inv.T
    middle = jac.T @ toeplitz_product(jac, lam, bounds)
    middle = 0.5 * (middle + middle.T)
    return a_inv @ middle @ a_inv, lags
