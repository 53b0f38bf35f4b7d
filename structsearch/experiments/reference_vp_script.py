"""The bench's whole-process reference: CL-VI by variable projection in plain numpy/scipy.

Run as its own process: ``python reference_vp_script.py CAMPAIGN_DIR``. It reads the campaign itself
(campaign.toml, the CSV files of the training maneuvers), fits CL-VI (docs/catalogue.md: X_ss unsteady,
X_w steady; C_L0, K_L(X_ss), K_L(X_w), q*, delta_e) from its declared start inside its default box,
and prints one JSON line: RSS, parameters, evaluations, seconds. It imports nothing from structsearch
on purpose: a benchmark whose reference is computed by the code under test measures nothing.
"""
import csv
import json
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import lfilter
from scipy.special import expit

NAMES = ("tau1_ss", "tau2_ss", "a1_ss", "a_star_ss", "a1_w", "a_star_w")
LOWER = np.array([0.005, 0.0, 2.0, 0.05, 2.0, 0.22])          # tau1, tau2 scale with cbar/V below
UPPER = np.array([2.0, 1.0, 200.0, 0.27, 200.0, 0.45])
START = np.array([0.2, 0.05, 30.0, 0.16, 30.0, 0.335])         # a_star: the middle of its box
COLUMNS = ("t", "alpha", "q", "V", "de", "CL")


def read(directory: Path):
    doc = tomllib.loads((directory / "campaign.toml").read_text())
    parts = []
    for m in doc["maneuver"]:
        if m["split"] == "train":
            with open(directory / m["file"], newline="") as f:
                header = next(csv.reader(f))
            use = [header.index(c) for c in COLUMNS] + ([header.index("alpha_dot")] if "alpha_dot" in header else [])
            cols = np.loadtxt(directory / m["file"], delimiter=",", skiprows=1, usecols=use, ndmin=2).T
            d = dict(zip(COLUMNS, cols))
            d["alpha_dot"] = cols[6] if len(use) > 6 else np.gradient(d["alpha"], d["t"], edge_order=2)
            parts.append(d)
    return parts, float(doc["aircraft"]["cbar"])


def lag(u, du, tau1, dt):
    """X_k = a X_(k-1) + b0 u_(k-1) + b1 u_k (exact for u linear between samples), X_0 = u_0; and dX."""
    x = dt / tau1
    a, g = np.exp(-x), -np.expm1(-x) / x
    da, dg = a * x / tau1, -np.expm1(-x) / dt - a / tau1
    b0, b1 = g - a, 1.0 - g
    X = u[0] + lfilter([b1, b0], [1.0, -a], u - u[0])
    dX = np.column_stack([du[0, j] + lfilter([b1, b0], [1.0, -a], du[:, j] - du[0, j]) for j in range(du.shape[1])])
    forcing = np.zeros_like(u)
    forcing[1:] = da * X[:-1] + (dg - da) * u[:-1] - dg * u[1:]
    return X, np.column_stack([lfilter([1.0], [1.0, -a], forcing), dX])


def model(th, parts, cbar):
    """Phi (m x 5) and the derivative of its K_L(X_ss) (4 columns) and K_L(X_w) (2 columns) columns."""
    tau1, tau2, a1, ast, a1w, astw = th
    phis, d_ss, d_w = [], [], []
    for d in parts:
        t, alpha = d["t"], d["alpha"]
        dt = np.diff(t)
        if np.ptp(dt) > 1e-9 * dt[0]:
            raise SystemExit("this script handles uniformly sampled maneuvers only")
        eff = alpha - tau2 * d["alpha_dot"]
        u = expit(-2.0 * a1 * (eff - ast))
        s = -2.0 * u * (1.0 - u)
        du = np.column_stack([s * (-a1 * d["alpha_dot"]), s * (eff - ast), s * (-a1)])
        xs, dxs = lag(u, du, tau1, dt[0])
        xw = expit(-2.0 * a1w * (alpha - astw))
        sw = -2.0 * xw * (1.0 - xw)
        dxw = np.column_stack([sw * (alpha - astw), sw * (-a1w)])
        xs, xw = np.clip(xs, 1e-300, 1.0), np.clip(xw, 1e-300, 1.0)
        kl = lambda X: ((1.0 + np.sqrt(X)) / 2.0) ** 2 * alpha  # noqa: E731
        dkl = lambda X: (1.0 + np.sqrt(X)) / (4.0 * np.sqrt(X)) * alpha  # noqa: E731
        phis.append(np.column_stack([np.ones_like(t), kl(xs), kl(xw), d["q"] * cbar / d["V"], d["de"]]))
        d_ss.append(dxs * dkl(xs)[:, None])
        d_w.append(dxw * dkl(xw)[:, None])
    return np.vstack(phis), np.vstack(d_ss), np.vstack(d_w)


def fit(parts, cbar):
    y = np.concatenate([d["CL"] for d in parts])
    v = np.concatenate([d["V"] for d in parts])
    scale = max(cbar / np.median(v) / (2.013 / 73.0), 1.0)   # time constants scale with cbar/V
    lower, upper = LOWER.copy(), UPPER.copy()
    upper[:2] *= scale
    cache = {}

    def parts_at(th):
        key = th.tobytes()
        if key not in cache:
            cache.clear()
            phi, d_ss, d_w = model(th, parts, cbar)
            q, r = np.linalg.qr(phi)
            qty = q.T @ y
            c = np.linalg.solve(r, qty)
            cache[key] = (q, r, c, y - q @ qty, d_ss, d_w)
        return cache[key]

    def jac(th):  # Golub-Pereyra: -(I - Q Q^T) dPhi c - Q R^-T dPhi^T r, dPhi one column per parameter
        q, r, c, res, d_ss, d_w = parts_at(th)
        cols = []
        for dcol, row in [(d_ss[:, j], 1) for j in range(4)] + [(d_w[:, j], 2) for j in range(2)]:
            a = dcol * c[row]
            a -= q @ (q.T @ a)
            e = np.zeros(len(c))
            e[row] = dcol @ res
            cols.append(-(a + q @ np.linalg.solve(r.T, e)))
        return np.column_stack(cols)

    span = upper - lower
    x0 = np.clip(np.clip(START, lower, upper), lower + 1e-10 * span, upper - 1e-10 * span)
    sol = least_squares(lambda th: parts_at(th)[3], x0, jac=jac, bounds=(lower, upper), method="trf",
                        x_scale=span, ftol=1e-10, xtol=1e-10, gtol=1e-10, max_nfev=1000)
    q, r, c, res, _, _ = parts_at(sol.x)
    return {"rss": float(res @ res), "samples": len(y), "theta": dict(zip(NAMES, sol.x.tolist())),
            "coef": c.tolist(), "nfev": int(sol.nfev), "njev": int(sol.njev or 0), "status": int(sol.status),
            "at_bound": [n for n, v, lo, hi in zip(NAMES, sol.x, lower, upper) if min(v - lo, hi - v) <= 1e-6 * (hi - lo)]}


if __name__ == "__main__":
    t0 = time.perf_counter()
    data, chord = read(Path(sys.argv[1]))
    t_read = time.perf_counter() - t0
    out = fit(data, chord)
    print(json.dumps({**out, "read_s": t_read, "fit_s": time.perf_counter() - t0 - t_read}))
