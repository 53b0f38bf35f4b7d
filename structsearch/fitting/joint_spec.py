"""The structures of a joint fit (:mod:`structsearch.fitting.joint`): the checks that two or three structures can be
fitted jointly (one per coefficient, sharing separation states with the lift model), and ``fit --joint``'s
names, spec files or joint spec file."""
from __future__ import annotations

from typing import Sequence

from ..data.errors import DeclarationError
from ..engine.separation import SeparationState
from .candidates import Candidate
from .models import used_states
from ..data.reading import shown


def check_joint(candidates: Sequence[Candidate]) -> tuple[Candidate | None, list[Candidate]]:
    """The lift structure (or None) and the drag and pitch ones; one clear error for a joint fit that cannot be."""
    if len(candidates) < 2:
        raise DeclarationError("a joint fit needs two or three structures (lift, drag, pitch)")
    coefs = [c.coefficient for c in candidates]
    twice = sorted({c for c in coefs if coefs.count(c) > 1})
    if twice:
        raise DeclarationError(f"a joint fit names the coefficient {twice[0]} twice "
                               f"({', '.join(c.name for c in candidates if c.coefficient == twice[0])})")
    lifts = [c for c in candidates if c.coefficient == "CL"]
    lift = lifts[0] if lifts else None
    others = [c for c in candidates if c.coefficient != "CL"]
    for c in others:
        if not c.lift:
            raise DeclarationError(f"{c.name} reads no lift model's states: a joint fit shares separation states")
        if lift is not None:
            own = used_states(c)
            theirs = dict(lift.states)
            missing = [n for n, k in own.items() if theirs.get(n) != k or c.form_of(n) != lift.form_of(n)]
            if missing:
                raise DeclarationError(
                    f"{c.name} uses the state(s) {', '.join('X_' + n if n else 'X' for n in missing)} of its lift "
                    f"model {c.lift}, which the joint lift structure {lift.name} does not have with the same kind and form "
                    f"({', '.join(f'{n or chr(88)}: {k}' for n, k in theirs.items()) or 'no state'})")
    shared = set.intersection(*[set(_params_of(c)) for c in candidates])
    if not shared:
        raise DeclarationError(f"{', '.join(c.name for c in candidates)} share no separation state: a joint fit "
                               "would be separate fits")
    if lift is None and len({c.lift for c in others}) > 1:
        raise DeclarationError(f"{', '.join(c.name for c in others)} read different lift models "
                               f"({', '.join(sorted({c.lift for c in others}))})")
    return lift, others


def _params_of(c: Candidate) -> list[str]:
    states = dict(c.states) if c.coefficient == "CL" else used_states(c)
    return [p for n, k in states.items() for p in SeparationState(n, k, c.form_of(n)).parameters]


def joint_structures(spec: str) -> list[Candidate]:
    """The structures of ``fit --joint``: comma-separated names or spec files, or a joint spec file (TOML)::

        [joint]
        structures = ["CL-VI", "CD-IXr", "Cm-XXXIIIr"]   # names or model spec files

    The structures share the separation states they have in common, by name (X_ss, X_w): a drag or pitch
    structure's states are its lift model's. One clear error naming the file and the entry otherwise."""
    from pathlib import Path
    from .specs import read_toml, resolve_candidate
    items: list[str]
    path = Path(spec)
    if path.suffix == ".toml" and "," not in spec:
        doc = read_toml(path)
        joint = doc.get("joint")
        if not isinstance(joint, dict) or not isinstance(joint.get("structures"), list) or \
                not all(isinstance(s, str) for s in joint["structures"]):
            raise DeclarationError(f"{path}: a joint spec needs [joint] structures = [\"LIFT\", \"DRAG\", ...] "
                                   "(names or model spec files)")
        items = [s if not s.endswith(".toml") or Path(s).is_absolute() else str(path.parent / s)
                 for s in joint["structures"]]
        where = f"{path}: "
    else:
        items = [s.strip() for s in spec.split(",") if s.strip()]
        where = "--joint: "
    out = []
    for item in items:
        try:
            out.append(resolve_candidate(item))
        except DeclarationError as exc:
            raise DeclarationError(f"{where}structure {shown(item)}: {exc}") from None
    try:
        check_joint(out)
    except DeclarationError as exc:
        raise DeclarationError(f"{where}{exc}") from None
    return out
