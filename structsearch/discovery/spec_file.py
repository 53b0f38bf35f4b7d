"""A structure written as a model spec file (``model_specs/`` format) that ``fit`` and ``search`` accept."""
from __future__ import annotations

import json

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
    lines += ["", "[[entry]]", f"name = {_q(c.name)}"]
    if c.note:
        lines.append(f"note = {_q(c.note)}")
    if c.lift:
        lines.append(f"lift = {_q(c.lift)}")
    lines.append("regressors = { " + ", ".join(f"{_q(n)} = {_q(e)}" for n, e in c.regressors) + " }")
    if c.states and not c.lift:   # a drag or pitch structure takes its states (and boxes) from its lift model
        lines.append("states = { " + ", ".join(f"{_q(n)} = {_q(k)}" for n, k in c.states) + " }")
        if c.bounds:
            lines.append("bounds = { " + ", ".join(f"{_q(n)} = [{lo!r}, {hi!r}]" for n, (lo, hi) in c.bounds) + " }")
    return "\n".join(lines) + "\n"
