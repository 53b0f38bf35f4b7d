"""The models a covariance calibration fits and their simulator truth (:mod:`.calibration`)."""
from __future__ import annotations

from ..flight.reference import FINAL_DRAG, FINAL_LIFT, FINAL_MODEL_NAMES, FINAL_PITCH

TRUTH = {"CL": FINAL_LIFT, "CD": FINAL_DRAG, "Cm": FINAL_PITCH}
# How the simulated truth's C_m depends on the cg (simulate --cg-moment) -> the pitch model calibrated on it, the
# truth's own structure: the thesis' cg term (Cm-XXXIIIr), or the transfer about the fixed reference point
# (Cm-XXXIIIf, whose x_cg flight effect has the transfer's known coefficient: docs/guide/flight-effects.md).
PITCH_MODELS = {"thesis": FINAL_MODEL_NAMES["Cm"], "transfer": "Cm-XXXIIIf"}


def final_models(cg_moment: str = "thesis") -> tuple[dict[str, str], dict[str, dict[str, float]]]:
    """The models a calibration fits (coefficient -> name) and their simulator truth (coefficient -> parameter ->
    value) on campaigns flown with ``cg_moment``: about the fixed point, the truth's cg terms frozen at the
    reference point (:func:`structsearch.flight.aero.cg_transfer_pitch`), its transfer known."""
    from ..data.errors import DeclarationError
    if cg_moment not in PITCH_MODELS:
        raise DeclarationError(f"cg moment {cg_moment!r}: one of {', '.join(PITCH_MODELS)}")
    names = dict(FINAL_MODEL_NAMES, Cm=PITCH_MODELS[cg_moment])
    if cg_moment == "thesis":
        return names, {coef: dict(v) for coef, v in TRUTH.items()}
    from ..flight.aero import truth_model
    params = truth_model(cg_moment=cg_moment).params
    pitch = {k: float(params[k]) for k in FINAL_PITCH if k != "Cm_xcgCL"}
    return names, {"CL": dict(FINAL_LIFT), "CD": dict(FINAL_DRAG), "Cm": pitch}
