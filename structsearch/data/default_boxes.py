"""The reference aircraft's default search boxes of the separation parameters.

The engine knows no aircraft: a separation parameter without a declared box gets the box below,
set on the Citation II stall campaign of the thesis (Herbold 2025, docs/catalogue.md "separation
parameters") and widened to the data at hand by :func:`data_bounds`.
"""
from __future__ import annotations

import numpy as np

# The most knots a spline:K static curve may have (each ratio r1 ... rK has the box below).
MAX_SPLINE_KNOTS = 12
# Physical search box for each parameter kind [s, s, 1/rad, rad], then those of the other static curves
# (structsearch.engine.static_forms): goman's rate [1/rad] and value at the break [-], two_break's rates
# [1/rad], first break [rad], distance of the second beyond it [rad] and plateau [-], spline's first knot [rad],
# knot spacing [rad] and ratios [-]. A ratio in [0, 1] is what keeps a spline monotone; x_star stops short of 0
# and 1, where goman's slope below the break would vanish or become infinite.
DEFAULT_BOUNDS = {
    "tau1": (0.0, 2.0),
    "tau2": (0.0, 1.0),
    "tau_v": (0.0, 2.0),
    "a1": (2.0, 200.0),
    "a_star": (0.05, 0.45),
    "k_e": (2.0, 200.0),
    "x_star": (0.05, 0.95),
    "k1": (2.0, 200.0),
    "a_k1": (0.05, 0.45),
    "k2": (2.0, 200.0),
    "da_k2": (0.0, 0.3),
    "x_mid": (0.0, 1.0),
    "a_sp": (0.05, 0.45),
    "h_sp": (0.005, 0.1),
    **{f"r{j}": (0.0, 1.0) for j in range(1, MAX_SPLINE_KNOTS + 1)},
}
DEFAULT_START = {"tau1": 0.2, "tau2": 0.05, "tau_v": 0.1, "a1": 30.0, "a_star": 0.25, "k_e": 30.0, "x_star": 0.5,
                 "k1": 30.0, "a_k1": 0.2, "k2": 30.0, "da_k2": 0.08, "x_mid": 0.5, "a_sp": 0.15, "h_sp": 0.04,
                 **{f"r{j}": 0.6 for j in range(1, MAX_SPLINE_KNOTS + 1)}}
# The separation time constants [s]: their boxes scale with the aerodynamic time of the data.
TIME_CONSTANTS = ("tau1", "tau2", "tau_v")
# The angles at which a static curve breaks: their boxes widen to the alpha range flown.
BREAK_ANGLES = ("a_star", "a_k1", "a_sp")
# The time constants above are the Citation II's (cbar 2.013 m at 73 m/s, the median airspeed of its
# stall campaign): their upper limits grow with the aerodynamic time cbar/V of the data, so they do
# not bind on a larger or slower aircraft.
REFERENCE_TIME = 2.013 / 73.0
# alpha* may lie this far outside the alpha range flown (the search box; admissibility asks for inside).
ALPHA_STAR_MARGIN = np.deg2rad(2.0)


def data_bounds(data) -> dict[str, tuple[float, float]]:
    """The default search box of each parameter kind for this data, never narrower than the Citation's:
    alpha* widened to the alpha range flown plus a margin (an aircraft that stalls beyond 0.45 rad), the
    time constants' upper limits scaled by cbar/V when it exceeds the Citation's. Not narrowed: a state
    that the data barely reach still fits, and admissibility names an alpha* outside the range flown."""
    out = dict(DEFAULT_BOUNDS)
    if "alpha" in data and data.n_samples:
        alpha = data["alpha"]
        for name in BREAK_ANGLES:
            lo, hi = DEFAULT_BOUNDS[name]
            out[name] = (min(lo, max(float(np.min(alpha)) - ALPHA_STAR_MARGIN, 0.0)),
                         max(hi, float(np.max(alpha)) + ALPHA_STAR_MARGIN))
    if "V" in data and "cbar" in data.constants and data.n_samples:
        scale = max(float(data.constants["cbar"] / np.median(data["V"])) / REFERENCE_TIME, 1.0)
        for kind in TIME_CONSTANTS:
            lo, hi = DEFAULT_BOUNDS[kind]
            out[kind] = (lo, hi * scale)
    return out
