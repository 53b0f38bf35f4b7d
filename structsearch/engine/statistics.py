"""Parameter covariance and goodness of fit.

``hac-maneuver`` (below) is the default: it is the one estimate that met the calibration goals of
issue 11 on the flight simulator (``structsearch bench --calibration``, results/calibration.md).

``colored`` is the sandwich of the thesis' Eqs. 19 and 22,

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

``hac`` (Bartlett kernel) and ``hac-qs`` (quadratic-spectral kernel) are
heteroscedasticity- and autocorrelation-consistent sandwiches (Newey-West 1987,
Andrews 1991): the meat is sum_t sum_s w(|t-s|/b) g_t g_s^T over the scores
g_t = F_t r_t of each maneuver (never across a boundary), so noise whose level
changes along a maneuver (buffet growing with flow separation) is weighted where
it occurs, which the stationary Toeplitz estimate cannot do. Both kernels have a
non-negative spectral window, so the estimate is positive semi-definite by
construction. The bandwidth b follows Andrews' (1991) AR(1) plug-in rule on the
standardised score columns; the sums over lags are FFT convolutions per maneuver,
O(p m log m) plus O(p^2 m) for the products.

``hac-maneuver`` is the Bartlett sandwich with the bandwidth of the whole maneuver (b = 1 in the
fixed-b theory of Kiefer & Vogelsang 2002, "heteroskedasticity-autocorrelation robust testing
without truncation"): it needs no bandwidth rule, so it keeps the slow errors that data-driven
bandwidths cut off, and it stays positive semi-definite. Its noise is that of a few effective
observations per maneuver, so its t-tests and intervals use Student's t with G - 1 degrees of
freedom, as for clustered sandwiches (Cameron & Miller 2015), with G the effective number of
maneuvers behind each parameter (:func:`effective_maneuvers`: a deep-stall term that only two
maneuvers inform gets 1 dof, not G - 1); the other kinds use m - p. See :func:`reference_dof`.

``cluster`` sums the scores of each maneuver and allows any dependence inside it
(a per-maneuver sensor bias, for one); it needs more maneuvers than parameters.
Which estimate is the default is decided by ``structsearch bench --calibration``: ``colored``
under-reports intercept-like parameters (CL0, Cm0: 0.75 of the Monte Carlo spread, 95 % coverage
0.84), the data-driven HAC bandwidths cut the slow errors off (pooled coverage 0.83).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import qr, solve_triangular
from scipy.signal import fftconvolve


def cross_covariance(ra: np.ndarray, rb: np.ndarray, bounds: np.ndarray, max_lag: int) -> np.ndarray:
    """gamma(k) = (1/m) sum_t ra(t) rb(t + k) for k = -max_lag..max_lag, pooled over maneuvers and never
    across a boundary (biased, 1/m)."""
    out = np.zeros(2 * max_lag + 1)
    for i in range(len(bounds) - 1):
        a, b = ra[int(bounds[i]):int(bounds[i + 1])], rb[int(bounds[i]):int(bounds[i + 1])]
        n = len(a)
        nfft = 1 << int(np.ceil(np.log2(2 * n)))
        full = np.fft.irfft(np.conj(np.fft.rfft(a, nfft)) * np.fft.rfft(b, nfft), nfft)
        upto = min(max_lag, n - 1)
        out[max_lag:max_lag + upto + 1] += full[:upto + 1]                 # k >= 0
        if upto:
            out[max_lag - upto:max_lag] += full[nfft - upto:]              # k < 0
    return out / len(ra)


def autocovariance(residual: np.ndarray, bounds: np.ndarray, max_lag: int) -> np.ndarray:
    """lambda_0..lambda_max_lag, pooled over maneuvers, never across a boundary (biased, 1/m)."""
    return cross_covariance(residual, residual, bounds, max_lag)[max_lag:]


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


def shifted_product(matrix: np.ndarray, gamma: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """out_t = sum_k gamma(k) matrix_{t+k} within each maneuver (FFT convolution); ``gamma`` holds
    k = -L..L. With a symmetric gamma this is Lambda @ matrix for the block-diagonal Toeplitz Lambda."""
    lags = (len(gamma) - 1) // 2
    out = np.empty_like(matrix)
    for i in range(len(bounds) - 1):
        s, e = int(bounds[i]), int(bounds[i + 1])
        use = min(lags, e - s - 1)
        if use == 0:
            out[s:e] = gamma[lags] * matrix[s:e]
        else:  # convolution flips its kernel: hand it gamma reversed
            out[s:e] = fftconvolve(matrix[s:e], gamma[lags - use:lags + use + 1][::-1, None], mode="same", axes=0)
    return out


def toeplitz_product(matrix: np.ndarray, lam: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Lambda @ matrix for the block-diagonal symmetric Toeplitz Lambda built from ``lam`` (lags 0..L)."""
    return shifted_product(matrix, np.concatenate([lam[:0:-1], lam]), bounds)


def _column_scale(jac: np.ndarray) -> np.ndarray:
    """Column norms of the Jacobian, 1 for a zero column (it stays zero, and is named elsewhere)."""
    scale = np.sqrt(np.sum(jac * jac, axis=0))
    scale[scale == 0] = 1.0
    return scale


def scaled_factor(jac: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R of the thin QR of the Jacobian with unit-norm columns, and the column norms."""
    scale = _column_scale(jac)
    return qr(jac / scale, mode="r", check_finite=False)[0][: jac.shape[1]], scale


def scaled_factor_from_qr(jac: np.ndarray, r: np.ndarray, columns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`scaled_factor` of ``jac`` from a pivoted thin QR of it that kept every column
    (``jac[:, columns] = Q r``): jac D^-1 = Q (r P^T D^-1), so the QR of that p x p matrix has the same
    triangular factor up to the signs of its rows, which no estimator here sees (they use R^-1 R^-T,
    singular values and right singular vectors). p x p work instead of m x p."""
    scale = _column_scale(jac)
    unpivoted = np.empty_like(r)
    unpivoted[:, columns] = r
    return qr(unpivoted / scale, mode="r", check_finite=False)[0], scale


def inverse_factor(jac: np.ndarray, factor: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """R^-1 of the thin QR of the column-scaled Jacobian, with the scaling folded back in; ``factor``:
    (R, column norms) of :func:`scaled_factor` when the caller has it."""
    r, scale = scaled_factor(jac) if factor is None else factor
    r_inv = solve_triangular(r, np.eye(r.shape[0]), check_finite=False)
    return r_inv / scale[:, None]


def _sandwich(jac: np.ndarray, meat: np.ndarray, r_inv: np.ndarray | None = None) -> np.ndarray:
    """(F^T F)^-1 meat (F^T F)^-1, with the meat symmetrised. ``r_inv``: :func:`inverse_factor` of
    ``jac`` when the caller has it (one QR of an m x p Jacobian serves every estimator)."""
    r_inv = inverse_factor(jac) if r_inv is None else r_inv
    a_inv = r_inv @ r_inv.T
    return a_inv @ (0.5 * (meat + meat.T)) @ a_inv


def scaled_condition_number(jac: np.ndarray, factor: np.ndarray | None = None) -> float:
    """Condition number of the Jacobian with unit-norm columns (its thin-QR factor has the same one);
    ``factor``: that factor when the caller has it."""
    s = np.linalg.svd(scaled_factor(jac)[0] if factor is None else factor, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


def white_covariance(jac: np.ndarray, residual: np.ndarray, r_inv: np.ndarray | None = None) -> np.ndarray:
    m, p = jac.shape
    r_inv = inverse_factor(jac) if r_inv is None else r_inv
    s2 = float(residual @ residual) / max(m - p, 1)
    return s2 * (r_inv @ r_inv.T)


def colored_covariance(jac: np.ndarray, residual: np.ndarray, bounds: np.ndarray, max_lag=None,
                       r_inv: np.ndarray | None = None):
    """Toeplitz-autocorrelation sandwich; returns (covariance, number of lags used)."""
    lags = choose_max_lag(residual, bounds, max_lag)
    lam = autocovariance(residual, bounds, lags) * lag_weights(lags, max_lag)
    return _sandwich(jac, jac.T @ toeplitz_product(jac, lam, bounds), r_inv), lags


# ----- heteroscedasticity- and autocorrelation-consistent (HAC) sandwich --------------------------
HAC_KERNELS = {"hac": "bartlett", "hac-qs": "quadratic-spectral", "hac-maneuver": "bartlett"}


def kernel_weights(kernel: str, bandwidth: float, n_lags: int) -> np.ndarray:
    """w(j / b) for lags j = 0..n_lags: Bartlett 1 - x on [0, 1], or the quadratic-spectral kernel."""
    x = np.arange(n_lags + 1) / bandwidth
    if kernel == "bartlett":
        return np.clip(1.0 - x, 0.0, None)
    if kernel == "quadratic-spectral":
        z = 6.0 * np.pi * x[1:] / 5.0
        return np.concatenate([[1.0], 3.0 / z ** 2 * (np.sin(z) / z - np.cos(z))])
    raise ValueError(f"unknown HAC kernel {kernel!r}")


def andrews_bandwidth(scores: np.ndarray, bounds: np.ndarray, kernel: str) -> float:
    """Andrews' (1991) AR(1) plug-in bandwidth for the score columns, pooled within maneuvers.

    Columns are standardised first (the rule is not scale invariant across columns), AR(1)
    coefficients are estimated from pairs inside each maneuver only, and the sample size is
    the mean maneuver length, because every maneuver is its own series.
    """
    inside = np.ones(len(scores), bool)
    inside[np.asarray(bounds[:-1], int)] = False  # a maneuver's first sample has no predecessor in it
    num = den = 0.0
    for g in scores.T:
        sd = g.std()
        if not np.isfinite(sd) or sd == 0:
            continue
        g = g / sd
        cur, prev = g[1:][inside[1:]], g[:-1][inside[1:]]
        rho = float(np.clip(cur @ prev / (prev @ prev), -0.999, 0.999))
        s4 = float(np.mean((cur - rho * prev) ** 2)) ** 2
        if kernel == "bartlett":
            num += 4 * rho ** 2 * s4 / ((1 - rho) ** 6 * (1 + rho) ** 2)
        else:
            num += 4 * rho ** 2 * s4 / (1 - rho) ** 8
        den += s4 / (1 - rho) ** 4
    if den == 0:
        return 1.0
    n = len(scores) / (len(bounds) - 1)
    if kernel == "bartlett":
        return float(max(1.1447 * (num / den * n) ** (1 / 3), 1.0))
    return float(max(1.3221 * (num / den * n) ** (1 / 5), 1.0))


def bartlett_maneuver_sums(scores: np.ndarray, bounds: np.ndarray, bandwidth: float,
                           diagonal: bool = False) -> np.ndarray:
    """Per maneuver, sum_t sum_s (1 - |t-s|/b) g_t g_s^T for a Bartlett bandwidth b at least as long as
    the maneuver (every lag inside it carries weight): (G, p, p), or its diagonals (G, p).

    With S = sum_t g_t and E_t = sum_{s<t} (t-s) g_s (a double running sum), the double sum is
    S S^T - (G^T E + E^T G)/b: O(n p^2) per maneuver instead of a convolution per column.
    """
    b = float(bandwidth)
    p = scores.shape[1]
    out = np.empty((len(bounds) - 1, p) if diagonal else (len(bounds) - 1, p, p))
    for i in range(len(bounds) - 1):
        g = scores[int(bounds[i]):int(bounds[i + 1])]
        if len(g) - 1 > b:
            raise ValueError(f"bandwidth {b} is shorter than maneuver {i} ({len(g)} samples)")
        running = np.cumsum(g, axis=0)
        lagged = np.zeros_like(g)          # E_t = E_{t-1} + sum_{s<t} g_s
        np.cumsum(running[:-1], axis=0, out=lagged[1:])
        total = running[-1]
        if diagonal:
            out[i] = total * total - 2.0 * np.einsum("tj,tj->j", g, lagged) / b
        else:
            cross = g.T @ lagged
            out[i] = np.outer(total, total) - (cross + cross.T) / b
    return out


def hac_meat(scores: np.ndarray, bounds: np.ndarray, kind: str = "hac",
             bandwidth: float | None = None) -> tuple[np.ndarray, float]:
    """sum over maneuvers of sum_t sum_s w(|t-s|/b) g_t g_s^T; returns (meat, bandwidth b)."""
    kernel = HAC_KERNELS[kind]
    if bandwidth is not None:
        b = float(bandwidth)
    elif kind == "hac-maneuver":  # every lag inside the longest maneuver carries weight
        b = float(np.max(np.diff(bounds)))
    else:
        b = andrews_bandwidth(scores, bounds, kernel)
    longest = int(np.max(np.diff(bounds))) - 1
    if kernel == "bartlett" and b >= longest:  # every lag of every maneuver: running sums, no convolution
        return bartlett_maneuver_sums(scores, bounds, b).sum(axis=0), b
    n_lags = min(int(np.ceil(b)), longest) if kernel == "bartlett" else longest
    return scores.T @ toeplitz_product(scores, kernel_weights(kernel, b, n_lags), bounds), b


def hac_covariance(jac: np.ndarray, residual: np.ndarray, bounds: np.ndarray, kind: str = "hac",
                   bandwidth: float | None = None, r_inv: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """HAC sandwich A^-1 (sum_maneuvers G^T W G) A^-1 * m/(m-p); returns (covariance, bandwidth)."""
    m, p = jac.shape
    meat, b = hac_meat(jac * residual[:, None], bounds, kind, bandwidth)
    return _sandwich(jac, meat, r_inv) * (m / max(m - p, 1)), b


def cluster_meat(scores: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """sum over maneuvers of (sum of the maneuver's scores)(...)^T, times G/(G-1) (CR1)."""
    sums = np.add.reduceat(scores, np.asarray(bounds[:-1], int), axis=0)
    g = len(sums)
    return sums.T @ sums * (g / (g - 1) if g > 1 else float("nan"))


def cluster_estimable(bounds: np.ndarray, n_params: int) -> bool:
    """The clustered meat has rank <= G - 1: with G - 1 < p some combinations would get variance 0."""
    return len(bounds) - 2 >= n_params


def cluster_covariance(jac: np.ndarray, residual: np.ndarray, bounds: np.ndarray,
                       r_inv: np.ndarray | None = None) -> np.ndarray:
    """Maneuver-clustered sandwich (Liang-Zeger; CR1 small-sample factor): any correlation and any
    change of variance inside a maneuver, independence between maneuvers. Its meat has rank at most
    G - 1 for G maneuvers, so with fewer than p + 1 maneuvers it is not estimable (NaN, never a
    variance of 0); it needs many more maneuvers than parameters to be accurate."""
    m, p = jac.shape
    if not cluster_estimable(bounds, p):
        return np.full((p, p), np.nan)
    return _sandwich(jac, cluster_meat(jac * residual[:, None], bounds), r_inv) * ((m - 1) / max(m - p, 1))


COVARIANCE_KINDS = ("colored", "white", "hac", "hac-qs", "hac-maneuver", "cluster")
# kinds whose estimate has the precision of a few numbers per maneuver: t references with few dof
PER_MANEUVER_KINDS = ("hac-maneuver", "cluster")


def effective_maneuvers(jac: np.ndarray, scores: np.ndarray, bounds: np.ndarray, kind: str,
                        bandwidth: float | None = None, r_inv: np.ndarray | None = None) -> np.ndarray:
    """Effective number of maneuvers behind each parameter's variance (Satterthwaite 1946; the
    "effective number of clusters" of Carter, Schnepel & Steigerwald 2017): (sum_g c_g)^2 / sum_g c_g^2,
    with c_g >= 0 maneuver g's share of the sandwich's diagonal. G when every maneuver informs a
    parameter equally, about 1 when one maneuver does (a deep-stall term seen in one maneuver)."""
    r_inv = inverse_factor(jac) if r_inv is None else r_inv
    u = scores @ (r_inv @ r_inv.T)                  # (A^-1 g_t)^T per sample
    starts = np.asarray(bounds[:-1], int)
    if kind == "cluster":
        share = np.add.reduceat(u, starts, axis=0) ** 2
    else:  # a positive semi-definite kernel inside each maneuver: every share is >= 0
        b = float(np.max(np.diff(bounds))) if bandwidth is None else float(bandwidth)
        longest = int(np.max(np.diff(bounds))) - 1
        if b >= longest:
            share = bartlett_maneuver_sums(u, bounds, b, diagonal=True)
        else:
            lags = min(int(np.ceil(b)), longest)
            share = np.add.reduceat(u * toeplitz_product(u, kernel_weights("bartlett", b, lags), bounds), starts,
                                    axis=0)
    total, square = share.sum(axis=0), (share ** 2).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(square > 0, total ** 2 / square, np.nan)


def reference_dof(kind: str, n_samples: int, n_params: int, n_maneuvers: float) -> float:
    """Degrees of freedom of the Student-t reference for t-tests and intervals with this covariance:
    (effective) maneuvers - 1 for the per-maneuver kinds, m - p otherwise."""
    if kind in PER_MANEUVER_KINDS:
        return float(max(n_maneuvers - 1.0, 1.0)) if np.isfinite(n_maneuvers) else float("nan")
    return float(max(n_samples - n_params, 1))
# Chosen by the Monte Carlo calibration on the flight simulator (structsearch bench --calibration).
DEFAULT_COVARIANCE = "hac-maneuver"


@dataclass(frozen=True)
class Covariances:
    """The requested covariance and the white one, on the identifiable parameters (NaN elsewhere)."""

    covariance: np.ndarray
    white: np.ndarray
    max_lag: int | None = None
    bandwidth: float | None = None
    # per parameter, for the per-maneuver kinds (NaN for the others and the non-identifiable ones)
    effective_maneuvers: np.ndarray | None = None
    # inverse_factor of the Jacobian's kept columns (None when none could be formed): an estimator that
    # refines this covariance later (the two-step one) reuses it instead of factorising the m x p Jacobian
    inverse_factor: np.ndarray | None = None

    @classmethod
    def on(cls, jac: np.ndarray, keep: np.ndarray, residual: np.ndarray, bounds: np.ndarray, kind: str,
           max_lag=None, factor: tuple[np.ndarray, np.ndarray] | None = None) -> "Covariances":
        """Covariances of the parameters selected by ``keep`` (the others held at their estimates);
        ``factor``: :func:`scaled_factor` of ``jac[:, keep]`` when the caller has it."""
        p = jac.shape[1]
        full, white = np.full((p, p), np.nan), np.full((p, p), np.nan)
        lags = bandwidth = r_inv = None
        effective = np.full(p, np.nan)
        sub = jac[:, keep]
        if sub.shape[1] and np.all(np.isfinite(sub)) and np.all(np.isfinite(residual)):
            block = np.ix_(keep, keep)
            try:
                r_inv = inverse_factor(sub, factor)
                white[block] = white_covariance(sub, residual, r_inv)
                if kind == "colored":
                    full[block], lags = colored_covariance(sub, residual, bounds, max_lag, r_inv)
                elif kind in HAC_KERNELS:
                    full[block], bandwidth = hac_covariance(sub, residual, bounds, kind, r_inv=r_inv)
                elif kind == "cluster":
                    full[block] = cluster_covariance(sub, residual, bounds, r_inv)
                else:
                    full[block] = white[block]
                if kind in PER_MANEUVER_KINDS:
                    effective[keep] = effective_maneuvers(sub, sub * residual[:, None], bounds, kind, bandwidth,
                                                          r_inv)
            except np.linalg.LinAlgError:
                # an exactly singular factor despite the basis choice: report "not estimable" (NaN)
                full[block] = white[block] = np.nan
                r_inv = None
        return cls(full, white, lags, bandwidth, effective, r_inv)

    def without(self, indices) -> "Covariances":
        """The same estimate with the rows and columns of ``indices`` set to NaN (not estimable)."""
        cov, white = self.covariance.copy(), self.white.copy()
        for m in (cov, white):
            m[indices, :] = np.nan
            m[:, indices] = np.nan
        effective = None if self.effective_maneuvers is None else self.effective_maneuvers.copy()
        if effective is not None:
            effective[indices] = np.nan
        return Covariances(cov, white, self.max_lag, self.bandwidth, effective, self.inverse_factor)
