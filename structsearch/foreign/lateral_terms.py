"""A JSBSim aircraft's lateral coefficients term by term, as a flight test records them: the body-axis side force
and the rolling and yawing moments about the cg.

JSBSim's SIDE functions are wind-axis forces (the LIFT, DRAG and SIDE frame); the body-axis side force an
accelerometer measures is cos(beta) of them less sin(beta) of the drag. Its ROLL and YAW functions are body-axis
moments about the aerodynamic reference point; about the cg they add the moment of the aerodynamic force, d x F
with d the reference point's offset from the cg in body axes (x forward, y right, z down: d = ((x_cg - x_ARP),
(y_ARP - y_cg), (z_cg - z_ARP)) from JSBSim's structural frame, x aft, z up, inches). Each function is a term
``sim:<function>`` (force over q S, moment over q S b); ``sim:transfer`` is the rest of what JSBSim's body-axis
aerodynamic force and moment make of them, computed from its own body forces:

* C_Y: F_y / q S less the SIDE terms (the drag turned by the sideslip);
* C_l: (d_y F_z - d_z F_y) / q S b (the lift's arm when the cg is off the plane of symmetry, the side force's when
  it is below or above the reference point);
* C_n: (d_x F_y - d_y F_x) / q S b.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..data.coefficients import Coefficient

TERM_PREFIX = "sim:"
TRANSFER = "sim:transfer"
# the body axis (x, y, z) each of JSBSim's moment axes turns about
BODY_AXIS = {"ROLL": 0, "PITCH": 1, "YAW": 2}


def arm_ft(geometry) -> np.ndarray:
    """The aerodynamic reference point's offset from the cg in body axes [ft] (module docstring)."""
    g = geometry
    return np.array([g["inertia/cg-x-in"] - g["metrics/aero-rp-x-in"], g["metrics/aero-rp-y-in"] - g["inertia/cg-y-in"],
                     g["inertia/cg-z-in"] - g["metrics/aero-rp-z-in"]]) / 12.0


def lateral_terms(evaluation, record: Coefficient, functions: Sequence[str]) -> dict[str, np.ndarray]:
    """Each of ``functions`` (``record``'s axis) as its share of the body-axis coefficient, and ``sim:transfer``."""
    g = evaluation.geometry
    qs = evaluation.qbar * g["metrics/Sw-sqft"]
    fx, fy, fz = (evaluation.body[f"forces/fb{a}-aero-lbs"] for a in "xyz")
    scale = qs * g["metrics/bw-ft"] if record.moment else qs
    out = {TERM_PREFIX + f: evaluation.functions[f] / scale for f in functions}
    if not record.moment:
        out[TRANSFER] = fy / qs - sum(out.values())
        return out
    moment = np.cross(arm_ft(g), np.column_stack([fx, fy, fz]))[:, BODY_AXIS[record.jsbsim_axis]]
    out[TRANSFER] = moment / scale
    return out
