"""A model set: one simulator's lift, drag and pitch structures fitted together on the training maneuvers
(drag and pitch on the lift model's separation states), through the search's cache. The report draws it and the
study compares it; a set's coefficients are predicted on any data.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..data.coefficients import LONGITUDINAL
from ..data.errors import DeclarationError
from ..data.flightdata import FlightData
from ..flight.aero import AeroModel
from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
from ..fitting.lift_fit import LiftFit
from ..fitting.models import build_model, predict_candidate
from ..fitting.fitter import Fitter
from ..fitting.specs import find_candidate



@dataclass(frozen=True)
class ModelSet:
    """Lift, drag and pitch structures fitted together (drag and pitch on the lift model's states)."""

    label: str
    candidates: Mapping[str, Candidate]
    summaries: Mapping[str, CandidateResult]
    aero: AeroModel

    @property
    def lift_summary(self) -> CandidateResult:
        return self.summaries["CL"]

    @property
    def lift(self) -> LiftFit:
        """The set's lift model, as its drag and pitch models use it."""
        return LiftFit(self.candidates["CL"], self.summaries["CL"])

    def predict(self, coef: str, data: FlightData, candidate: Candidate | None = None,
                params: dict | None = None) -> np.ndarray:
        """Output of the set's ``coef`` model (or of ``candidate`` with ``params`` in its place) on ``data``."""
        c = candidate or self.candidates[coef]
        return predict_candidate(c, params or self.summaries[coef].estimates.params, data,
                                 None if coef == "CL" else self.lift)


def fit_model_set(label: str, names: Mapping[str, str | Candidate], fitter: Fitter) -> ModelSet:
    """Fit the lift, drag and pitch structures (named, or candidates such as a search's refined ones; with
    ``fitter``: cached, on its workers)."""
    cands = {coef: names[coef] if isinstance(names[coef], Candidate) else find_candidate(names[coef])
             for coef in LONGITUDINAL}
    for coef in ("CD", "Cm"):
        if cands[coef].lift != cands["CL"].name:
            raise DeclarationError(f"{cands[coef].name} takes its separation states from {cands[coef].lift}, "
                                   f"not from the lift model {cands['CL'].name} of the same model set")
    lift = fitter.fit_one(cands["CL"])
    others = fitter.with_lifts({cands["CL"].name: LiftFit(cands["CL"], lift)}).fit([cands["CD"], cands["Cm"]])
    summaries = {"CL": lift, "CD": others[0], "Cm": others[1]}
    for coef, s in summaries.items():
        if s.failed:
            raise DeclarationError(f"report: fitting {cands[coef].name} failed: {s.error}")
    params = dict(lift.estimates.params)
    for coef in ("CD", "Cm"):
        params.update({k: v for k, v in summaries[coef].estimates.params.items() if k not in lift.estimates.params})
    lift_fit = LiftFit(cands["CL"], lift)
    aero = AeroModel(build_model(cands["CL"]), build_model(cands["CD"], lift_fit), build_model(cands["Cm"], lift_fit),
                     params, name=label)
    return ModelSet(label, cands, summaries, aero)


def fit_with_effect(ms: ModelSet, coef: str, effect: str, fitter: Fitter) -> tuple[Candidate, CandidateResult]:
    """The set's ``coef`` model after a diagnosis' move (a library effect's name or a structural move's label),
    fitted (with ``fitter``) on the set's lift model: the "after" of the report's gap breakdown."""
    from ..discovery.moves import generate
    from ..discovery.terms import library_for
    base = ms.candidates[coef]
    lift_candidates = {} if coef == "CL" else {ms.lift.name: ms.lift.candidate}
    found = [child for move, child in generate(base, library_for(coef, fitter.campaign.split("train")), lift_candidates)
             if move.name == effect]
    if not found:
        raise DeclarationError(f"report: no move {effect!r} applies to {base.name}")
    changed = found[0]
    result = (fitter if coef == "CL" else fitter.with_lifts({ms.lift.name: ms.lift})).quiet().fit_one(changed)
    if result.failed:
        raise DeclarationError(f"report: fitting {changed.name} failed: {result.error}")
    return changed, result
