"""Units read from the data, one maneuver file at a time (docs/guide/data.md, "Units the reader checks").

A number in the wrong unit passes every range check and changes a fit without a word: a pitch rate in deg/s in one
file of twenty moves C_L's pitch-rate derivative through zero. The reader compares each file's channels with the
redundant ones it carries:

* the pitch rate with the derivative of the pitch attitude (else of the angle of attack): the regression slope of
  q on d(theta)/dt, both smoothed below 2 Hz, is 0.95-1.00 in rad/s on the simulated campaigns (q = d(theta)/dt in
  wings-level flight) and 57.3 in deg/s; q on d(alpha)/dt (q = d(alpha)/dt + d(gamma)/dt) is 0.62-1.23 in the
  stall maneuvers and 2.3-3.3 in pullups, far from 57 (pushovers and phugoids, whose q and d(alpha)/dt do not move
  together, are not judged). A slope near 1000 is time in milliseconds instead;
* the time step with the other files' and the declared ``sample_rate``, and one above a second;
* the airspeed with sqrt(2 qbar / rho) and with Mach times the speed of sound (``a``, else from ``T_air``, else
  the ISA at ``h``), and with the aircraft's declared ``V_range``: a factor of a common unit (knots, km/h, ft/s,
  mph) is named.

Each finding is one :class:`~structsearch.errors.DataError` naming the file, the column and the likely unit.
"""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from .errors import DataError

# q against the derivative of the attitude or the angle of attack: deg/s gives 57.3 times the rad/s slope, time
# in ms 1000 times, both 57,300 times. The rad/s slopes lie within 0.6-3.3 (module docstring), so each window
# starts a factor of 3 above the largest and ends a factor of 3 beyond the unit's own factor.
RATE_UNITS = (("q", "degrees per second", 57.29578, (12.0, 200.0)),
              ("t", "milliseconds", 1000.0, (300.0, 4000.0)),
              ("t", "milliseconds and q in degrees per second", 57295.78, (15000.0, 250000.0)))
SMOOTH_HZ = 2.0
# a regression slope means something only when the two signals move together (q on d(alpha)/dt in a hand-flown
# quasi-steady stall: 0.27-0.62 on the simulated campaigns; a phugoid 0.1, which is left unjudged)
MIN_CORRELATION = 0.2
# the longest plausible sample step of a stall maneuver [s]: separation lags are tenths of a second
MAX_STEP_S = 1.0
# time steps of two files or of a file and the declared rate that differ this much (factor) are a unit
STEP_FACTOR = 300.0
SAMPLE_RATE_TOLERANCE = 1.5
# airspeed units as factors of m/s
SPEED_UNITS = (("knots", 1.0 / 0.514444), ("km/h", 3.6), ("ft/s", 1.0 / 0.3048), ("mph", 1.0 / 0.44704))
SPEED_TOLERANCE = 0.06   # relative: the redundant channels agree within a few per cent (ISA temperature at h)
GAMMA_AIR, R_AIR = 1.4, 287.053


def _smoothed(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """x low-passed below SMOOTH_HZ (2nd-order Butterworth, forward-backward) where the sampling allows."""
    from scipy.signal import butter, sosfiltfilt
    dt = float(np.median(np.diff(t)))
    nyquist = 0.5 / dt
    if SMOOTH_HZ >= 0.9 * nyquist or len(x) < 16:
        return np.asarray(x, float)
    return sosfiltfilt(butter(2, SMOOTH_HZ / nyquist, output="sos"), np.asarray(x, float))


def rate_slope(columns: Mapping[str, np.ndarray]) -> tuple[str, float] | None:
    """(reference, slope): the regression slope of the smoothed q on the derivative of the smoothed theta (else
    alpha), centred; None without q, without either angle, or when they do not move together."""
    reference = next((c for c in ("theta", "alpha") if c in columns), None)
    t = columns.get("t")
    if "q" not in columns or reference is None or t is None or len(t) < 3:
        return None
    rate = np.gradient(_smoothed(columns[reference], t), t)
    q = _smoothed(columns["q"], t)
    rate, q = rate - rate.mean(), q - q.mean()
    spread = float(rate @ rate)
    if not (np.isfinite(spread) and spread > 0 and np.any(q)):
        return None
    if float(q @ rate) / math.sqrt(spread * float(q @ q)) < MIN_CORRELATION:
        return None
    return reference, float(q @ rate) / spread


def check_rate_units(columns: Mapping[str, np.ndarray], source: str) -> None:
    """q in deg/s or t in ms, read from q's ratio to the derivative of theta (else alpha)."""
    found = rate_slope(columns)
    if found is None:
        return
    reference, slope = found
    for column, unit, factor, (low, high) in RATE_UNITS:
        if low < slope < high:
            what = "rates must be in rad/s" if column == "q" else "time must be in seconds and rates in rad/s"
            raise DataError(f"{column} looks like {unit}: the ratio of q to d({reference})/dt is {slope:.1f} "
                            f"(about 1 in s and rad/s, {factor:.4g} in {unit}); {what}", source=source, column=column)


def median_step(t: np.ndarray) -> float:
    return float(np.median(np.diff(t))) if len(t) > 1 else float("nan")


def check_step(t: np.ndarray, source: str, sample_rate: float | None) -> None:
    """One file's time step: against the declared ``sample_rate`` [Hz], and not above MAX_STEP_S."""
    step = median_step(t)
    if sample_rate is not None:
        declared = 1.0 / sample_rate
        ratio = step / declared
        if ratio > STEP_FACTOR:
            raise DataError(f"t looks like milliseconds: the median time step is {step:.4g} against "
                            f"{declared:.4g} s at the declared sample_rate = {sample_rate:g} Hz; time must be in "
                            "seconds", source=source, column="t")
        if not 1 / SAMPLE_RATE_TOLERANCE <= ratio <= SAMPLE_RATE_TOLERANCE:
            raise DataError(f"the median time step is {step:.4g} s, {1 / step:.4g} samples per second, where "
                            f"campaign.toml declares sample_rate = {sample_rate:g} Hz", source=source, column="t")
    if step > MAX_STEP_S:
        raise DataError(f"t looks like milliseconds: the median time step is {step:.4g}, too slow for separation "
                        "dynamics if it were seconds; time must be in seconds", source=source, column="t")


def check_steps_across(steps: Sequence[float], sources: Sequence[str]) -> None:
    """A file whose time step is STEP_FACTOR times the median of all files' (time in ms among files in s)."""
    finite = [s for s in steps if np.isfinite(s)]
    if len(finite) < 2:
        return
    typical = float(np.median(finite))
    for step, source in zip(steps, sources):
        if np.isfinite(step) and step > STEP_FACTOR * typical:
            raise DataError(f"t looks like milliseconds: the median time step is {step:.4g} against {typical:.4g} s "
                            "in the campaign's other files; time must be in seconds", source=source, column="t")


def _isa(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ISA troposphere (below 11 km): temperature [K] and density [kg/m^3] at altitude h [m]."""
    temperature = 288.15 - 0.0065 * np.clip(h, -500.0, 11000.0)
    return temperature, 1.225 * (temperature / 288.15) ** 4.2559


def _redundant_speeds(columns: Mapping[str, np.ndarray]) -> list[tuple[str, np.ndarray]]:
    """The airspeeds the file's other channels imply, each with how it was formed."""
    out = []
    h = columns.get("h")
    if "qbar" in columns:
        rho, how = (columns["rho"], "rho") if "rho" in columns else (None, "")
        if rho is None and h is not None:
            rho, how = _isa(h)[1], "the ISA density at h"
        if rho is not None:
            out.append((f"sqrt(2 qbar / {how})", np.sqrt(2.0 * np.abs(columns["qbar"]) / rho)))
    if "Mach" in columns:
        if "a" in columns:
            a, how = columns["a"], "a"
        elif "T_air" in columns:
            a, how = np.sqrt(GAMMA_AIR * R_AIR * columns["T_air"]), "the speed of sound at T_air"
        elif h is not None:
            a, how = np.sqrt(GAMMA_AIR * R_AIR * _isa(h)[0]), "the ISA speed of sound at h"
        else:
            return out
        out.append((f"Mach times {how}", columns["Mach"] * a))
    return out


def _speed_unit(ratio: float) -> str | None:
    return next((name for name, factor in SPEED_UNITS if abs(ratio / factor - 1) < SPEED_TOLERANCE), None)


def check_airspeed_units(columns: Mapping[str, np.ndarray], source: str,
                         v_range: tuple[float, float] | None = None) -> None:
    """V in knots (km/h, ft/s, mph) against the redundant channels and the declared envelope ``V_range`` [m/s]."""
    v = float(np.median(columns["V"]))
    for how, implied in _redundant_speeds(columns):
        reference = float(np.median(implied))
        if not (np.isfinite(reference) and reference > 0):
            continue
        unit = _speed_unit(v / reference)
        if unit is not None:
            raise DataError(f"V looks like {unit}: its median {v:.4g} is {v / reference:.3f} times {how} "
                            f"({reference:.4g} m/s); airspeed must be in m/s", source=source, column="V")
    if v_range is None:
        return
    low, high = v_range
    if low <= v <= high:
        return
    unit = next((name for name, factor in SPEED_UNITS if low <= v / factor <= high), None)
    hint = f"V looks like {unit} ({v / dict(SPEED_UNITS)[unit]:.4g} m/s); " if unit else ""
    raise DataError(f"{hint}its median {v:.4g} m/s is outside the aircraft's V_range [{low:g}, {high:g}] m/s; "
                    "airspeed must be in m/s", source=source, column="V")
