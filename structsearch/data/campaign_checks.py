"""The checks of a campaign on disk (docs/interfaces.md sections 1 and 5): campaign.toml's values (the [aircraft]
table, the [[maneuver]] entries' keys and flights, [cutoffs], the top-level keys) and every maneuver file's columns
(required columns, finite values, increasing time, positive airspeed, length, units of angles and rates). Each
problem raises one :class:`~structsearch.errors.DataError` naming the file, the column and the row.
"""
from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Mapping

import numpy as np

from .errors import DataError
from . import records
from .moment_transfer import REFERENCE_KEY, check_reference_point
from .tables import LINE_KEY
from . import units
from .reading import shown

REQUIRED = ("t", "alpha", "q", "V", "de")
# The lateral-directional channels a standard campaign may carry (optional; checked when present, as the others):
# sideslip beta (positive with the relative wind from the right), roll and yaw rates p and r (body axes: right wing
# down and nose right positive), aileron da (JSBSim's left aileron position: positive with the left aileron trailing
# edge down, which rolls the aircraft right) and rudder dr (positive trailing edge left, which yaws it left), the
# side force, rolling and yawing moment coefficients CY, Cl and Cn (positive to the right, right wing down, nose
# right). SI, radians.
LATERAL = ("beta", "p", "r", "da", "dr", "CY", "Cl", "Cn")
ANGLES = ("alpha", "de", "theta", "phi", "beta", "da", "dr")
# Raw flight-test campaigns (docs/interfaces.md 5.2, ``format = "raw"``): the channels as recorded.
RAW_REQUIRED = ("t", "ax", "ay", "az", "p", "q", "r", "phi", "theta", "V", "alpha", "h", "de", "thrust")
RAW_ANGLES = ("alpha", "de", "theta", "phi", "beta", "da", "dr")
# Largest plausible magnitude of an angle in radians; more looks like degrees.
MAX_ANGLE_RAD = 1.2
# ... except a bank angle: an upset or a wing drop rolls past 70 deg, and a bank is at most pi in radians
MAX_ANGLE_RAD_OF = {"phi": math.pi}
# The shortest maneuver worth fitting is measured in convective times cbar/V (structsearch.data.records)
MIN_CONVECTIVE_TIMES = records.MIN_CONVECTIVE_TIMES
MIN_SAMPLES = records.MIN_SAMPLES
AIRCRAFT_KEYS = ("S", "cbar", "b")
# optional aircraft data (docs/interfaces.md 5.1): positive scalars, signed scalars, and vectors of a length
OPTIONAL_POSITIVE = ("mass", "Ixx", "Iyy", "Izz")
OPTIONAL_SIGNED = ("Ixz", "thrust_line_z")
OPTIONAL_VECTORS = {"x_cg_range": 2, "accelerometer": 3, "V_range": 2}
# Top-level names of campaign.toml that free-text keys of a campaign may not take.
RESERVED_KEYS = ("name", "format", "aircraft", "maneuver", "cutoffs", "min_convective_times")


# The one free table: ``source = { simulator = ..., aircraft = ..., ... }``, what flew a simulated campaign
SOURCE_KEY = "source"

# The keys a [[maneuver]] entry may hold (docs/interfaces.md 1, 6.4, 6.9): any other is a typo, refused.
MANEUVER_KEYS = ("id", "file", "kind", "split", "flight", "record", "segment", "periodic", "frequency", "steady")


def _close_match(key: str, known) -> str:
    close = difflib.get_close_matches(key, list(known), n=1, cutoff=0.6)
    return f" (did you mean {shown(close[0])}?)" if close else f" (known: {', '.join(known)})"


def _check_top_level(doc: dict, toml: str) -> None:
    """Top-level scalars are free metadata (the simulator's seed and truth, a preprocessing record), kept in
    ``Campaign.extra``; a table or list that is not one of campaign.toml's, or a scalar whose name is one
    letter or two from a reserved key (``fromat``), is a typo: refused with the close match."""
    for key, value in doc.items():
        if key in RESERVED_KEYS:
            continue
        if key == SOURCE_KEY and isinstance(value, dict) and all(not isinstance(v, (dict, list))
                                                                 for v in value.values()):
            continue   # where a simulated campaign comes from: { simulator = "jsbsim", aircraft = ..., ... }
        close = difflib.get_close_matches(key, RESERVED_KEYS, n=1, cutoff=0.75)
        if isinstance(value, (dict, list)) or close:
            hint = f" (did you mean {shown(close[0])}?)" if close else f" (tables: {', '.join(RESERVED_KEYS[2:])})"
            raise DataError(f"unknown key {shown(key)}{hint}", source=toml, column=key)


def _flight(entry: dict, where: str) -> str | None:
    """A maneuver's optional ``flight``: a non-empty string naming the flight it was flown on."""
    if "flight" not in entry:
        return None
    value = entry["flight"]
    if not isinstance(value, str) or not value.strip() or not value.isprintable():
        hint = f' (quote it: flight = "{value}")' if _number(value) else ""
        raise DataError(f"maneuver {shown(entry['id'])}: flight must be a non-empty string of printable characters "
                        f"naming the flight it was flown on, not {shown(value)}{hint}", source=where, column="flight")
    return value


def _periodic(entry: dict, where: str) -> tuple[bool, float | None]:
    """A maneuver's optional ``periodic`` (true or false) and ``frequency`` (Hz, positive and finite; it makes the
    maneuver periodic, so ``periodic = false`` beside it is a contradiction)."""
    periodic = entry.get("periodic")
    if periodic is not None and not isinstance(periodic, bool):
        raise DataError(f"maneuver {shown(entry['id'])}: periodic must be true or false, not {shown(periodic)}", source=where,
                        column="periodic")
    if "frequency" not in entry:
        return bool(periodic), None
    frequency = entry["frequency"]
    if not (_number(frequency) and frequency > 0):
        raise DataError(f"maneuver {shown(entry['id'])}: frequency must be a positive finite number of cycles per "
                        f"second (Hz), not {shown(frequency)}", source=where, column="frequency")
    if periodic is False:
        raise DataError(f"maneuver {shown(entry['id'])}: a frequency makes the maneuver periodic; remove periodic = false "
                        "or the frequency", source=where, column="frequency")
    return True, float(frequency)


def _steady(entry: dict, where: str, periodic: bool) -> bool:
    """A maneuver's optional ``steady`` (true or false): its samples are steady points (a static polar, trim
    points), each an equilibrium of the separation states; a cycle (``periodic``, ``frequency``) is not."""
    steady = entry.get("steady", False)
    if not isinstance(steady, bool):
        raise DataError(f"maneuver {shown(entry['id'])}: steady must be true or false, not {shown(steady)}",
                        source=where, column="steady")
    if steady and periodic:
        raise DataError(f"maneuver {shown(entry['id'])}: steady points are no cycle; remove steady = true or the "
                        "periodic and frequency keys", source=where, column="steady")
    if steady and "segment" in entry:
        raise DataError(f"maneuver {shown(entry['id'])}: steady points are not cut into cycles; remove its segment "
                        "key", source=where, column="segment")
    return steady


def check_steady(columns: Mapping[str, np.ndarray], source: str) -> None:
    """Steady points hold alpha still: an ``alpha_dot`` column, where the file has one, is zero."""
    rate = columns.get("alpha_dot")
    moving = np.flatnonzero(rate != 0) if rate is not None else np.array([], int)
    if moving.size:
        raise DataError(f"alpha_dot is {rate[moving[0]]:g} at a steady point; steady points are equilibria (alpha "
                        "held): give alpha_dot = 0 or drop the column, or declare the maneuver as a time series"
                        + _row_message(columns, int(moving[0])), source=source, column="alpha_dot",
                        row=int(moving[0]))


def _number(v) -> bool:
    """A finite int or float (TOML integers are unbounded: one beyond float range is not finite)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    try:
        return math.isfinite(v)
    except OverflowError:
        return False


def _parse_aircraft(aircraft: dict, toml: str) -> dict:
    """The [aircraft] table: S, cbar, b required; the optional data of docs/interfaces.md 5.1 checked."""
    out: dict = {}
    for key in AIRCRAFT_KEYS:
        if not _number(aircraft.get(key)) or aircraft[key] <= 0:
            raise DataError(f"[aircraft] needs a positive finite number {key}", source=toml, column=key)
        out[key] = float(aircraft[key])
    known = AIRCRAFT_KEYS + OPTIONAL_POSITIVE + OPTIONAL_SIGNED + tuple(OPTIONAL_VECTORS) + (REFERENCE_KEY,)
    for key, value in aircraft.items():
        if key not in known:
            raise DataError(f"[aircraft] has an unknown key {shown(key)}; known keys: {', '.join(known)}",
                            source=toml, column=key)
        if key in OPTIONAL_POSITIVE and not (_number(value) and value > 0):
            raise DataError(f"[aircraft] {key} must be a positive finite number, not {shown(value)}", source=toml,
                            column=key)
        if key in OPTIONAL_SIGNED and not _number(value):
            raise DataError(f"[aircraft] {key} must be a finite number, not {shown(value)}", source=toml, column=key)
        if key in OPTIONAL_VECTORS:
            n = OPTIONAL_VECTORS[key]
            if not (isinstance(value, list) and len(value) == n and all(_number(v) for v in value)):
                raise DataError(f"[aircraft] {key} must be a list of {n} finite numbers, not {shown(value)}",
                                source=toml, column=key)
            if key == "x_cg_range" and not value[0] < value[1]:
                raise DataError(f"[aircraft] x_cg_range must be [forward, aft] with forward < aft, not {shown(value)}",
                                source=toml, column=key)
            if key == "V_range" and not 0 < value[0] < value[1]:
                raise DataError(f"[aircraft] V_range must be [slowest, fastest] airspeed in m/s with 0 < slowest < "
                                f"fastest, not {shown(value)}", source=toml, column=key)
            out[key] = tuple(float(v) for v in value)
        elif key not in AIRCRAFT_KEYS and key != REFERENCE_KEY:
            out[key] = float(value)
    if REFERENCE_KEY in aircraft:   # checked against the cg envelope, whichever order the keys come in
        out[REFERENCE_KEY] = check_reference_point(aircraft[REFERENCE_KEY], out, toml)
    return out


def _row_message(columns: Mapping[str, np.ndarray], row: int) -> str:
    lines = columns.get(LINE_KEY)
    return f" (line {int(lines[row])})" if lines is not None and row < len(lines) else ""


# No measured quantity in any unit comes near it; a fit squares and sums the values, which must stay finite.
MAX_MAGNITUDE = 1e15


def validate_maneuver(columns: Mapping[str, np.ndarray], path: Path, required=REQUIRED, angles=ANGLES, *,
                      cbar: float | None = None, rule: records.LengthRule | None = None,
                      sample_rate: float | None = None, v_range: tuple[float, float] | None = None,
                      steady: bool = False) -> None:
    """One clear error for the first problem found in a maneuver's columns (``required`` and ``angles``: those
    of the standard format, or RAW_REQUIRED and RAW_ANGLES for a raw campaign). With the aircraft's ``cbar``, a
    maneuver shorter than ``rule`` (default: :class:`structsearch.data.records.LengthRule`) in convective times
    cbar/V is an error too. The units of time, pitch rate and airspeed are read from the file's redundant
    channels, the declared ``sample_rate`` [Hz] and the aircraft's ``v_range`` [m/s] (:mod:`.units`). ``steady``
    points have no time step, duration or rate to check; their alpha_dot, where given, is zero."""
    source = str(path)
    _check_required(columns, source, required)
    n = len(columns["t"])
    if n < MIN_SAMPLES and not steady:   # steady points are each an equilibrium: no dynamics to follow
        raise DataError(f"maneuver has {n} samples; it needs at least {MIN_SAMPLES} to fit separation dynamics",
                        source=source, column="t")
    _check_values(columns, source)
    _check_time_and_speed(columns, source)
    if not steady:
        units.check_step(columns["t"], source, sample_rate)
    why = None if cbar is None or steady else (rule or records.LengthRule()).problem(columns["t"], columns["V"], cbar)
    if why is not None:
        raise DataError(f"maneuver is too short to fit separation dynamics: {why}", source=source, column="t")
    _check_angles(columns, source, angles)
    _check_rates(columns, source)
    if steady:
        check_steady(columns, source)
    else:
        units.check_rate_units(columns, source)
    units.check_airspeed_units(columns, source, v_range)


def _check_required(columns: Mapping[str, np.ndarray], source: str, required) -> None:
    """Each required column present, or one error naming it (and the column a typo or a space made of it)."""
    names = [c for c in columns if c != LINE_KEY]
    for col in required:
        if col not in columns:
            close = [c for c in names if c.lower() == col.lower()]
            spaced = [c for c in names if c.strip() == col]
            hint = (f" (found {shown(close[0])}: column names are case-sensitive)" if close else
                    f" (found {shown(spaced[0])}: remove the spaces around the column name)" if spaced else
                    " (a phase-averaged cycle without time stamps: give its frequency in Hz in its [[maneuver]] "
                    "entry)" if col == "t" else "")
            raise DataError(f"required column is missing{hint}", source=source, column=col)


def _check_values(columns: Mapping[str, np.ndarray], source: str) -> None:
    """Every value finite and of a magnitude whose square a fit can hold."""
    for col in (c for c in columns if c != LINE_KEY):
        values = columns[col]
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise DataError("value is NaN or infinite" + _row_message(columns, int(bad[0])), source=source,
                            column=col, row=int(bad[0]))
        huge = np.flatnonzero(np.abs(values) > MAX_MAGNITUDE)
        if huge.size:
            raise DataError(f"value {values[huge[0]]:g} is an absurd magnitude (above {MAX_MAGNITUDE:g}): its squares "
                            "would overflow a fit" + _row_message(columns, int(huge[0])), source=source, column=col,
                            row=int(huge[0]))


def _check_time_and_speed(columns: Mapping[str, np.ndarray], source: str) -> None:
    """Time strictly increasing; airspeed positive."""
    bad = np.flatnonzero(np.diff(columns["t"]) <= 0)
    if bad.size:
        raise DataError("time is not strictly increasing" + _row_message(columns, int(bad[0]) + 1),
                        source=source, column="t", row=int(bad[0]) + 1)
    slow = np.flatnonzero(columns["V"] <= 0)
    if slow.size:
        raise DataError(f"airspeed {columns['V'][slow[0]]:g} m/s is not positive"
                        + _row_message(columns, int(slow[0])), source=source, column="V", row=int(slow[0]))


def _check_angles(columns: Mapping[str, np.ndarray], source: str, angles) -> None:
    """Angles in radians: a value beyond :data:`MAX_ANGLE_RAD` (a bank beyond pi) is in degrees."""
    for col in angles:
        if col in columns:
            big = np.flatnonzero(np.abs(columns[col]) > MAX_ANGLE_RAD_OF.get(col, MAX_ANGLE_RAD))
            if big.size:
                raise DataError(f"value {columns[col][big[0]]:g} looks like degrees; angles must be in "
                                f"radians" + _row_message(columns, int(big[0])), source=source, column=col,
                                row=int(big[0]))


# Body rates beyond a full turn per second are not flown by a fixed-wing aircraft: degrees per second.
MAX_RATE_RAD_S = 2 * math.pi
RATES = ("q", "p", "r")


def _check_rates(columns: Mapping[str, np.ndarray], source: str) -> None:
    """Rates in rad/s: a rate above a turn per second is refused (a pitch rate in deg/s with small values, a
    gentle stall at 5 deg/s, is found by :func:`.units.check_rate_units`)."""
    for col in RATES:
        if col in columns:
            big = np.flatnonzero(np.abs(columns[col]) > MAX_RATE_RAD_S)
            if big.size:
                raise DataError(f"value {columns[col][big[0]]:g} looks like degrees per second; rates must be in "
                                "rad/s" + _row_message(columns, int(big[0])), source=source, column=col,
                                row=int(big[0]))


def _parse_cutoffs(table, toml: str) -> dict[str, float]:
    """``[cutoffs]``: pre-filter cut-offs [Hz] by channel that override the defaults (docs/interfaces.md 5.2)."""
    if not isinstance(table, dict):
        raise DataError("[cutoffs] must be a table of channel = frequency in Hz", source=toml, column="cutoffs")
    for key, value in table.items():
        if not (_number(value) and value > 0):
            raise DataError(f"[cutoffs] {key} must be a positive frequency in Hz, not {shown(value)}", source=toml,
                            column=key)
    return {k: float(v) for k, v in table.items()}
