"""``--modify``'s ``[[wing_drop]]``: an asymmetric stall flown in a JSBSim aircraft, a separation state per wing::

    [[wing_drop]]
    a_star = 0.30       # rad: where each wing's static separation curve is at one half
    a1 = 30.0           # 1/rad: its steepness (X0 = 0.5 (1 - tanh(a1 (alpha_wing - a_star))))
    tau1 = 0.1          # s: each wing's separation lag, tau1 dX/dt + X = X0
    eta = 0.5           # the wing's effective span station over the half span
    asymmetry = 0.01    # rad: the right wing's a_star lies this much below the left one's (optional, 0)
    roll = 0.05         # C_l per unit of X_left - X_right: the more separated wing drops
    yaw = 0.01          # C_n per unit of X_left - X_right (optional, 0): and yaws the nose toward it
    function = "aero/coefficient/CLwbh"   # optional: an axis function that reads the wings' mean separation,
    input = "aero/stall-hyst-norm"        # 1 - (X_left + X_right)/2, where it read this property (a stall latch)

Each wing sees its own angle of attack, alpha -+ eta p b / (2 V) (the right wing, going down when p > 0, sees
more). A system (``structsearch-wing-drop``) computes both states in the aircraft's flight-control loop, each a
JSBSim ``lag_filter`` of its static curve; the ROLL and YAW axes gain a function each,
q S b roll (X_left - X_right) and q S b yaw (X_left - X_right). Fed back through the roll rate, the wing that
separates first drops and separates further: the wing drop of an asymmetric stall. The states are the properties
``structsearch/wing-drop/X-left`` and ``.../X-right``. With ``function`` and ``input`` the lift stalls with the
wings: c172p's lift table, which picks its attached or stalled column by its stall latch, blends them by the wings'
mean separation instead (as ``[[state]]`` with ``complement`` does).
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, fields

from ..data.errors import DeclarationError

NAMESPACE = "structsearch/wing-drop"
STATES = {"X_left": f"{NAMESPACE}/X-left", "X_right": f"{NAMESPACE}/X-right"}
# pstar = p b / (2 V) in JSBSim's own properties
PSTAR = ("velocities/p-aero-rad_sec", "aero/bi2vel")
MOMENT = ("aero/qbar-psf", "metrics/Sw-sqft", "metrics/bw-ft")
REQUIRED = ("a_star", "a1", "tau1", "eta", "roll")
OPTIONAL = ("asymmetry", "yaw", "function", "input")
SEPARATED = f"{NAMESPACE}/separated"


@dataclass(frozen=True)
class WingDrop:
    """One ``[[wing_drop]]`` entry (module docstring)."""

    a_star: float
    a1: float
    tau1: float
    eta: float
    roll: float
    asymmetry: float = 0.0
    yaw: float = 0.0
    function: str = ""
    input: str = ""
    entry: str = "[[wing_drop]]"

    def key(self) -> str:
        return "wing-drop:" + ",".join(f"{f.name}={getattr(self, f.name)!r}" for f in fields(self)
                                       if f.name != "entry")


def _element(tag: str, *children: ET.Element, text: str | None = None, **attributes) -> ET.Element:
    e = ET.Element(tag, attributes)
    e.extend(children)
    if text is not None:
        e.text = text
    return e


def _prop(name: str) -> ET.Element:
    return _element("property", text=name)


def _value(number: float) -> ET.Element:
    return _element("value", text=repr(float(number)))


def _static(drop: WingDrop, side: int) -> ET.Element:
    """X0 of one wing (``side`` +1 right, -1 left) at its own alpha: 1 / (1 + exp(2 a1 (alpha_wing - a_star)))."""
    a_star = drop.a_star - side * drop.asymmetry / 2.0
    alpha = _element("sum", _prop("aero/alpha-rad"),
                     _element("product", _value(side * drop.eta), *map(_prop, PSTAR)))
    exponent = _element("product", _value(2.0 * drop.a1), _element("difference", alpha, _value(a_star)))
    return _element("quotient", _value(1.0), _element("sum", _value(1.0), _element("exp", exponent)))


def system(drop: WingDrop) -> ET.Element:
    """The ``<system>`` computing both wings' states (module docstring)."""
    parts = []
    for side, symbol in ((-1, "X_left"), (1, "X_right")):
        static = f"{STATES[symbol]}-static"
        parts.append(_element("fcs_function", _element("function", _static(drop, side)), _element("output", text=static),
                              name=static))
        # C1 / (s + C1): tau1 dX/dt + X = X0, starting at its input
        parts.append(_element("lag_filter", _element("input", text=static), _element("c1", text=repr(1.0 / drop.tau1)),
                              _element("output", text=STATES[symbol]), name=STATES[symbol]))
    return _element("system", _element("channel", *parts, name="structsearch wing drop"), name="structsearch-wing-drop")


def moment_function(drop: WingDrop, axis: str) -> ET.Element:
    """The ROLL (``roll``) or YAW (``yaw``) function q S b k (X_left - X_right)."""
    factor = drop.roll if axis == "ROLL" else drop.yaw
    difference = _element("difference", _prop(STATES["X_left"]), _prop(STATES["X_right"]))
    return _element("function", _element("product", *map(_prop, MOMENT), _value(factor), difference),
                    name=f"{NAMESPACE}/C{'l' if axis == 'ROLL' else 'n'}")


def separated() -> ET.Element:
    """The wings' mean separation, 1 - (X_left + X_right) / 2, as a function ahead of the axes."""
    mean = _element("product", _value(0.5), _element("sum", _prop(STATES["X_left"]), _prop(STATES["X_right"])))
    return _element("function", _element("difference", _value(1.0), mean), name=SEPARATED)


def insert(doc: ET.Element, aero: ET.Element, drop: WingDrop, aircraft: str) -> None:
    """The wing drop's system ahead of the aerodynamics, and its functions in the ROLL and YAW axes (the function
    reading the wings' mean separation: :func:`structsearch.foreign.private_copy.make_copy`)."""
    doc.insert(list(doc).index(aero), system(drop))
    for axis in ("ROLL", "YAW"):
        found = [a for a in aero.findall("axis") if a.get("name") == axis]
        if not found:
            raise DeclarationError(f"--modify: {drop.entry}: the aircraft {aircraft} has no {axis} axis to carry "
                                   "the wing drop's moment")
        found[0].append(moment_function(drop, axis))
