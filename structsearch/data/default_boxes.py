"""The reference aircraft's default search boxes of the separation parameters.

The engine knows no aircraft: a separation parameter without a declared box gets the box below,
set on the Citation II stall campaign of the thesis (Herbold 2025, docs/catalogue.md "separation
parameters") and widened to the data at hand by :func:`data_bounds`.
"""
from __future__ import annotations

import numpy as np

# The most knots a spline:K static curve may have (each ratio r1 ... rK has a box [0, 1]).
MAX_SPLINE_KNOTS = 12
# Search box and start of each separation time constant [s]: tau1 the lag, tau2 the alpha_dot delay, tau_v the
# vortex's. The static curves' boxes and starts are their records' (structsearch.engine.static_forms).
TIME_BOUNDS = {"tau1": (0.0, 2.0), "tau2": (0.0, 1.0), "tau_v": (0.0, 2.0)}
TIME_STARTS = {"tau1": 0.2, "tau2": 0.05, "tau_v": 0.1}
# The separation time constants: their boxes scale with the aerodynamic time of the data.
TIME_CONSTANTS = tuple(TIME_BOUNDS)
# The time constants above are the Citation II's (cbar 2.013 m at 73 m/s, the median airspeed of its
# stall campaign): their upper limits grow with the aerodynamic time cbar/V of the data, so they do
# not bind on a larger or slower aircraft.
REFERENCE_TIME = 2.013 / 73.0
# alpha* may lie this far outside the alpha range flown (the search box; admissibility asks for inside).
ALPHA_STAR_MARGIN = np.deg2rad(2.0)


def data_bounds(data, boxes: dict[str, tuple[float, float]], break_angles) -> dict[str, tuple[float, float]]:
    """The default search ``boxes`` of the separation parameters for this data, never narrower than the
    Citation's: the ``break_angles`` (where a static curve breaks) widened to the alpha range flown plus a margin
    (an aircraft that stalls beyond 0.45 rad), the time constants' upper limits scaled by cbar/V when it exceeds
    the Citation's. Not narrowed: a state that the data barely reach still fits, and admissibility names an
    alpha* outside the range flown."""
    out = dict(boxes)
    if "alpha" in data and data.n_samples:
        alpha = data["alpha"]
        for name in break_angles:
            lo, hi = boxes[name]
            out[name] = (min(lo, max(float(np.min(alpha)) - ALPHA_STAR_MARGIN, 0.0)),
                         max(hi, float(np.max(alpha)) + ALPHA_STAR_MARGIN))
    if "V" in data and "cbar" in data.constants and data.n_samples:
        scale = max(float(data.constants["cbar"] / np.median(data["V"])) / REFERENCE_TIME, 1.0)
        for kind in TIME_CONSTANTS:
            lo, hi = boxes[kind]
            out[kind] = (lo, hi * scale)
    return out
