"""A global model's parts that each flow regime alone can identify (``fit --by-kind``).

A global model (model_specs/global.toml) holds separation states for the stall and attached-flow terms over Mach
number and dynamic pressure for the envelope. Fitted to one kind of maneuver alone, part of it is not identified,
and the comparison model is what is:

* on the stall maneuvers (:func:`stall_part`): every regressor without a separation state that is zero on every
  training sample (a hinge above the stall maneuvers' Mach numbers or dynamic pressures) is dropped, named;
* on the nominal maneuvers (:func:`attached_part`): alpha never reaches the stall, so the separation states sit at
  attached flow (X = 1) and their parameters cannot be placed. The model fitted is the global one with every state
  at 1: a regressor that vanishes there is dropped, regressors that coincide there are one parameter (their sum),
  and the separation parameters are named unidentifiable. The comparison model is the attached-flow part, stated
  as such, never a stall model fitted to data without a stall. A drag or pitch part reads the C_L of its lift
  model's attached-flow part fitted on the same maneuvers, as the global model reads the global lift model's: the
  measured C_L would hand it each validation maneuver's own measurement noise, which is correlated with that of
  C_D and C_m (both are rotations of the measured C_X and C_Z), and errors in variables besides.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..data.errors import DeclarationError
from ..data.flightdata import FlightData
from ..engine.regressors import declare
from ..engine.separation import SeparationState
from .candidates import Candidate

NOT_PLACED = "separation parameter: the nominal maneuvers never reach the stall (the states stay attached)"
VANISHES = "its regressor is zero at attached flow (X = 1)"
ZERO_ON_STALL = "its regressor is zero on every training sample of the stall maneuvers"


@dataclass(frozen=True)
class Part:
    """The model a regime identifies: its candidate, the global model's parameters it cannot estimate (name,
    reason) and the parameters it estimates as sums of the global model's (name, the names summed)."""

    candidate: Candidate
    unidentifiable: tuple[tuple[str, str], ...] = ()
    sums: tuple[tuple[str, tuple[str, ...]], ...] = ()


def _symbols(c: Candidate) -> list[str]:
    return [SeparationState(n, k).symbol for n, k in c.states]


def _parameters(c: Candidate, lift: Candidate | None) -> tuple[str, ...]:
    own = c.state_parameters
    return own if own or lift is None else lift.state_parameters


def attached_part(c: Candidate, lift: Candidate | None = None, lift_name: str | None = None) -> Part:
    """``c`` with every separation state at attached flow (X = 1): the nominal maneuvers' comparison model.
    ``lift``: the lift candidate whose states a drag or pitch candidate reads (their parameters are named too);
    ``lift_name``: the name its lift model (itself an attached part) is fitted under, by default
    ``"<c.lift>.nominal"`` (:func:`attached_part` of the lift model's name)."""
    symbols = _symbols(c)
    kept: list[tuple[str, sp.Expr, str]] = []
    dropped, sums = [], {}
    for name, text in c.regressors:
        r = declare(name, text, states=symbols, context=f"{c.name}, regressor {name!r}", free_columns=True)
        if not r.states:
            kept.append((name, r.expr, text))
            continue
        expr = sp.simplify(r.expr.subs({sp.Symbol(s, real=True): 1 for s in r.states}))
        if expr == 0:
            dropped.append((name, VANISHES))
            continue
        twin = next((k for k in kept if sp.simplify(k[1] - expr) == 0), None)
        if twin is None:
            kept.append((name, expr, str(expr)))
        else:
            sums.setdefault(twin[0], [twin[0]]).append(name)
    regressors = tuple((_sum_name(sums.get(n, [n])), text) for n, _, text in kept)
    if not regressors:
        raise DeclarationError(f"{c.name}: no regressor is left at attached flow")
    reads = (lift_name or f"{c.lift}.nominal") if c.lift else None
    part = Candidate(f"{c.name}.nominal", c.grid, c.coefficient, regressors, (), reads,
                     f"the attached-flow part of {c.name} (every separation state at 1)")
    unidentifiable = tuple((p, NOT_PLACED) for p in _parameters(c, lift)) + tuple(dropped)
    return Part(part, unidentifiable, tuple((_sum_name(v), tuple(v)) for v in sums.values()))


def _sum_name(names) -> str:
    """The parameter that stands for the sum of ``names`` at attached flow (a plain identifier)."""
    return "_plus_".join(names)


def stall_part(c: Candidate, train: FlightData, lift_name: str | None = None) -> Part:
    """``c`` without the regressors (free of separation states) that are zero on every training sample of the
    stall maneuvers ``train``: the stall maneuvers' comparison model. ``lift_name``: the name its lift model
    (itself a stall part) is fitted under."""
    symbols = _symbols(c)
    kept, dropped = [], []
    for name, text in c.regressors:
        r = declare(name, text, states=symbols, context=f"{c.name}, regressor {name!r}", free_columns=True)
        if not r.states and not np.any(r.value(train, {}, train.n_samples)):
            dropped.append((name, ZERO_ON_STALL))
        else:
            kept.append((name, text))
    part = Candidate(f"{c.name}.stall", c.grid, c.coefficient, tuple(kept), c.states,
                     lift_name if c.lift else None, f"{c.name} without the terms the stall maneuvers never excite",
                     c.bounds)
    return Part(part, tuple(dropped))
