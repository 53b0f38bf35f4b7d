"""Data reduction: aerodynamic coefficients from recorded flight-test channels (thesis Eqs. 1-4).

Pure functions on arrays (SI units, angles in radians, body axes x forward, z down). The simulator's
measurement chain and the preprocessing of raw campaigns use the same equations.
"""
from __future__ import annotations

import numpy as np

G = 9.80665
RHO0 = 1.225
T0 = 288.15
LAPSE = 0.0065
GAS_EXPONENT = G / (287.053 * LAPSE) - 1.0


def isa_density(h):
    """ISA troposphere density [kg/m^3] at geometric altitude h [m]."""
    return RHO0 * (1.0 - LAPSE * np.asarray(h) / T0) ** GAS_EXPONENT


def isa_speed_of_sound(h):
    """ISA troposphere speed of sound [m/s] at geometric altitude h [m] (air as a perfect gas, gamma 1.4)."""
    return np.sqrt(1.4 * 287.053 * (T0 - LAPSE * np.asarray(h)))


def air_data(V, h) -> tuple[np.ndarray, np.ndarray]:
    """Mach number and dynamic pressure [Pa] of true airspeed ``V`` [m/s] at altitude ``h`` [m] (ISA), as an
    air-data computer gives them."""
    V = np.asarray(V, float)
    return V / isa_speed_of_sound(h), 0.5 * isa_density(h) * V * V


def specific_force_at_cg(ax, az, q, q_dot, position):
    """Specific force at the cg from an accelerometer at ``position`` = (x, y, z) from the cg, for a body
    pitching at q, q_dot without roll or yaw: a_cg = a_acc - q_dot x r - q x (q x r), longitudinal parts."""
    x, _, z = position
    return ax + q * q * x - q_dot * z, az + q_dot * x + q * q * z


def specific_force_at_accelerometer(ax_cg, az_cg, q, q_dot, position):
    """The inverse of :func:`specific_force_at_cg`: what an accelerometer at ``position`` reads,
    a_acc = a_cg + q_dot x r + q x (q x r) (the simulator's instrumentation model)."""
    x, _, z = position
    return ax_cg - q * q * x + q_dot * z, az_cg - q_dot * x - q * q * z


def body_from_lift_drag(cl, cd, alpha):
    """The inverse of :func:`lift_drag`: C_X and C_Z from C_L, C_D at angle of attack alpha."""
    return -cd * np.cos(alpha) + cl * np.sin(alpha), -cl * np.cos(alpha) - cd * np.sin(alpha)


def body_force_coefficients(ax, az, mass, thrust, qbar_s):
    """C_X and C_Z from the specific forces at the cg (Eq. 3): the aerodynamic force over q S, with the
    thrust (along body x) removed from the x force."""
    return (mass * ax - thrust) / qbar_s, mass * az / qbar_s


def lift_drag(cx, cz, alpha):
    """C_L and C_D from the body-axis C_X, C_Z (the stability-axis rotation by alpha, Eq. 4)."""
    return cx * np.sin(alpha) - cz * np.cos(alpha), -cx * np.cos(alpha) - cz * np.sin(alpha)


def pitch_moment_coefficient(q_dot, iyy, qbar_s, cbar, *, thrust=0.0, thrust_line_z=0.0, p=0.0, r=0.0,
                             ixx=0.0, izz=0.0, ixz=0.0):
    """C_m about the cg from the pitch equation (Eq. 2): M = Iyy q_dot + (Ixx - Izz) p r + Ixz (p^2 - r^2),
    less the thrust's moment T z_T (thrust along body x, its line ``thrust_line_z`` below the cg)."""
    moment = iyy * q_dot + (ixx - izz) * p * r + ixz * (p * p - r * r) - thrust * thrust_line_z
    return moment / (qbar_s * cbar)
