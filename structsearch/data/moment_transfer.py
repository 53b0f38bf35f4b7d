"""The pitching moment moved from a fixed reference point to the recorded centre of gravity (docs/interfaces.md 7.5).

Body x stations grow aft (the x_cg column's datum, ``[aircraft] x_cg_range``). The normal force C_N (up, normal to
the body x axis) acting at any station gives, about a point at station x_p, a nose-up moment that grows as the point
moves aft; the axial force acts along the axis through both points and adds none. So the moment about the recorded
cg and the one about the fixed ``[aircraft] reference_point`` x_ref differ by

    C_m,cg = C_m,ref + C_N (x_cg - x_ref) / cbar,    C_N = C_L cos(alpha) + C_D sin(alpha)

A pitch model about the fixed point adds this term, known and never estimated (:data:`TRANSFER_EXPRESSION`), to its
output: its C_L is the one its other regressors read (the output of the lift model it names, as the thesis feeds
pitch models; the measured C_L's buffet and reconstruction errors would enter the prediction), its C_D the measured.
This module holds the expression and the checks of the manifest key.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from .errors import DataError
from .reading import shown

REFERENCE_KEY = "reference_point"
TRANSFER_NAME = "Cm_transfer"
TRANSFER_EXPRESSION = "(x_cg - reference_point)/cbar*(CL*cos(alpha) + CD*sin(alpha))"
# A reference point further than this many chords from the cg envelope, or from a recorded cg, is a datum or unit
# slip (inches for metres, another datum): a moment transfer over it would swamp C_m.
MAX_CHORDS_FROM_CG = 2.0
# Without a cg envelope: no aircraft's body station lies a kilometre from its datum.
MAX_STATION_M = 1000.0


def check_reference_point(value, aircraft: Mapping[str, object], source: str | None) -> float:
    """``[aircraft] reference_point``: a finite station [m] within :data:`MAX_CHORDS_FROM_CG` chords of the cg
    envelope when the manifest gives one (else within :data:`MAX_STATION_M` of the datum)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(float(value)):
        raise DataError(f"[aircraft] {REFERENCE_KEY} must be a finite number (a body x station in m, the x_cg "
                        f"column's datum), not {shown(value)}", source=source, column=REFERENCE_KEY)
    x = float(value)
    envelope = aircraft.get("x_cg_range")
    if envelope is not None:
        reach = MAX_CHORDS_FROM_CG * float(aircraft["cbar"])
        lo, hi = float(envelope[0]) - reach, float(envelope[1]) + reach
        if not lo <= x <= hi:
            raise DataError(f"[aircraft] {REFERENCE_KEY} = {x:g} m lies more than {MAX_CHORDS_FROM_CG:g} chords from "
                            f"the cg envelope x_cg_range ({float(envelope[0]):g}, {float(envelope[1]):g}) m: the "
                            "same datum and unit as x_cg are needed", source=source, column=REFERENCE_KEY)
    elif abs(x) > MAX_STATION_M:
        raise DataError(f"[aircraft] {REFERENCE_KEY} = {x:g} m is not a body station (more than "
                        f"{MAX_STATION_M:g} m from the datum)", source=source, column=REFERENCE_KEY)
    return x


def check_transfer_datum(x_cg: np.ndarray | None, aircraft: Mapping[str, object], source: str | None) -> None:
    """Refuse a recorded cg more than :data:`MAX_CHORDS_FROM_CG` chords from the reference point (a datum or unit
    that differs between the x_cg column and the key), naming the key; nothing to check without either."""
    if REFERENCE_KEY not in aircraft or x_cg is None or not np.size(x_cg):
        return
    x_ref, cbar = float(aircraft[REFERENCE_KEY]), float(aircraft["cbar"])
    far = float(np.max(np.abs(np.asarray(x_cg, float) - x_ref))) / cbar
    if far > MAX_CHORDS_FROM_CG:
        raise DataError(f"[aircraft] {REFERENCE_KEY} = {x_ref:g} m lies {far:.3g} chords from a recorded x_cg: the "
                        "reference point and the x_cg column need the same datum and unit", source=source,
                        column=REFERENCE_KEY)
