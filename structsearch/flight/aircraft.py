"""Citation II (PH-LAB) mass, engine and atmosphere models for the simulator (SI units)."""
from __future__ import annotations

import numpy as np

from .reference import AIRCRAFT, EMPTY_MASS, IYY

G = 9.80665
RHO0 = 1.225
T0 = 288.15
LAPSE = 0.0065
GAS_EXPONENT = G / (287.053 * LAPSE) - 1.0
FT = 0.3048
INCH = 0.0254

# Two Pratt & Whitney JT15D-4: about 11.1 kN static sea-level thrust each.
MAX_THRUST_SL = 2 * 11_100.0
# Fuel flow at full throttle, both engines [kg/s]; scales with throttle.
MAX_FUEL_FLOW = 0.16
CREW_MASS = 3 * 85.0
# Centre of gravity envelope [m from the datum 15 in ahead of the nose] (catalogue section 6).
X_CG_RANGE = (276 * INCH, 286 * INCH)


def density(h):
    """ISA troposphere density [kg/m^3] at geometric altitude h [m]."""
    return RHO0 * (1.0 - LAPSE * np.asarray(h) / T0) ** GAS_EXPONENT


def flight_level_altitude(fl: float) -> float:
    return fl * 100 * FT


def max_thrust(h):
    """Available thrust [N] of both engines at altitude (density lapse^0.75)."""
    return MAX_THRUST_SL * (density(h) / RHO0) ** 0.75


def inertia(mass):
    """Pitch inertia [kg m^2]: the empty-mass value plus fuel and crew near the cg."""
    return IYY + 0.9 * (np.asarray(mass) - EMPTY_MASS)


S, CBAR, SPAN = AIRCRAFT["S"], AIRCRAFT["cbar"], AIRCRAFT["b"]
