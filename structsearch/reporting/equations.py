"""A candidate structure written as equations (:mod:`structsearch.engine.equations` writes them): its
coefficient as the sum of its parameters times their regressors, each separation state's equation, and what the
helper functions in its regressors stand for."""
from __future__ import annotations

from typing import Mapping

from ..engine.equations import HELPER_MEANINGS, write_equations
from ..engine.equations import helpers_used as _helpers_used
from ..engine.equations import model_equation as _model_equation
from ..engine.equations import state_equation
from ..fitting.candidates import Candidate
from ..fitting.models import known_offset

__all__ = ["HELPER_MEANINGS", "equations", "helpers_used", "model_equation", "state_equation", "latex_equations"]


def _offset(c: Candidate) -> tuple[str, str] | None:
    """The known term of a pitch candidate about the fixed reference point (docs/interfaces.md 7.5) and the
    candidate's own known terms, else None."""
    return known_offset(c)


def model_equation(c: Candidate) -> str:
    """``c``'s coefficient as the sum of its parameters times their regressors (and the known terms: the moment
    transfer of a pitch candidate about the fixed point)."""
    line = _model_equation(c.coefficient, c.regressors)
    offset = _offset(c)
    return line.replace(" = ", f" = {offset[0]} + ", 1) if offset else line


def helpers_used(c: Candidate) -> list[str]:
    """The meaning of every helper function ``c``'s regressors call, in the order of :data:`HELPER_MEANINGS`."""
    return _helpers_used([text for _, text in c.regressors])


def _states(c: Candidate) -> list[tuple[str, str, str]]:
    return [(n, k, c.form_of(n)) for n, k in c.states]


def _state_note(c: Candidate) -> str:
    return f"  (a state of the lift model {c.lift}, its parameters fixed at that model's fit)" if c.lift else ""


def equations(c: Candidate, values: Mapping[str, float | str] | None = None) -> list[str]:
    """Every line that states ``c``: its model equation, its states' equations (a drag or pitch candidate's are
    its lift model's, with that model's fitted parameters) and the helpers it calls. With ``values`` (estimates
    by parameter name), each parameter that has one is written as its value (4 significant digits; a text value, such
    as "(0.12 ± 0.01)", as it is)."""
    return list(write_equations(c.coefficient, c.regressors, _states(c), state_note=_state_note(c),
                                values=values, offset=_offset(c)).text)


def latex_equations(c: Candidate) -> list[str]:
    """``c``'s model and state equations in LaTeX (one equation a line, no delimiters)."""
    return list(write_equations(c.coefficient, c.regressors, _states(c), offset=_offset(c)).latex)
