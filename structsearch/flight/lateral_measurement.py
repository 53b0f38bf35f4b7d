"""The lateral-directional measurement chain: sideslip vane, roll and yaw rate gyros, lateral accelerometer, bank
angle and the aileron and rudder synchros at their rates, with buffet while the flow is separated, pre-filtered
(thesis Table 5's cut-offs), and the reconstruction of C_Y, C_l and C_n.

Sign conventions (body axes, as JSBSim's): beta positive with the relative wind from the right, p right wing down,
r nose right; C_Y positive to the right, C_l right wing down, C_n nose right; the aileron ``da`` is JSBSim's left
aileron position (positive trailing edge down, the right one up: it rolls the aircraft right) and the rudder ``dr``
positive trailing edge left (it yaws the aircraft left).

The reconstruction is the rigid-body moment equations with the measured rates' derivatives (as C_m is reconstructed
from the pitch acceleration), the product of inertia I_xz in the standard convention (the integral of x z dm)::

    C_Y = m a_y / (qbar S) - C_Y,engine
    C_l = (I_xx p' - I_xz (r' + p q) + (I_zz - I_yy) q r) / (qbar S b) - C_l,engine
    C_n = (I_zz r' - I_xz (p' - q r) + (I_yy - I_xx) p q) / (qbar S b) - C_n,engine

with the engine's force and moments removed as the longitudinal reduction removes its thrust (known, as the thrust
is). With the roll and yaw rates measured, C_m gains the inertial coupling the pitch equation holds
(:func:`pitch_coupling`): I_yy q' + (I_xx - I_zz) p r + I_xz (p^2 - r^2). Nothing here is drawn from the
generator the longitudinal chain uses: a campaign with the lateral channels has the same longitudinal readings as
one without (C_m differs by the coupling alone).
"""
from __future__ import annotations

import numpy as np

from ..data.prefilter import derivative, prefilter
from .measurement import NOISE, RATES, sensor, separation_of, vibration

# Noise standard deviations (SI) of the lateral sensors as left after flight-path reconstruction: the sideslip vane
# as the alpha vane, the rate gyros as a general-aviation AHRS's, the lateral accelerometer as the normal one's,
# the synchros as the elevator's.
LATERAL_NOISE = {"beta": NOISE["alpha"], "p": 0.0005, "r": 0.0005, "ay": NOISE["az"], "phi": NOISE["theta"],
                 "da": NOISE["de"], "dr": NOISE["de"]}
LATERAL_BIAS = {"beta": 0.0005, "p": 0.0002, "r": 0.0002, "ay": 0.01}
# buffet at unit separation: the lateral accelerometer and the roll gyro feel the wing's buffet, less than the
# normal accelerometer does
BUFFET_AY = 0.2      # m/s^2
BUFFET_P = 0.004     # rad/s
LATERAL_COLUMNS = ("beta", "p", "r", "phi", "da", "dr", "CY", "Cl", "Cn")


def _readings(rng: np.random.Generator, t: np.ndarray, truth: dict, ay_true: np.ndarray) -> dict:
    """The raw readings of the lateral sensors (with buffet), drawn from ``rng`` in this order."""
    fs = 1.0 / (t[1] - t[0])
    separation = separation_of(truth["states"], len(t))
    buffet = vibration(rng, len(t), fs) * separation
    gyro_buffet = vibration(rng, len(t), fs) * separation
    noise, bias = LATERAL_NOISE, LATERAL_BIAS
    return {
        "beta": sensor(rng, t, truth["beta"], RATES["boom"], noise["beta"], rng.normal(0, bias["beta"])),
        "p": sensor(rng, t, truth["p"] + BUFFET_P * gyro_buffet, RATES["ahrs"], noise["p"], rng.normal(0, bias["p"])),
        "r": sensor(rng, t, truth["r"], RATES["ahrs"], noise["r"], rng.normal(0, bias["r"])),
        "ay": sensor(rng, t, ay_true + BUFFET_AY * buffet, RATES["ahrs"], noise["ay"], rng.normal(0, bias["ay"])),
        "phi": sensor(rng, t, truth["phi"], RATES["ahrs"], noise["phi"]),
        "da": sensor(rng, t, truth["da"], RATES["synchro"], noise["da"]),
        "dr": sensor(rng, t, truth["dr"], RATES["synchro"], noise["dr"]),
    }


def measure_lateral(rng: np.random.Generator, t: np.ndarray, truth: dict, longitudinal: dict, span: float,
                    area: float) -> dict:
    """One maneuver's lateral columns (module docstring) from its truth histories and the longitudinal chain's
    columns of the same maneuver (``longitudinal``: its filtered pitch rate ``q``, dynamic pressure ``qbar`` and
    the mass the reduction takes; :func:`.measurement.measure` with ``record_qbar``).

    ``truth`` holds 1-D arrays: beta, p, r, phi, da, dr, qbar, mass, Ixx, Iyy, Izz, Ixz (standard convention),
    CY, Cl, Cn (the aerodynamic coefficients about the cg), the engine's fy_engine [N], cl_engine and cn_engine
    (its moments as coefficients), and ``states`` (what buffet scales with). ``span`` b [m], ``area`` S [m^2]."""
    fs = 1.0 / (t[1] - t[0])
    qs_true = truth["qbar"] * area
    ay_true = (truth["CY"] * qs_true + truth["fy_engine"]) / truth["mass"]
    f = {name: prefilter(name, v, fs) for name, v in _readings(rng, t, truth, ay_true).items()}
    qbar = np.asarray(longitudinal["qbar"])
    qsb = qbar * area * span
    mass = longitudinal["mass"]
    ixx, iyy, izz, ixz = _inertias(truth, mass)
    p, q, r = f["p"], longitudinal["q"], f["r"]
    p_dot, r_dot = derivative(p, t), derivative(r, t)
    roll = ixx * p_dot - ixz * (r_dot + p * q) + (izz - iyy) * q * r
    yaw = izz * r_dot - ixz * (p_dot - q * r) + (iyy - ixx) * p * q
    return {"beta": f["beta"], "p": p, "r": r, "phi": f["phi"], "da": f["da"], "dr": f["dr"],
            "CY": mass * f["ay"] / (qbar * area) - truth["fy_engine"] / (qbar * area),
            "Cl": roll / qsb - truth["cl_engine"], "Cn": yaw / qsb - truth["cn_engine"],
            "CY_true": truth["CY"], "Cl_true": truth["Cl"], "Cn_true": truth["Cn"]}


def _inertias(truth: dict, mass: np.ndarray) -> tuple[np.ndarray, ...]:
    """I_xx, I_yy, I_zz, I_xz as the reduction takes them: they scale with the mass it takes, as the pitch inertia
    does."""
    k = mass / truth["mass"]
    return tuple(truth[n] * k for n in ("Ixx", "Iyy", "Izz", "Ixz"))


def pitch_coupling(lateral: dict, truth: dict, longitudinal: dict, area: float, cbar: float) -> np.ndarray:
    """The inertial coupling's share of C_m, ((I_xx - I_zz) p r + I_xz (p^2 - r^2)) / (qbar S cbar), from the
    measured rates (``lateral``: :func:`measure_lateral`'s columns) and the reduction's dynamic pressure and mass."""
    ixx, _, izz, ixz = _inertias(truth, longitudinal["mass"])
    p, r = lateral["p"], lateral["r"]
    return ((ixx - izz) * p * r + ixz * (p ** 2 - r ** 2)) / (np.asarray(longitudinal["qbar"]) * area * cbar)
