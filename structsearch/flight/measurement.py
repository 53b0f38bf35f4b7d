"""The measurement chain: sensors at their own rates, buffet and boom vibration, pre-filter, and
reconstruction of the aerodynamic coefficients from specific forces and rates (thesis Eqs. 3-4).

What comes out is what a flight-test engineer has after flight-path reconstruction:
the interface columns plus theta, h, CX, CZ, and the truth coefficients for reference.
"""
from __future__ import annotations

from dataclasses import dataclass

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
# Errors shared by every maneuver of one flight (``build_campaign(flights=N)``; standard deviations, drawn once per
# flight): what the data reduction takes as known for the whole flight and gets wrong by that flight's amount.
# - mass 0.6 % (about 35 kg of 5.9 t): the ramp weight from the last weighing and the loading sheet, plus the fuel on
#   board at take-off read from the gauges (about 2 % of a 1.5 t load); fuel used after take-off comes from the
#   flow totalisers, whose error is relative and folds into the same constant. It scales the reconstructed C_L and
#   C_D (force over dynamic pressure: m a / (qbar S)) and the pitch inertia, hence C_m's dynamic part.
# - cg 0.25 in (6 mm, 0.3 % of the chord): the loading sheet's crew, ballast and fuel positions; it shifts the
#   recorded x_cg column.
# - engine model 2 % of the thrust: the thrust deck against that day's engines (bleed, deterioration, temperature),
#   on top of the 3 % per maneuver above; it enters C_D through the thrust subtracted from the axial force.
# - vane calibration: 0.001 rad (0.06 deg) bias and 1 % scale factor left after that flight's flight-path
#   reconstruction (its upwash and alignment calibration; the per-maneuver residual bias is BIAS["alpha"]).
FLIGHT_ERROR_SD = {"mass": 0.006, "x_cg": 0.25 * 0.0254, "thrust": 0.02, "alpha_bias": 0.001, "alpha_scale": 0.01}


@dataclass(frozen=True)
class FlightErrors:
    """One flight's shared errors (:data:`FLIGHT_ERROR_SD`): relative mass and thrust-model errors, a cg error [m]
    and the alpha vane's bias [rad] and scale-factor error (0: none)."""

    mass: float = 0.0
    x_cg: float = 0.0
    thrust: float = 0.0
    alpha_bias: float = 0.0
    alpha_scale: float = 0.0

    @classmethod
    def draw(cls, rng: np.random.Generator) -> "FlightErrors":
        sd = FLIGHT_ERROR_SD
        return cls(*(float(rng.normal(0.0, sd[k])) for k in ("mass", "x_cg", "thrust", "alpha_bias", "alpha_scale")))


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


def _alpha_reading(rng: np.random.Generator, t: np.ndarray, vane: np.ndarray, flight: FlightErrors | None,
                   vane_lag_s: float) -> tuple[np.ndarray, np.ndarray | None]:
    """The alpha vane's reading of ``vane`` (alpha and boom vibration) with the flight's calibration error and the
    vane lag, and the reading without that lag (None without a lag): same noise and bias."""
    if flight is not None:
        vane = (1.0 + flight.alpha_scale) * vane + flight.alpha_bias
    unlagged = None
    if vane_lag_s > 0:
        vane, unlagged = vane_lag(t, vane, vane_lag_s), vane
    alpha_reading = sensor(rng, t, vane, RATES["boom"], NOISE["alpha"], rng.normal(0, BIAS["alpha"]), unlagged)
    if unlagged is not None:
        alpha_reading, unlagged = alpha_reading
    return alpha_reading, unlagged


def _other_readings(rng: np.random.Generator, t: np.ndarray, truth: dict, aircraft: Aircraft, ax_true: np.ndarray,
                    az_true: np.ndarray, buffet: np.ndarray, gyro_buffet: np.ndarray) -> dict:
    """The readings of every sensor but the alpha vane, drawn from ``rng`` in this order."""
    return {
        "q": sensor(rng, t, truth["q"] + aircraft.gyro_buffet * gyro_buffet, RATES["ahrs"], aircraft.gyro_noise,
                     rng.normal(0, BIAS["q"])),
        "theta": sensor(rng, t, truth["theta"], RATES["ahrs"], NOISE["theta"]),
        "ax": sensor(rng, t, ax_true + 0.25 * BUFFET_AZ * buffet, RATES["ahrs"], NOISE["ax"],
                      rng.normal(0, BIAS["ax"])),
        "az": sensor(rng, t, az_true + BUFFET_AZ * buffet, RATES["ahrs"], NOISE["az"], rng.normal(0, BIAS["az"])),
        "V": sensor(rng, t, truth["V"], RATES["tas"], NOISE["V"]),
        "qbar": sensor(rng, t, truth["qbar"], RATES["qbar"], NOISE["qbar"]),
        "de": sensor(rng, t, truth["de"], RATES["synchro"], NOISE["de"]),
        "h": sensor(rng, t, truth["h"], RATES["gps"], NOISE["h"]),
    }


def measure(rng: np.random.Generator, t: np.ndarray, truth: dict, slow_error: np.ndarray | None = None,
            slow_error_stall_gain: float = 1.0, aircraft: Aircraft = CITATION, vane_lag_s: float = 0.0,
            record_alpha: bool = False, flight: FlightErrors | None = None, record_qbar: bool = False) -> dict:
    """One maneuver's measured, pre-filtered, reconstructed columns from its truth histories.

    ``truth`` holds 1-D arrays: V, alpha, q, theta, h, de, thrust, qbar, mass, x_cg,
    CL, CD, Cm, q_dot and ``states``: the separation states by symbol (X_ss, X_w or X).
    ``slow_error`` (n, 3) holds slow C_L, C_D, C_m reconstruction errors at attached flow; they grow by
    ``slow_error_stall_gain`` per unit of separation and enter through the body-axis forces (C_L, C_D)
    and the pitch moment. ``aircraft`` gives S, cbar and the pitch inertia.

    ``vane_lag_s`` > 0 passes the alpha vane's reading through a first-order lag of that time constant
    (the ``vane_lag`` anomaly) and adds the column ``alpha_unlagged_true``: the alpha this chain gives without
    the lag (same noise, bias and pre-filter). ``record_alpha`` adds the truth alpha as ``alpha_true``,
    ``record_qbar`` the filtered dynamic pressure reading the reduction divides by as ``qbar`` [Pa].
    Neither draws random numbers: with the same ``rng`` every other column is unchanged.

    ``flight`` (:class:`FlightErrors`, drawn per flight) adds the errors the maneuver shares with the others of
    its flight: the vane reads (1 + alpha_scale) (alpha + boom) + alpha_bias, the thrust model and the mass the
    reduction uses are off by their relative errors, the recorded x_cg by its error. It draws no random
    numbers either, and adds the truth columns ``alpha_true``, ``mass_true``, ``x_cg_true`` and ``CT_true``.
    """
    fs = 1.0 / (t[1] - t[0])
    n = len(t)
    alpha = truth["alpha"]
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

    alpha_reading, unlagged = _alpha_reading(rng, t, alpha + boom, flight, vane_lag_s)
    raw = {"alpha": alpha_reading,
           **_other_readings(rng, t, truth, aircraft, ax_true, az_true, buffet, gyro_buffet)}
    f = {name: prefilter(name, values, fs) for name, values in raw.items()}
    reduced = _reduction(rng, f, truth, aircraft, flight, slow_error, slow_error_stall_gain, separation)
    columns = _columns(t, f, truth, reduced, aircraft)
    if record_alpha or flight is not None:
        columns["alpha_true"] = alpha
    if record_qbar:
        columns["qbar"] = f["qbar"]
    if flight is not None:
        columns.update(x_cg=truth["x_cg"] + flight.x_cg, x_cg_true=truth["x_cg"], mass_true=truth["mass"],
                       CT_true=truth["thrust"] / reduced["qs"])
    if unlagged is not None:
        columns["alpha_unlagged_true"] = prefilter("alpha", unlagged, fs)
    if not aircraft.records_cg:  # flown at a fixed cg nobody recorded
        del columns["x_cg"]
        columns.pop("x_cg_true", None)
    return columns


def _columns(t: np.ndarray, f: dict, truth: dict, reduced: dict, aircraft: Aircraft) -> dict:
    """A maneuver's columns: the pre-filtered readings, the reduced coefficients (C_m from the derivative of the
    filtered pitch rate), alpha's derivative, and the truth beside them."""
    return {
        "t": t - t[0], "alpha": f["alpha"], "q": f["q"], "V": f["V"], "de": f["de"], "CL": reduced["CL"],
        "CD": reduced["CD"],
        "Cm": pitch_moment_coefficient(derivative(f["q"], t), aircraft.inertia(reduced["mass"]), reduced["qs"],
                                       aircraft.cbar) + reduced["cm_error"],
        "alpha_dot": derivative(f["alpha"], t), "CT": reduced["thrust"] / reduced["qs"], "x_cg": truth["x_cg"],
        "theta": f["theta"], "h": f["h"], "CX": reduced["CX"], "CZ": reduced["CZ"],
        "mass": reduced["mass"], "CL_true": truth["CL"], "CD_true": truth["CD"], "Cm_true": truth["Cm"],
        **{f"{symbol}_true": x for symbol, x in truth["states"].items()},
    }


def _reduction(rng: np.random.Generator, f: dict, truth: dict, aircraft: Aircraft, flight: FlightErrors | None,
               slow_error: np.ndarray | None, slow_error_stall_gain: float, separation: np.ndarray) -> dict:
    """The data reduction of the pre-filtered readings ``f``: the body-axis force coefficients from the measured
    specific forces, with the thrust model's error (drawn here) and the flight's errors, the slow reconstruction
    errors, and C_L, C_D from them at the measured alpha."""
    thrust_model = truth["thrust"] * (1 + rng.normal(0, ENGINE_MODEL_ERROR))
    mass = truth["mass"]
    if flight is not None:
        thrust_model = thrust_model * (1.0 + flight.thrust)
        mass = mass * (1.0 + flight.mass)
    qs_m = f["qbar"] * aircraft.S
    cx_m, cz_m = body_force_coefficients(f["ax"], f["az"], mass, thrust_model, qs_m)
    a = f["alpha"]
    cm_error = np.zeros(len(a))
    if slow_error is not None:
        d_cl, d_cd, cm_error = (slow_error * (1.0 + slow_error_stall_gain * separation)[:, None]).T
        cx_m = cx_m - d_cd * np.cos(a) + d_cl * np.sin(a)
        cz_m = cz_m - d_cl * np.cos(a) - d_cd * np.sin(a)
    cl_m, cd_m = lift_drag(cx_m, cz_m, a)
    return {"CL": cl_m, "CD": cd_m, "CX": cx_m, "CZ": cz_m, "thrust": thrust_model, "mass": mass, "qs": qs_m,
            "cm_error": cm_error}
