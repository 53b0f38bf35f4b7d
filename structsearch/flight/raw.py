"""Raw flight-test channels (docs/interfaces.md 5.2): what the sensors record before any processing.

The simulator's truth histories are measured as the instrumentation would: specific forces at the
accelerometer (not at the cg: the rigid-body lever-arm terms are in), body rates, attitude, true
airspeed, the vane's angle of attack, altitude, elevator and the engine model's thrust, each at its own
rate with noise, buffet and boom vibration, and with sensor errors a flight-path reconstruction has to
find: accelerometer and rate-gyro biases, an alpha-vane bias and scale factor and an airspeed scale
factor. The errors are drawn once per campaign (one instrumentation installation) and recorded in the
campaign manifest (``injected_*`` keys) so that a reconstruction can be checked against them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .aircraft import Aircraft
from ..data.reduction import body_from_lift_drag, specific_force_at_accelerometer
from .measurement import (BOOM_VIBRATION, BUFFET_AZ, ENGINE_MODEL_ERROR, NOISE, RATES, band_noise, sensor,
                          separation_of, vibration)

# Accelerometer position from the cg [m], body axes (x forward, z down): the instrumentation rack.
ACCELEROMETER = (0.5, 0.0, -0.3)
# Standard deviations of the injected sensor errors, drawn once per campaign.
SENSOR_ERROR_SD = {"ax_bias": 0.05, "az_bias": 0.08, "q_bias": 0.002, "alpha_bias": 0.01, "alpha_scale": 0.04,
                   "V_scale": 0.02}


@dataclass(frozen=True)
class SensorErrors:
    """Errors of one instrumentation installation: biases [SI] and scale factors [-] (1 = none)."""

    ax_bias: float
    az_bias: float
    q_bias: float
    alpha_bias: float
    alpha_scale: float
    V_scale: float

    @classmethod
    def draw(cls, rng: np.random.Generator) -> "SensorErrors":
        sd = SENSOR_ERROR_SD
        return cls(rng.normal(0, sd["ax_bias"]), rng.normal(0, sd["az_bias"]), rng.normal(0, sd["q_bias"]),
                   rng.normal(0, sd["alpha_bias"]), 1.0 + rng.normal(0, sd["alpha_scale"]),
                   1.0 + rng.normal(0, sd["V_scale"]))

    def manifest(self) -> dict[str, float]:
        return {f"injected_{k}": float(v) for k, v in self.__dict__.items()}


def specific_force_at(ax_cg, az_cg, q, q_dot, position=ACCELEROMETER):
    """Specific force at the instrumentation's accelerometer (:data:`ACCELEROMETER`)."""
    return specific_force_at_accelerometer(ax_cg, az_cg, q, q_dot, position)


def raw_channels(rng: np.random.Generator, t: np.ndarray, truth: dict, errors: SensorErrors,
                 aircraft: Aircraft) -> dict:
    """One maneuver's raw channels from its truth histories (the keys of :func:`.measurement.measure`'s
    ``truth``; ``thrust`` is the engines' true thrust)."""
    fs = 1.0 / (t[1] - t[0])
    n = len(t)
    alpha, V, q = truth["alpha"], truth["V"], truth["q"]
    qs = truth["qbar"] * aircraft.S
    cx, cz = body_from_lift_drag(truth["CL"], truth["CD"], alpha)
    ax_acc, az_acc = specific_force_at((qs * cx + truth["thrust"]) / truth["mass"], qs * cz / truth["mass"], q,
                                       truth["q_dot"])
    separation = separation_of(truth["states"], n)
    buffet = vibration(rng, n, fs) * separation
    gyro_buffet = vibration(rng, n, fs) * separation
    boom = BOOM_VIBRATION * band_noise(rng, n, fs, 8.0, 12.0)
    zero = np.zeros(n)
    out = {
        "t": t - t[0],
        "ax": sensor(rng, t, ax_acc + 0.25 * BUFFET_AZ * buffet, RATES["ahrs"], NOISE["ax"], errors.ax_bias),
        "ay": sensor(rng, t, zero, RATES["ahrs"], NOISE["ax"]),
        "az": sensor(rng, t, az_acc + BUFFET_AZ * buffet, RATES["ahrs"], NOISE["az"], errors.az_bias),
        "p": sensor(rng, t, zero, RATES["ahrs"], aircraft.gyro_noise),
        "q": sensor(rng, t, q + aircraft.gyro_buffet * gyro_buffet, RATES["ahrs"], aircraft.gyro_noise,
                     errors.q_bias),
        "r": sensor(rng, t, zero, RATES["ahrs"], aircraft.gyro_noise),
        "phi": sensor(rng, t, zero, RATES["ahrs"], NOISE["theta"]),
        "theta": sensor(rng, t, truth["theta"], RATES["ahrs"], NOISE["theta"]),
        "V": sensor(rng, t, errors.V_scale * V, RATES["tas"], NOISE["V"]),
        "alpha": sensor(rng, t, errors.alpha_scale * (alpha + boom), RATES["boom"], NOISE["alpha"],
                         errors.alpha_bias),
        "h": sensor(rng, t, truth["h"], RATES["gps"], NOISE["h"]),
        "de": sensor(rng, t, truth["de"], RATES["synchro"], NOISE["de"]),
        "thrust": truth["thrust"] * (1 + rng.normal(0, ENGINE_MODEL_ERROR)),
        "mass": truth["mass"],
        "CL_true": truth["CL"], "CD_true": truth["CD"], "Cm_true": truth["Cm"], "alpha_true": alpha,
        "V_true": V, "q_true": q,
    }
    if aircraft.records_cg:
        out["x_cg"] = truth["x_cg"]
    return out
