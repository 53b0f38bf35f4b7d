"""The measurement chain: sensors at their own rates, buffet and boom vibration, pre-filter, and
reconstruction of the aerodynamic coefficients from specific forces and rates (thesis Eqs. 3-4).

What comes out is what a flight-test engineer has after flight-path reconstruction:
the interface columns plus theta, h, CX, CZ, and the truth coefficients for reference.
"""
from __future__ import annotations

import numpy as np

from .aircraft import CITATION, Aircraft
from ..data.reduction import body_force_coefficients, body_from_lift_drag, lift_drag, pitch_moment_coefficient
from ..data.prefilter import derivative, prefilter
from ..engine.separation import first_order_lag

# Sensor rates [Hz] (thesis Table 2) and noise standard deviations (SI units) as left after
# flight-path reconstruction (alpha: vane noise would turn into alpha_dot noise of ~0.02 rad/s); the
# pitch-rate gyro's are the aircraft's (:class:`.Aircraft`).
RATES = {"ahrs": 52.0, "boom": 100.0, "tas": 16.0, "qbar": 8.0, "synchro": 100.0, "gps": 1.0}
NOISE = {"alpha": 0.0002, "theta": 0.001, "ax": 0.04, "az": 0.06, "V": 0.25,
         "qbar": 12.0, "de": 0.0005, "h": 2.0}
# Residual sensor biases after flight-path reconstruction (the Kalman filter estimates the raw biases)
BIAS = {"alpha": 0.0005, "q": 0.0002, "ax": 0.005, "az": 0.01}
BUFFET_HZ = (6.0, 10.0, 12.0, 15.0)
BUFFET_WEIGHTS = (1.0, 0.6, 0.5, 0.35)
BUFFET_HALF_WIDTH_HZ = 0.8
BUFFET_AZ = 0.5          # m/s^2 per unit of separation (residual MSEs near thesis Table 7)
BOOM_VIBRATION = 0.0015  # rad, 8-12 Hz
ENGINE_MODEL_ERROR = 0.03  # relative, per maneuver


def _resample(t_out, t_in, values):
    return np.interp(t_out, t_in, values)


def sensor(rng, t, truth, rate, noise, bias=0.0, also=None):
    """Sample ``truth`` at ``rate`` with white noise and a constant bias, then back onto ``t``.

    ``also``: a second signal read with the same noise and bias; then both readings are returned."""
    t_s = np.arange(t[0], t[-1] + 1e-9, 1.0 / rate)
    white = rng.normal(0.0, noise, len(t_s))
    sampled = _resample(t_s, t, truth) + white + bias
    if also is None:
        return _resample(t, t_s, sampled)
    return _resample(t, t_s, sampled), _resample(t, t_s, _resample(t_s, t, also) + white + bias)


def vane_lag(t: np.ndarray, signal: np.ndarray, tau: float) -> np.ndarray:
    """``signal`` through a first-order lag of time constant ``tau`` [s], starting in equilibrium
    (exact for a signal linear between samples)."""
    bounds = np.array([0, len(t)])
    return first_order_lag(t, signal, np.zeros((len(t), 1)), tau, bounds)[0]


def band_noise(rng, n, fs, low, high):
    """Unit-variance Gaussian noise band-passed to [low, high] Hz (2nd order, forward and backward)."""
    from scipy.signal import butter, sosfiltfilt
    sos = butter(2, [low, high], btype="band", fs=fs, output="sos")
    x = sosfiltfilt(sos, rng.standard_normal(n + 400))[200:-200]
    return x / (x.std() or 1.0)


def separation_of(states: dict, n: int) -> np.ndarray:
    """Flow separation summed over the states (1 - X each), 0 to 2: what buffet and slow errors scale with."""
    return np.clip(sum(1 - x for x in states.values()) + np.zeros(n), 0, 2)


def vibration(rng: np.random.Generator, n: int, fs: float) -> np.ndarray:
    """Buffet at unit separation: narrow-band random vibration around each buffet peak (not pure tones: real
    buffet decorrelates)."""
    return sum(w * band_noise(rng, n, fs, f - BUFFET_HALF_WIDTH_HZ, f + BUFFET_HALF_WIDTH_HZ)
               for f, w in zip(BUFFET_HZ, BUFFET_WEIGHTS))


def measure(rng: np.random.Generator, t: np.ndarray, truth: dict, slow_error: np.ndarray | None = None,
            slow_error_stall_gain: float = 1.0, aircraft: Aircraft = CITATION, vane_lag_s: float = 0.0,
            record_alpha: bool = False) -> dict:
    """One maneuver's measured, pre-filtered, reconstructed columns from its truth histories.

    ``truth`` holds 1-D arrays: V, alpha, q, theta, h, de, thrust, qbar, mass, x_cg,
    CL, CD, Cm, q_dot and ``states``: the separation states by symbol (X_ss, X_w or X).
    ``slow_error`` (n, 3) holds slow C_L, C_D, C_m reconstruction errors at attached flow; they grow by
    ``slow_error_stall_gain`` per unit of separation and enter through the body-axis forces (C_L, C_D)
    and the pitch moment. ``aircraft`` gives S, cbar and the pitch inertia.

    ``vane_lag_s`` > 0 passes the alpha vane's reading through a first-order lag of that time constant
    (the ``vane_lag`` anomaly) and adds the column ``alpha_unlagged_true``: the alpha this chain gives without
    the lag (same noise, bias and pre-filter). ``record_alpha`` adds the truth alpha as ``alpha_true``.
    Neither draws random numbers: with the same ``rng`` every other column is unchanged.
    """
    fs = 1.0 / (t[1] - t[0])
    n = len(t)
    alpha, V = truth["alpha"], truth["V"]
    # body-axis specific forces measured by the AHRS (aerodynamic and thrust forces over mass)
    qs = truth["qbar"] * aircraft.S
    cx, cz = body_from_lift_drag(truth["CL"], truth["CD"], alpha)
    ax_true = (qs * cx + truth["thrust"]) / truth["mass"]
    az_true = qs * cz / truth["mass"]
    # buffet while the flow is separated, boom vibration always
    separation = separation_of(truth["states"], n)
    buffet = vibration(rng, n, fs) * separation
    # the rate gyro sees the same frequencies through other mode shapes: its own realisation
    gyro_buffet = vibration(rng, n, fs) * separation
    boom = BOOM_VIBRATION * band_noise(rng, n, fs, 8.0, 12.0)

    vane = alpha + boom
    unlagged = None
    if vane_lag_s > 0:
        vane, unlagged = vane_lag(t, vane, vane_lag_s), vane
    alpha_reading = sensor(rng, t, vane, RATES["boom"], NOISE["alpha"], rng.normal(0, BIAS["alpha"]), unlagged)
    if unlagged is not None:
        alpha_reading, unlagged = alpha_reading
    raw = {
        "alpha": alpha_reading,
        "q": sensor(rng, t, truth["q"] + aircraft.gyro_buffet * gyro_buffet, RATES["ahrs"], aircraft.gyro_noise,
                     rng.normal(0, BIAS["q"])),
        "theta": sensor(rng, t, truth["theta"], RATES["ahrs"], NOISE["theta"]),
        "ax": sensor(rng, t, ax_true + 0.25 * BUFFET_AZ * buffet, RATES["ahrs"], NOISE["ax"],
                      rng.normal(0, BIAS["ax"])),
        "az": sensor(rng, t, az_true + BUFFET_AZ * buffet, RATES["ahrs"], NOISE["az"], rng.normal(0, BIAS["az"])),
        "V": sensor(rng, t, V, RATES["tas"], NOISE["V"]),
        "qbar": sensor(rng, t, truth["qbar"], RATES["qbar"], NOISE["qbar"]),
        "de": sensor(rng, t, truth["de"], RATES["synchro"], NOISE["de"]),
        "h": sensor(rng, t, truth["h"], RATES["gps"], NOISE["h"]),
    }
    f = {name: prefilter(name, values, fs) for name, values in raw.items()}
    q_dot = derivative(f["q"], t)
    alpha_dot = derivative(f["alpha"], t)
    thrust_model = truth["thrust"] * (1 + rng.normal(0, ENGINE_MODEL_ERROR))
    mass = truth["mass"]
    qs_m = f["qbar"] * aircraft.S
    cx_m, cz_m = body_force_coefficients(f["ax"], f["az"], mass, thrust_model, qs_m)
    a = f["alpha"]
    cm_error = np.zeros(n)
    if slow_error is not None:
        d_cl, d_cd, cm_error = (slow_error * (1.0 + slow_error_stall_gain * separation)[:, None]).T
        cx_m = cx_m - d_cd * np.cos(a) + d_cl * np.sin(a)
        cz_m = cz_m - d_cl * np.cos(a) - d_cd * np.sin(a)
    cl_m, cd_m = lift_drag(cx_m, cz_m, a)
    columns = {
        "t": t - t[0], "alpha": a, "q": f["q"], "V": f["V"], "de": f["de"], "CL": cl_m, "CD": cd_m,
        "Cm": pitch_moment_coefficient(q_dot, aircraft.inertia(mass), qs_m, aircraft.cbar) + cm_error,
        "alpha_dot": alpha_dot, "CT": thrust_model / qs_m, "x_cg": truth["x_cg"],
        "theta": f["theta"], "h": f["h"], "CX": cx_m, "CZ": cz_m,
        "mass": mass, "CL_true": truth["CL"], "CD_true": truth["CD"], "Cm_true": truth["Cm"],
        **{f"{symbol}_true": x for symbol, x in truth["states"].items()},
    }
    if record_alpha:
        columns["alpha_true"] = alpha
    if unlagged is not None:
        columns["alpha_unlagged_true"] = prefilter("alpha", unlagged, fs)
    if not aircraft.records_cg:  # flown at a fixed cg nobody recorded
        del columns["x_cg"]
    return columns
