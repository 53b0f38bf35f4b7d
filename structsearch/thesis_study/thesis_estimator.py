"""The thesis' final models refitted with the thesis' own covariance estimator.

The thesis' standard deviations (Tables 11, 13, 15) come from its coloured Toeplitz sandwich
(Eqs. 19, 22): the simulator's realism is judged with the same estimator, whatever the default.
"""
from __future__ import annotations

from typing import Mapping, Sequence

from ..fitting.candidate_fit import fit_candidate
from ..fitting.lift_fit import LiftFit
from ..fitting.options import FitOptions
from ..fitting.specs import find_candidate
from ..flight.reference import AIRCRAFT, FINAL_MODEL_NAMES

THESIS_COVARIANCE = "colored"


def fit_final_models(train, val, options: FitOptions, starts: Mapping[str, Mapping[str, float]],
                     names: Mapping[str, str] = FINAL_MODEL_NAMES) -> dict:
    """The thesis' three final models (or ``names``: coefficient -> model name) fitted from ``starts``
    (coefficient -> parameters), drag and pitch on the fitted lift model's states: {coefficient: (candidate,
    result)}."""
    lift, out = None, {}
    for coef, name in names.items():
        cand = find_candidate(name)
        fit = fit_candidate(cand, train, val, lift if cand.lift else None, options, start=dict(starts[coef]))
        lift = LiftFit(cand, fit) if coef == "CL" else lift
        out[coef] = (cand, fit)
    return out


def other_aircraft(campaign) -> str | None:
    """None when ``campaign`` flies the thesis' aircraft (the Citation II's reference geometry S, cbar, b), else a
    note saying why ``thesis_stderr.md``, which compares standard deviations with the thesis' Citation, is not
    written."""
    mine = {k: float(campaign.aircraft.get(k, float("nan"))) for k in AIRCRAFT}
    if all(abs(mine[k] - v) <= 1e-6 * v for k, v in AIRCRAFT.items()):
        return None
    return ("thesis_stderr.md not written: it compares standard deviations with the thesis' Citation II (S 30 m^2, "
            f"cbar 2.013 m, b 15.75 m), and this campaign's aircraft has S {mine['S']:g} m^2, cbar {mine['cbar']:g} "
            f"m, b {mine['b']:g} m")


def thesis_estimator_fits(grids: Mapping[str, Sequence], campaign) -> dict[str, list]:
    """The thesis' final models of a search refitted with the thesis' covariance estimator (starting at
    their estimates, so only the covariance changes), as {model name: [result]}; {} unless the
    search fitted all three on a campaign of the thesis' aircraft (:func:`other_aircraft`)."""
    found = {s.name: s for ranked in grids.values() for s in ranked if not s.failed}
    if not all(name in found for name in FINAL_MODEL_NAMES.values()) or other_aircraft(campaign) is not None:
        return {}
    options = FitOptions(n_starts=1, covariance=THESIS_COVARIANCE, cv_folds=0)
    starts = {coef: found[name].estimates.params for coef, name in FINAL_MODEL_NAMES.items()}
    finals = fit_final_models(campaign.split("train"), campaign.split("validation"), options, starts)
    return {cand.name: [fit] for cand, fit in finals.values()}
