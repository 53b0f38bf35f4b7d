"""The attached-flow aerodynamics of the Citation II's wider envelope (nominal maneuvers, ``simulate --nominal``):
what compressibility and the wing's and tail's flexibility add to the truth at high Mach and dynamic pressure.

The thesis' final models were identified on stall maneuvers flown below Mach 0.36 and 4.8 kPa (the default
campaign's whole range), where they stand as they are. Each term here is a hinge that is zero below
:data:`MACH_ONSET` or :data:`QBAR_ONSET_PA`, above everything a stall maneuver flies: a campaign without nominal
maneuvers is the one simulated before they existed, bit for bit, and its stall maneuvers fly the same aerodynamics
with or without the nominal ones (up to the rounding of a term that is zero). The sizes are mild (Prandtl-Glauert's
rise of the lift slope, drag creep, a Mach tuck and an elevator losing effectiveness to aeroelastic twist) and of
our choosing: no Citation data of them is published.
"""
from __future__ import annotations

from typing import Mapping

from ..engine.stallmodel import StallModel

MACH_ONSET = 0.40
QBAR_ONSET_PA = 5000.0
# Regressors, in the grammar of the model specs (the columns Mach and qbar: structsearch.data.reduction.air_data)
ENVELOPE_TERMS: Mapping[str, Mapping[str, str]] = {
    "CL": {"CL_Ma": f"alpha*pos(Mach - {MACH_ONSET})"},
    "CD": {"CD_M2": f"pos(Mach - {MACH_ONSET})**2"},
    "Cm": {"Cm_M": f"pos(Mach - {MACH_ONSET})", "Cm_deq": f"de*pos(qbar - {QBAR_ONSET_PA:g})/10000"},
}
# The lift slope rises by about 15 % from Mach 0.40 to 0.60 (Prandtl-Glauert: 1/sqrt(1 - M^2)); drag creeps by
# 0.006 at Mach 0.6; the nose drops by 0.006 in C_m there; the elevator loses about 9 % of its power at 9.5 kPa.
ENVELOPE_VALUES: Mapping[str, float] = {"CL_Ma": 3.0, "CD_M2": 0.15, "Cm_M": -0.03, "Cm_deq": 0.15}


def with_envelope(model: StallModel) -> StallModel:
    """``model`` (a truth structure) with its coefficient's envelope terms added."""
    regressors = {r.name: r.text for r in model.regressors}
    regressors.update(ENVELOPE_TERMS[model.coefficient])
    return StallModel.declare(model.name, model.coefficient, regressors,
                              states={s.name: s.kind for s in model.states}, fixed=model.fixed)
