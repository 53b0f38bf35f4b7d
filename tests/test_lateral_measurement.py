"""The lateral reduction against the rigid body's own law: moments made by Euler's equation in vector form,
M = J w' + w x (J w) with the full inertia matrix (the product of inertia where the standard convention puts it,
large here so that its sign shows), read back through the sensors and the reduction's scalar equations."""
from __future__ import annotations

import numpy as np

from structsearch.flight.lateral_measurement import measure_lateral, pitch_coupling

IXX, IYY, IZZ, IXZ = 2000.0, 1800.0, 3400.0, 400.0      # kg m^2; I_xz = integral of x z dm
S, B, CBAR, MASS, QBAR = 16.0, 11.0, 1.5, 1100.0, 1500.0


def _rigid_body(t: np.ndarray):
    w = np.stack([0.4 * np.sin(1.3 * t), 0.1 * np.sin(0.7 * t + 0.5), 0.3 * np.cos(0.9 * t)], axis=1)
    w_dot = np.stack([0.52 * np.cos(1.3 * t), 0.07 * np.cos(0.7 * t + 0.5), -0.27 * np.sin(0.9 * t)], axis=1)
    inertia = np.array([[IXX, 0.0, -IXZ], [0.0, IYY, 0.0], [-IXZ, 0.0, IZZ]])
    moments = w_dot @ inertia.T + np.cross(w, w @ inertia.T)
    return w, w_dot, moments


def _truth(t, w, moments):
    n = len(t)
    ones = np.ones(n)
    return {"beta": 0.02 * np.sin(t), "p": w[:, 0], "r": w[:, 2], "phi": 0.1 * np.sin(0.2 * t),
            "da": 0.01 * np.sin(2 * t), "dr": 0.01 * np.cos(2 * t), "qbar": QBAR * ones, "mass": MASS * ones,
            "Ixx": IXX * ones, "Iyy": IYY * ones, "Izz": IZZ * ones, "Ixz": IXZ * ones,
            "CY": 0.05 * np.sin(t), "Cl": moments[:, 0] / (QBAR * S * B), "Cn": moments[:, 2] / (QBAR * S * B),
            "fy_engine": np.zeros(n), "cl_engine": np.zeros(n), "cn_engine": np.zeros(n), "states": {}}


def test_the_rolling_and_yawing_moments_are_those_of_the_rigid_body():
    t = np.arange(0.0, 30.0, 0.01)
    w, _, moments = _rigid_body(t)
    truth = _truth(t, w, moments)
    longitudinal = {"q": w[:, 1], "qbar": QBAR * np.ones(len(t)), "mass": MASS * np.ones(len(t))}
    out = measure_lateral(np.random.default_rng(3), t, truth, longitudinal, B, S)
    inner = slice(200, -200)        # the pre-filter's and the derivative's ends
    for name in ("Cl", "Cn", "CY"):
        error = (out[name] - truth[name])[inner]
        # the gyros' noise through the 4-5 Hz pre-filter and the derivative: far below the 2 * I_xz (r' + p q)
        # a wrong sign of the product of inertia would leave (about a third of C_l's span here)
        assert np.sqrt(np.mean(error ** 2)) < 0.02 * np.ptp(truth[name][inner]), name


def test_the_pitch_equation_s_coupling_is_the_rigid_body_s():
    t = np.arange(0.0, 30.0, 0.01)
    w, w_dot, moments = _rigid_body(t)
    coupling = pitch_coupling({"p": w[:, 0], "r": w[:, 2]}, _truth(t, w, moments),
                              {"qbar": QBAR * np.ones(len(t)), "mass": MASS * np.ones(len(t))}, S, CBAR)
    expected = (moments[:, 1] - IYY * w_dot[:, 1]) / (QBAR * S * CBAR)
    np.testing.assert_allclose(coupling, expected, rtol=1e-10, atol=1e-12)
