"""Longitudinal kinematics with sensor errors: the state-space model of the flight-path reconstruction.

States: body velocities u, w [m/s], pitch attitude theta [rad], altitude h [m] (kinematic, re-initialised per
maneuver) and the sensor errors (constant over the campaign): accelerometer biases b_ax, b_az [m/s^2], the
rate-gyro bias b_q [rad/s], the alpha vane's bias b_alpha [rad] and scale factor k_alpha [-], the airspeed's
scale factor k_V [-]. Inputs: specific forces at the cg and the body rates as measured (bias included), and the
roll attitude. No wind: air-relative and inertial velocities are the same (quasi-steady air over a maneuver).

    u' = ax - b_ax - g sin(theta) - (q - b_q) w
    w' = az - b_az + g cos(theta) cos(phi) + (q - b_q) u
    theta' = (q - b_q) cos(phi) - r sin(phi)
    h' = u sin(theta) - w cos(theta) cos(phi)

Measurements: V = k_V sqrt(u^2 + w^2), alpha = k_alpha atan(w/u) + b_alpha, theta, h.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.reduction import G

STATES = ("u", "w", "theta", "h", "ax_bias", "az_bias", "q_bias", "alpha_bias", "alpha_scale", "V_scale")
SENSOR_ERRORS = STATES[4:]
MEASUREMENTS = ("V", "alpha", "theta", "h")
INPUTS = ("ax", "az", "q", "r", "phi")
# Units of the sensor errors, for the record.
UNITS = {"ax_bias": "m/s^2", "az_bias": "m/s^2", "q_bias": "rad/s", "alpha_bias": "rad", "alpha_scale": "-",
         "V_scale": "-"}
NOMINAL = np.array([0.0, 0.0, 0.0, 0.0, 1.0, 1.0])
# Prior standard deviations of the sensor errors: wide against any installation (the data decide), narrow
# enough to keep the first linearisations sensible.
PRIOR_SD = np.array([0.5, 0.5, 0.02, 0.05, 0.2, 0.1])
# Standard deviations of the kinematic states at a maneuver start, about their values from the measurements.
START_SD = np.array([2.0, 2.0, 0.01, 5.0])


@dataclass(frozen=True)
class LongitudinalKinematics:
    """The model of the module docstring with a fixed step ``dt`` [s] (Heun's method over trapezoidal inputs)."""

    dt: float
    n_states = len(STATES)
    kinematic = slice(0, 4)

    def _rates(self, x, u_in):
        u, w, theta, h, bx, bz, bq = x[:7]
        ax, az, q, r, phi = u_in
        qc = q - bq
        cphi = np.cos(phi)
        st, ct = np.sin(theta), np.cos(theta)
        return np.array([ax - bx - G * st - qc * w, az - bz + G * ct * cphi + qc * u, qc * cphi - r * np.sin(phi),
                         u * st - w * ct * cphi])

    def _jacobian(self, x, u_in):
        u, w, theta = x[:3]
        bq = x[6]
        q, phi = u_in[2], u_in[4]
        qc = q - bq
        cphi = np.cos(phi)
        st, ct = np.sin(theta), np.cos(theta)
        a = np.zeros((4, self.n_states))
        a[0, 1], a[0, 2], a[0, 4], a[0, 6] = -qc, -G * ct, -1.0, w
        a[1, 0], a[1, 2], a[1, 5], a[1, 6] = qc, -G * st * cphi, -1.0, -u
        a[2, 6] = -cphi
        a[3, 0], a[3, 1], a[3, 2] = st, -ct * cphi, u * ct + w * st * cphi
        return a

    def transition(self, x, u0, u1):
        k1 = self._rates(x, u0)
        trial = x.copy()
        trial[:4] += self.dt * k1
        out = x.copy()
        out[:4] += 0.5 * self.dt * (k1 + self._rates(trial, u1))
        f = np.eye(self.n_states)
        a = self._jacobian(x, u0)
        f[:4] += self.dt * a + 0.5 * self.dt ** 2 * a[:, :4] @ a
        return out, f

    def measure(self, x):
        u, w = x[0], x[1]
        b_alpha, k_alpha, k_v = x[7], x[8], x[9]
        v2 = u * u + w * w
        v = np.sqrt(v2)
        alpha = np.arctan2(w, u)
        h = np.zeros((4, self.n_states))
        h[0, 0], h[0, 1], h[0, 9] = k_v * u / v, k_v * w / v, v
        h[1, 0], h[1, 1], h[1, 7], h[1, 8] = -k_alpha * w / v2, k_alpha * u / v2, 1.0, alpha
        h[2, 2] = 1.0
        h[3, 3] = 1.0
        return np.array([k_v * v, k_alpha * alpha + b_alpha, x[2], x[3]]), h

    def initial(self, x, y):
        """u, w from the measured airspeed and vane corrected by the current sensor-error estimates."""
        v = y[0] / x[9]
        alpha = (y[1] - x[7]) / x[8]
        return np.array([v * np.cos(alpha), v * np.sin(alpha), y[2], y[3]])
