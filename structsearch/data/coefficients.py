"""The aerodynamic coefficients the project models: one record each, the registry every layer reads what a
coefficient is from (its grid, its JSBSim axis, whether it is a moment, whether its structures own the
separation states) instead of comparing names.

>>> COEFFICIENTS["Cm"].moment, LIFT.name, coefficient("CD").jsbsim_axis
(True, 'CL', 'DRAG')
"""
from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

from .errors import DeclarationError


@dataclass(frozen=True)
class Coefficient:
    """One aerodynamic coefficient.

    ``grid``: its shipped grid; ``jsbsim_axis``: the axis of a JSBSim aircraft that builds it; ``moment``: a
    moment coefficient (qbar S cbar C; it reads the forces too, where the moment is taken about a point);
    ``owns_states``: its structures declare the separation states (the lift model's), where the others take
    theirs, and C_L, from a lift model. ``latex``: its symbol in equations. ``k_term``: the (name, expression)
    templates of the term a new separation state brings into its structure (``{c}`` the coefficient, ``{s}`` the
    state's suffix, ``{X}`` its symbol: Kirchhoff's lift, the separation drag 1 - X, the centre-of-pressure
    shift (1 - X) C_L). ``transfer_reads``: the campaign signals the term a simulator's axis functions need beside
    them follows (a moment's transfer to the cg, the side force's turn into body axes)."""

    name: str
    quantity: str
    grid: str
    jsbsim_axis: str
    latex: str
    k_term: tuple[str, str]
    moment: bool = False
    owns_states: bool = False
    lateral: bool = False
    transfer_reads: tuple[str, ...] = ()

    @property
    def length(self) -> str:
        """The reference length a moment coefficient is made dimensionless with ("cbar" pitch, "b" roll and
        yaw; "" for a force)."""
        return ("b" if self.lateral else "cbar") if self.moment else ""


COEFFICIENTS = MappingProxyType({c.name: c for c in (
    Coefficient("CL", "lift", "lift", "LIFT", "C_L", ("{c}_KL{s}", "K_L({X})"), owns_states=True),
    Coefficient("CD", "drag", "drag", "DRAG", "C_D", ("{c}_1mX{s}", "1 - {X}")),
    Coefficient("Cm", "pitching moment", "pitch", "PITCH", "C_m", ("{c}_1mX{s}CL", "(1 - {X})*CL"), moment=True,
                transfer_reads=("CL", "x_cg")),
    # lateral-directional (body axes: side force right, rolling moment right wing down, yawing moment nose right);
    # a separation state brings the side force and yawing moment a share of the flow lost, the rolling moment the
    # roll damping lost with it
    Coefficient("CY", "side force", "side", "SIDE", "C_Y", ("{c}_1mX{s}beta", "(1 - {X})*beta"), lateral=True,
                transfer_reads=("beta", "CD")),
    Coefficient("Cl", "rolling moment", "roll", "ROLL", "C_l", ("{c}_1mX{s}p", "(1 - {X})*pstar"), moment=True,
                lateral=True, transfer_reads=("CL", "CY")),
    Coefficient("Cn", "yawing moment", "yaw", "YAW", "C_n", ("{c}_1mX{s}r", "(1 - {X})*rstar"), moment=True,
                lateral=True, transfer_reads=("CY", "CD")),
)})
LIFT = COEFFICIENTS["CL"]
# each coefficient's shipped grid, and each grid's coefficient
GRID_OF = MappingProxyType({c.name: c.grid for c in COEFFICIENTS.values()})
COEFFICIENT_OF_GRID = MappingProxyType({c.grid: c.name for c in COEFFICIENTS.values()})
# the longitudinal coefficients (what the thesis models: the demo, the report's first screen, joint fits, the
# global models) and the lateral-directional ones, each in the registry's order
LONGITUDINAL = tuple(c.name for c in COEFFICIENTS.values() if not c.lateral)
LATERAL = tuple(c.name for c in COEFFICIENTS.values() if c.lateral)
# the longitudinal forces, in the registry's order (a pitching moment about a point reads them)
FORCES = tuple(c for c in COEFFICIENTS.values() if not c.moment and not c.lateral)


def coefficient(name: str) -> Coefficient:
    """The record of coefficient ``name``; one error naming the known ones otherwise."""
    try:
        return COEFFICIENTS[name]
    except KeyError:
        raise DeclarationError(f"coefficient {name!r} is not one of {', '.join(COEFFICIENTS)}") from None
