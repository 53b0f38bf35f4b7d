"""The reference aircraft's default search boxes of the separation parameters.

The engine knows no aircraft: a separation parameter without a declared box gets the box below,
set on the Citation II stall campaign of the thesis (Herbold 2025, docs/catalogue.md "separation
parameters") and widened to the data at hand by :func:`data_bounds`.
"""
from __future__ import annotations

import numpy as np

# Physical search box for each parameter kind [s, s, 1/rad, rad].
DEFAULT_BOUNDS = {
    "tau1": (0.0, 2.0),
    "tau2": (0.0, 1.0),
    "a1": (2.0, 200.0),
    "a_star": (0.05, 0.45),
}
DEFAULT_START = {"tau1": 0.2, "tau2": 0.05, "a1": 30.0, "a_star": 0.25}
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
        lo, hi = DEFAULT_BOUNDS["a_star"]
        out["a_star"] = (min(lo, max(float(np.min(alpha)) - ALPHA_STAR_MARGIN, 0.0)),
                         max(hi, float(np.max(alpha)) + ALPHA_STAR_MARGIN))
    if "V" in data and "cbar" in data.constants and data.n_samples:
        scale = max(float(data.constants["cbar"] / np.median(data["V"])) / REFERENCE_TIME, 1.0)
        for kind in ("tau1", "tau2"):
            lo, hi = DEFAULT_BOUNDS[kind]
            out[kind] = (lo, hi * scale)
    return out
