"""A twin-jet transport for the simulator: our own data, not a certified aircraft's.

Geometry of the A320 class (public figures: S = 122.6 m^2, cbar = 4.19 m, b = 34.1 m); mass,
inertia, engines and aerodynamics are round numbers we chose to be plausible for a 50 t twin-jet
(README, "A second aircraft"). Unlike the Citation II it has **one** flow-separation state (no
stall strips: the whole wing separates together, X with alpha* = 15 deg) and it flies at a fixed,
unrecorded centre of gravity, so its campaign has no x_cg column and its pitch model no x_cg term.

The separation state's time constants are the Citation's in nondimensional time
(tau* = tau V / cbar: 15 for the lag, 12 for the delay) at a stall speed of 95 m/s.
"""
from __future__ import annotations

from ..engine.stallmodel import StallModel
from .aircraft import Aircraft

TRANSPORT = Aircraft(
    name="transport", label="twin-jet transport", S=122.6, cbar=4.19, b=34.1,
    empty_mass=43_000.0, crew_mass=4 * 85.0, iyy_empty=2.2e6, iyy_per_kg=4.0,
    max_thrust_sl=2 * 120_000.0, max_fuel_flow=2.4, x_cg_range=None, records_cg=False,
    # an inertial reference unit, and rates that vibrate less in buffet: the Citation's errors in C_m
    # terms (Iyy / (qbar S cbar) is about 5 times the Citation's at the stall speeds flown)
    gyro_noise=0.0004, gyro_buffet=0.0008)

# The one state: X (parameters tau1, tau2, a1, a_star), unsteady.
TRANSPORT_LIFT = {
    "tau1": 0.65, "tau2": 0.50, "a1": 24.0, "a_star": 0.26,
    "CL0": 0.20, "CL_KL": 5.0, "CL_qstar": 7.0, "CL_de": 0.35,
}
TRANSPORT_DRAG = {"CD0": 0.022, "CD_CT": 0.12, "CD_de": -0.06, "CD_CL2": 0.045, "CD_1mX": 0.16}
# Statically stable (dCm/dCL = -0.12 attached), nose-down pitch break, elevator losing 30 % of its
# power at full separation; underwing engines pitch the nose up.
TRANSPORT_PITCH = {
    "Cm0": 0.03, "Cm_CT": 0.12, "Cm_qstar": -12.0, "Cm_de": -0.9, "Cm_CL": -0.12,
    "Cm_1mXCL": -0.08, "Cm_Xde": -0.4,
}
# What withholding an effect of docs/interfaces.md section 3 zeroes in this truth model.
TRANSPORT_ZEROED = {
    "pitch_rate": ("CL_qstar",),
    "elevator": ("CL_de", "CD_de"),
    "elevator_effectiveness_loss": ("Cm_Xde",),
    "thrust": ("CD_CT", "Cm_CT"),
    "induced_drag": ("CD_CL2",),
    "separation_drag": ("CD_1mX",),
    "cp_shift": ("Cm_1mXCL",),
}
_SEPARATION = ("tau1", "tau2", "a1", "a_star")


def transport_lift_model() -> StallModel:
    """One unsteady state X; K_L(X), q*, delta_e and C_L0."""
    return StallModel.declare(
        "transport lift", "CL", states={"": "U"},
        regressors={"CL0": "1", "CL_KL": "K_L(X)", "CL_qstar": "qstar", "CL_de": "de"})


def transport_drag_model(lift_params=TRANSPORT_LIFT) -> StallModel:
    return StallModel.declare(
        "transport drag", "CD", states={"": "U"},
        fixed={k: lift_params[k] for k in _SEPARATION if k in lift_params},
        regressors={"CD0": "1", "CD_CT": "CT", "CD_de": "de", "CD_CL2": "CL**2", "CD_1mX": "1 - X"})


def transport_pitch_model(lift_params=TRANSPORT_LIFT) -> StallModel:
    return StallModel.declare(
        "transport pitch", "Cm", states={"": "U"},
        fixed={k: lift_params[k] for k in _SEPARATION if k in lift_params},
        regressors={"Cm0": "1", "Cm_CT": "CT", "Cm_qstar": "qstar", "Cm_de": "de", "Cm_CL": "CL",
                    "Cm_1mXCL": "(1 - X)*CL", "Cm_Xde": "X*de"})
