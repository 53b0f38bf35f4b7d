"""The kinds of separation state, their parameters, and which kind holds which (:mod:`.separation` evaluates
them)."""
from __future__ import annotations

KINDS = ("S", "Q", "U", "L", "V")
PARAMETERS_OF_KIND = {
    "S": ("a1", "a_star"),
    "Q": ("tau2", "a1", "a_star"),
    "U": ("tau1", "tau2", "a1", "a_star"),
    "L": ("tau1", "a1", "a_star"),
    "V": ("tau1", "tau_v", "a1", "a_star"),
}
# the time constants of each kind, before the static curve's parameters
TIME_PARAMETERS_OF_KIND = {"S": (), "Q": ("tau2",), "U": ("tau1", "tau2"), "L": ("tau1",), "V": ("tau1", "tau_v")}


def is_lagged(kind: str) -> bool:
    """Whether a state of ``kind`` lags its static value (has tau1): U and L."""
    return "tau1" in TIME_PARAMETERS_OF_KIND[kind]


def is_delayed(kind: str) -> bool:
    """Whether a state of ``kind`` reads alpha - tau2 alpha_dot (has tau2): Q and U."""
    return "tau2" in TIME_PARAMETERS_OF_KIND[kind]


def is_vortex(kind: str) -> bool:
    """Whether a state of ``kind`` is a vortex strength (the high-pass of a lagged separation, has tau_v): V."""
    return "tau_v" in TIME_PARAMETERS_OF_KIND[kind]


# (simpler, richer): the richer kind reaches the simpler at a time constant of zero (S is Q at tau2 = 0, L at
# tau1 = 0; Q and L are U at tau1 = 0 and tau2 = 0). Q and L do not nest each other, and a vortex state nests no
# other kind (its value is a high-pass of the separation, zero where the others are X0).
_NESTS = frozenset({("S", "Q"), ("S", "L"), ("S", "U"), ("Q", "U"), ("L", "U")})


def nests(inner: str, outer: str) -> bool:
    """Whether a state of kind ``outer`` holds one of kind ``inner`` (the same kind, or one it reaches)."""
    return inner == outer or (inner, outer) in _NESTS
