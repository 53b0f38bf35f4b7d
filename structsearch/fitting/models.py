"""A candidate as a StallModel: drag and pitch candidates take the lift model's states and output."""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..data.errors import DeclarationError, StructSearchError
from ..data.flightdata import FlightData
from ..data.moment_transfer import TRANSFER_EXPRESSION, TRANSFER_NAME
from ..engine.regressors import declare
from ..engine.separation import SeparationState
from ..engine.stallmodel import StallModel
from .candidates import Candidate
from .lift_fit import LiftFit


def build_model(c: Candidate, lift: LiftFit | None = None) -> StallModel:
    """The StallModel of a candidate; ``lift`` is the fitted lift model it names."""
    if c.lift and (lift is None or lift.failed):
        raise StructSearchError(f"candidate {c.name} needs the fitted lift model {c.lift}")
    return model_with_lift(c, lift.params if c.lift else None)


def used_states(c: Candidate) -> dict[str, str]:
    """The states (name -> kind) ``c``'s regressors use: of a drag or pitch candidate, the lift model's states it
    reads (CD-X reads none); a wing state is not among them (:func:`wing_states`)."""
    states = dict(c.states)
    symbols = {SeparationState(n, k, c.form_of(n)).symbol: n for n, k in states.items()}
    wings = [SeparationState(n, "S").symbol for n, _ in c.wings]
    used = {s for name, text in c.regressors
            for s in declare(name, text, states=list(symbols) + wings, free_columns=True).states}
    return {symbols[s]: states[symbols[s]] for s in symbols if s in used}


def wing_source(c: Candidate) -> str:
    """The lift model's state each wing state of ``c`` copies: its only state, or its wing's ("w")."""
    names = [n for n, _ in c.states]
    if len(names) == 1 or "w" in names:
        return names[0] if len(names) == 1 else "w"
    raise DeclarationError(f"candidate {c.name}: its wing states copy the lift model {c.lift}'s wing state, and "
                           f"{c.lift} has neither one state nor one named 'w' ({', '.join(names) or 'none'})")


def wing_aliases(c: Candidate) -> dict[str, str]:
    """Each parameter of ``c``'s wing states -> the lift model's parameter it copies (its wing state's:
    :func:`wing_source`); empty without wing states."""
    if not c.wings:
        return {}
    source = wing_source(c)
    kind, form = dict(c.states)[source], c.form_of(source)
    shared = SeparationState(source, kind, form)
    return {SeparationState(name, kind, form).parameter_name(p): shared.parameter_name(p)
            for name, _ in c.wings for p in shared.base_parameters}


def wing_states(c: Candidate, lift_params: Mapping[str, float]) -> tuple[dict, dict, dict, dict]:
    """(states, forms, fixed parameters, drives) of ``c``'s wing states: the lift model's wing state (kind, form,
    fitted parameters) read at each wing's own angle of attack."""
    source = wing_source(c)
    kind, form = dict(c.states)[source], c.form_of(source)
    states = {name: kind for name, _ in c.wings}
    forms = {name: form for name, _ in c.wings if form != "tanh"}
    fixed = {own: lift_params[copied] for own, copied in wing_aliases(c).items()}
    return states, forms, fixed, dict(c.wings)


def model_with_lift(c: Candidate, lift_params: Mapping[str, float] | None) -> StallModel:
    """The StallModel of a candidate whose lift-model states take the separation parameters in
    ``lift_params`` (a drag or pitch candidate; ignored for the others). With ``lift_params`` empty the states'
    parameters are free (a joint fit estimates them with the lift model's)."""
    fixed = None
    states = dict(c.states)
    wings: tuple[dict, dict, dict, dict] = ({}, {}, {}, {})
    if c.lift:
        states = used_states(c)
        own = {p for n, k in states.items() for p in SeparationState(n, k, c.form_of(n)).parameters}
        fixed = {k: v for k, v in lift_params.items() if k in own}
        if c.wings:
            wings = wing_states(c, lift_params)
            fixed.update(wings[2])
    elif c.wings:
        raise DeclarationError(f"candidate {c.name}: wing states read a fitted lift model")
    free_bounds = {k: v for k, v in c.bounds if not fixed or k not in fixed}
    free_bounds = {k: v for k, v in free_bounds.items()
                   if k in {p for n, kd in states.items() for p in SeparationState(n, kd, c.form_of(n)).parameters}}
    forms = {**{n: f for n, f in c.forms if n in states}, **wings[1]}
    states.update(wings[0])
    # about the fixed reference point: C_m about the recorded cg is the model's plus the known transfer
    offset = known_offset(c)
    return StallModel.declare(c.name, c.coefficient, dict(c.regressors), states=states, fixed=fixed,
                              bounds=free_bounds, forms=forms, offset=offset, drives=wings[3])


def known_offset(c: Candidate) -> tuple[str, str] | None:
    """The known term added to ``c``'s output with coefficient 1 (None: none): the moment transfer of a pitch
    candidate about the fixed point, and the candidate's own known terms, summed into one expression."""
    parts = ([(TRANSFER_NAME, TRANSFER_EXPRESSION)] if c.moment_reference == "fixed" else []) + list(c.known)
    if len(parts) <= 1:
        return parts[0] if parts else None
    return " + ".join(n for n, _ in parts), " + ".join(f"({e})" for _, e in parts)


def with_lift_prediction(data: FlightData, lift_params: Mapping[str, float], lift_candidate: Candidate) -> FlightData:
    """``data`` with column CL replaced by the output of the lift model ``lift_candidate`` with ``lift_params``
    (the thesis feeds the lift model to drag and pitch; the measured C_L carries buffet noise that would
    bias them as errors in variables); the measured C_L is kept as CL_measured."""
    cols = dict(data.columns)
    cols["CL_measured"] = data["CL_measured"] if "CL_measured" in data else data["CL"]
    cols["CL"] = model_with_lift(lift_candidate, None).predict(data, lift_params)
    return data.with_columns(cols)


def predict_candidate(c: Candidate, params: Mapping[str, float], data: FlightData,
                      lift: LiftFit | None = None) -> np.ndarray:
    """A fitted candidate's output on ``data``; drag and pitch candidates get the lift model's C_L."""
    if c.lift and lift is not None:
        data = with_lift_prediction(data, lift.params, lift.candidate)
    return build_model(c, lift).predict(data, params)
