"""Structures written as a model spec file (``model_specs/`` format) that ``fit`` and ``search`` accept."""
from __future__ import annotations

import json
from typing import Sequence

from ..fitting.candidates import Candidate

# TOML basic strings are JSON strings (the same escapes), so json.dumps quotes a key or a value for both.
_q = json.dumps


def spec_text(c: Candidate, note: str = "") -> str:
    """One candidate as a grid file of one entry (``fit --model FILE``, ``search --grid FILE``)."""
    lines = [f"# {note}" if note else "# written by structsearch discover",
             f"name = {_q(c.grid or 'discover')}", f"coefficient = {_q(c.coefficient)}",
             f"prefix = {_q(c.coefficient + '-')}"]
    if c.lift:
        lines.append(f"lift = {_q(c.lift)}")
    return "\n".join(lines + [""] + _entry_lines(c)) + "\n"


def grid_text(candidates: Sequence[Candidate], note: str) -> str:
    """Candidates of one grid (one coefficient) as a grid file of one entry each, in order: what
    :func:`structsearch.fitting.specs.load_grid` reads back into the same candidates."""
    first = candidates[0]
    if any(c.coefficient != first.coefficient or c.grid != first.grid for c in candidates):
        raise ValueError("grid_text: the candidates of one grid file share their grid and coefficient")
    lines = [f"# {note}", f"name = {_q(first.grid)}", f"coefficient = {_q(first.coefficient)}",
             f"prefix = {_q(first.coefficient + '-')}"]
    for c in candidates:
        lines += [""] + _entry_lines(c)
    return "\n".join(lines) + "\n"


def _entry_lines(c: Candidate) -> list[str]:
    lines = ["[[entry]]", f"name = {_q(c.name)}"]
    if c.note:
        lines.append(f"note = {_q(c.note)}")
    if c.lift:
        lines.append(f"lift = {_q(c.lift)}")
    lines.append("regressors = { " + ", ".join(f"{_q(n)} = {_q(e)}" for n, e in c.regressors) + " }")
    if c.moment_reference != "cg":   # C_m about the fixed reference point: read back as it was fitted
        lines.append(f"moment_reference = {_q(c.moment_reference)}")
    if c.states and not c.lift:   # a drag or pitch structure takes its states (and boxes) from its lift model
        lines.append("states = { " + ", ".join(f"{_q(n)} = {_q(k)}" for n, k in c.states) + " }")
        if c.forms:   # a state not named keeps the tanh
            lines.append("x0 = { " + ", ".join(f"{_q(n)} = {_q(f)}" for n, f in c.forms) + " }")
        own = [(n, box) for n, box in c.bounds if n in c.state_parameters]   # a box of its own parameters only
        if own:
            lines.append("bounds = { " + ", ".join(f"{_q(n)} = [{lo!r}, {hi!r}]" for n, (lo, hi) in own) + " }")
    return lines
