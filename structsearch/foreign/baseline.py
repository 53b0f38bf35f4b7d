"""``diagnose --simulator jsbsim:NAME_OR_DIR``: any JSBSim aircraft as the baseline of a diagnosis, term by term.

The aircraft (one of JSBSim's own or an aircraft directory) is evaluated at every recorded sample
(:mod:`.evaluate`). What it is given, and in which units:

* the state: ``h`` [m] -> ``ic/h-sl-ft``, ``V`` [m/s] -> ``ic/vt-fps``, ``alpha``, ``q`` [rad, rad/s] as they are;
  ``beta``, ``theta``, ``phi``, ``p``, ``r`` from columns of those names when the campaign has them, else
  symmetric wings-level flight (beta = phi = p = r = 0) with theta = alpha (none of these change the
  longitudinal coefficients but through the aircraft's own tables of them);
* ``de`` [rad] -> ``fcs/elevator-pos-rad`` (both positive trailing edge down); ``da`` -> ``fcs/left-aileron-pos-rad``
  and its negative -> ``fcs/right-aileron-pos-rad``, ``dr`` -> ``fcs/rudder-pos-rad`` where the aircraft reads them
  (JSBSim's signs, as the campaign's);
* ``alpha_dot`` [rad/s] -> ``structsearch/alphadot-rad_sec``, read in place of ``aero/alphadot-rad_sec``;
* ``aero/stall-hyst-norm``: JSBSim's own latch run along each maneuver's recorded alpha (set above the
  aircraft's ``<hysteresis_limits>`` max, cleared below its min, starting cleared unless the first sample is above
  the max);
* every other property the diagnosed axis reads that JSBSim does not derive from the state (a flap position, a
  propeller's induced velocity, ...): ``--simulator-input PROPERTY=COLUMN`` (a campaign column, in the property's
  own unit) or ``PROPERTY=VALUE`` (a constant). Those missing are listed in one error.

The coefficient of each axis function (:func:`terms`): a LIFT or DRAG function's force over q S, a PITCH
function's moment over q S cbar (JSBSim's q, S and cbar, in lbs, ft). JSBSim's pitch functions act about the
aircraft's aerodynamic reference point; C_m about the campaign's cg adds the moment of the aerodynamic force, the
term ``sim:transfer`` = C_N (x_cg - x_ARP) / cbar + C_A (z_ARP - z_cg) / cbar (structural frame, x aft, z up;
C_N = -F_z / q S, C_A = -F_x / q S from JSBSim's body-axis aerodynamic forces), with the campaign's ``x_cg`` [m]
read as a station of the aircraft's structural frame (JSBSim's own cg when the campaign has no x_cg) and
JSBSim's z_cg. C_Y, C_l and C_n are the body-axis side force and the moments about JSBSim's own cg
(:mod:`.lateral_terms`). The baseline is the sum of the terms.
"""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from ..data.campaign import Campaign
from ..data.errors import DataError, DeclarationError
from ..diagnosis.offset import JSBSIM_PREFIX, SimulatorBaseline, check_values
from ..data.coefficients import coefficient as coefficient_record
from .aircraft_xml import AircraftFile, axes_read, check_axes, read_aircraft
from .evaluate import evaluate
from .lateral_terms import TERM_PREFIX, TRANSFER, lateral_terms
from .private_copy import ALPHADOT, ELEVATOR, ELEVATOR_DERIVED, HYSTERESIS, INPUT_PREFIX, derived, rewritten

# the lateral surfaces an aircraft's axes may read, from the campaign's columns (JSBSim's signs: the left
# aileron's position is da, the right one's -da)
SURFACES = {"fcs/left-aileron-pos-rad": ("da", 1.0), "fcs/right-aileron-pos-rad": ("da", -1.0),
            "fcs/rudder-pos-rad": ("dr", 1.0)}
FT = 0.3048
# state -> (campaign column, its factor to JSBSim's unit, the default when the campaign lacks the column: None
# when it is required, "alpha" for theta)
STATE_COLUMNS = {"ic/h-sl-ft": ("h", 1.0 / FT, None), "ic/vt-fps": ("V", 1.0 / FT, None),
                 "ic/alpha-rad": ("alpha", 1.0, None), "ic/beta-rad": ("beta", 1.0, 0.0),
                 "ic/theta-rad": ("theta", 1.0, "alpha"), "ic/phi-rad": ("phi", 1.0, 0.0),
                 "ic/p-rad_sec": ("p", 1.0, 0.0), "ic/q-rad_sec": ("q", 1.0, None), "ic/r-rad_sec": ("r", 1.0, 0.0)}
MAX_CHORDS = 2.0


def parse_inputs(items: Sequence[str]) -> dict[str, str | float]:
    """``--simulator-input PROPERTY=COLUMN|VALUE`` items as property -> column name or number."""
    out: dict[str, str | float] = {}
    for item in items:
        prop, sep, value = item.partition("=")
        prop, value = prop.strip(), value.strip()
        if not sep or not prop or not value:
            raise DeclarationError(f"--simulator-input {item!r}: give PROPERTY=COLUMN or PROPERTY=VALUE "
                                   "(e.g. fcs/flap-pos-deg=0)")
        if prop in out:
            raise DeclarationError(f"--simulator-input names {prop} twice")
        try:
            number = float(value)
        except ValueError:
            out[prop] = value
            continue
        if not math.isfinite(number):
            raise DeclarationError(f"--simulator-input {item!r}: the value must be a finite number")
        out[prop] = number
    return out


def _source(campaign: Campaign) -> str:
    return str(campaign.directory / "campaign.toml") if campaign.directory is not None else campaign.name


def _given(campaign: Campaign, prop: str, value) -> np.ndarray:
    n = campaign.data.n_samples
    if not isinstance(value, str):
        return np.full(n, float(value))
    if value not in campaign.data:
        raise DataError(f"--simulator-input {prop}={value}: the campaign has no column {value!r}",
                        source=_source(campaign), column=value)
    return np.asarray(campaign.data[value], float)


def hysteresis(campaign: Campaign, limits: tuple[float, float] | None) -> np.ndarray:
    """JSBSim's stall latch along each maneuver's alpha (module docstring); 0 without hysteresis limits."""
    alpha = np.asarray(campaign.data["alpha"], float)
    out = np.zeros_like(alpha)
    if limits is None:
        return out
    lo, hi = limits
    for sl in campaign.data.segment_slices():
        latch = 0.0
        for k in range(sl.start, sl.stop):
            latch = 1.0 if alpha[k] > hi else 0.0 if alpha[k] < lo else latch
            out[k] = latch
    return out


def _states(campaign: Campaign, given: Mapping) -> tuple[dict, dict, list[str]]:
    data, states, record, missing = campaign.data, {}, {}, []
    for prop, (column, factor, default) in STATE_COLUMNS.items():
        if prop in given:
            states[prop], record[prop] = _given(campaign, prop, given[prop]), given[prop]
        elif column in data:
            states[prop], record[prop] = np.asarray(data[column], float) * factor, column
        elif default is None:
            missing.append(f"{prop} (the campaign has no column {column}: --simulator-input {prop}=VALUE, in the "
                           "property's unit)")
        else:
            states[prop] = np.asarray(data[default], float) if isinstance(default, str) else np.full(data.n_samples,
                                                                                                       default)
            record[prop] = default
    return states, record, missing


def _inputs(campaign: Campaign, aircraft: AircraftFile, reads: set[str], given: Mapping):
    """The properties written besides the state (module docstring), what each was taken from, and the missing."""
    data, inputs, record, missing = campaign.data, {}, {}, []
    if reads & set(ELEVATOR_DERIVED):   # JSBSim derives them from the elevator position written
        reads = reads | {ELEVATOR}
    for prop in sorted(reads):
        if derived(prop) and prop != ELEVATOR:
            continue
        target = rewritten(prop)
        if prop in given:
            inputs[target], record[prop] = _given(campaign, prop, given[prop]), given[prop]
        elif prop == ELEVATOR:
            inputs[target], record[prop] = np.asarray(data["de"], float), "de"
        elif prop in SURFACES and SURFACES[prop][0] in data:
            column, sign = SURFACES[prop]
            inputs[target] = sign * np.asarray(data[column], float)
            record[prop] = column if sign > 0 else f"-{column}"
        elif prop in ALPHADOT:
            scale = 1.0 if prop.endswith("rad_sec") else 180.0 / math.pi
            inputs[target], record[prop] = np.asarray(data["alpha_dot"], float) * scale, "alpha_dot"
        elif prop == HYSTERESIS:
            inputs[target] = hysteresis(campaign, aircraft.hysteresis)
            record[prop] = "JSBSim's stall latch along each maneuver's alpha" + (
                f" (set above {aircraft.hysteresis[1]:g} rad, cleared below {aircraft.hysteresis[0]:g} rad)"
                if aircraft.hysteresis else " (no hysteresis limits: 0)")
        elif target.startswith(INPUT_PREFIX):
            missing.append(f"{prop} (--simulator-input {prop}=COLUMN or {prop}=VALUE, in the property's unit)")
    return inputs, record, missing


def _check_given(given: Mapping, aircraft: AircraftFile, target: str) -> None:
    """Every ``--simulator-input`` names a state or a property the aircraft's aerodynamics read (any axis: one the
    diagnosed axis does not read is unused)."""
    known = aircraft.leaves(list(aircraft.reads)) | set(STATE_COLUMNS)
    stray = [p for p in given if p not in known]
    if stray:
        raise DeclarationError(f"--simulator-input {stray[0]}: the aircraft {target} does not read it (it reads: "
                               f"{', '.join(sorted(p for p in known if not derived(p) or p == ELEVATOR))})")


def terms(evaluation, coefficient: str, aircraft: AircraftFile, x_cg_ft: np.ndarray | None) -> dict[str, np.ndarray]:
    """Each axis function of ``coefficient``'s axis as its share of the coefficient (module docstring), named
    ``sim:<function>``; for a moment and for C_Y also ``sim:transfer``."""
    record = coefficient_record(coefficient)
    if record.lateral:
        return lateral_terms(evaluation, record, aircraft.functions(record.jsbsim_axis))
    g = evaluation.geometry
    qs = evaluation.qbar * g["metrics/Sw-sqft"]
    scale = qs * (g["metrics/cbarw-ft"] if record.moment else 1.0)
    out = {TERM_PREFIX + f: evaluation.functions[f] / scale for f in aircraft.functions(record.jsbsim_axis)}
    if record.moment:
        cbar = g["metrics/cbarw-ft"]
        x_cg = g["inertia/cg-x-in"] / 12.0 if x_cg_ft is None else x_cg_ft
        c_n = -evaluation.body["forces/fbz-aero-lbs"] / qs
        c_a = -evaluation.body["forces/fbx-aero-lbs"] / qs
        out[TRANSFER] = (c_n * (x_cg - g["metrics/aero-rp-x-in"] / 12.0)
                         + c_a * (g["metrics/aero-rp-z-in"] / 12.0 - g["inertia/cg-z-in"] / 12.0)) / cbar
    return out


def _signal(prop: str, record: Mapping) -> str | None:
    """The campaign signal a property JSBSim reads stands for (None: geometry, air data, a constant)."""
    if prop.startswith(("velocities/q", "velocities/q-aero")):
        return "q"
    if prop in ALPHADOT:
        return "alpha_dot"
    if prop.startswith("aero/alpha-") or prop == HYSTERESIS:
        return "alpha"
    if prop == ELEVATOR or prop in ELEVATOR_DERIVED:
        return "de"
    if prop.startswith(("aero/beta-", "aero/mag-beta-")):
        return "beta"
    if prop.startswith(("velocities/vt", "velocities/mach")):
        return "V"
    value = record.get(prop)
    return value if isinstance(value, str) else None


def term_signals(aircraft: AircraftFile, coefficient: str, record: Mapping) -> dict[str, tuple[str, ...]]:
    """Per term, the campaign signals it reads (through the helper functions)."""
    out = {}
    for f in aircraft.functions(coefficient_record(coefficient).jsbsim_axis):
        out[TERM_PREFIX + f] = tuple(sorted({s for p in aircraft.leaves([f]) if (s := _signal(p, record))}))
    if coefficient_record(coefficient).transfer_reads:
        out[TRANSFER] = coefficient_record(coefficient).transfer_reads
    return out


def _check_cg(campaign: Campaign, x_cg_ft: np.ndarray, evaluation) -> None:
    g = evaluation.geometry
    far = float(np.max(np.abs(x_cg_ft - g["metrics/aero-rp-x-in"] / 12.0))) / g["metrics/cbarw-ft"]
    if far > MAX_CHORDS:
        raise DataError(f"x_cg lies {far:.1f} chords from the aircraft's aerodynamic reference point "
                        f"({g['metrics/aero-rp-x-in'] * 0.0254:.3f} m): C_m about the campaign's cg needs x_cg as a "
                        "station of the aircraft's structural frame (x aft, in m)", source=_source(campaign),
                        column="x_cg")


def evaluate_campaign(target: str, campaign: Campaign, coefficient: str,
                      given: Mapping[str, str | float] | None = None, scales: Mapping[str, float] | None = None,
                      also=()):
    """(the aircraft, JSBSim's evaluation at every sample of ``campaign``, what each property was taken from, the
    axes evaluated) for ``coefficient`` (module docstring); ``also``: properties read besides (tests)."""
    given = dict(given or {})
    aircraft = read_aircraft(target)
    functions = list(check_axes(aircraft, coefficient))
    axes = axes_read(coefficient)
    reads = aircraft.leaves([f for a in axes for f in aircraft.functions(a)])
    _check_given(given, aircraft, target)
    states, state_record, missing = _states(campaign, given)
    inputs, input_record, missing_inputs = _inputs(campaign, aircraft, reads, given)
    missing += missing_inputs
    if missing:
        raise DeclarationError(f"--simulator jsbsim:{target}: the aircraft {aircraft.name} reads what the campaign "
                               f"does not give ({_source(campaign)}); supply each: " + "; ".join(missing))
    evaluation = evaluate(aircraft, functions, states, inputs, scales, also)
    return aircraft, evaluation, {**state_record, **input_record}, axes


def jsbsim_baseline(target: str, campaign: Campaign, coefficient: str,
                    given: Mapping[str, str | float] | None = None,
                    scales: Mapping[str, float] | None = None) -> SimulatorBaseline:
    """The JSBSim aircraft ``target``'s ``coefficient`` at every sample of ``campaign``, term by term (``scales``:
    function -> factor, a modified aircraft: :mod:`.modify`)."""
    aircraft, evaluation, record, axes = evaluate_campaign(target, campaign, coefficient, given, scales)
    x_cg_ft = np.asarray(campaign.data["x_cg"], float) / FT if "x_cg" in campaign.data and coefficient == "Cm" \
        else None
    if x_cg_ft is not None:
        _check_cg(campaign, x_cg_ft, evaluation)
    parts = {k: check_values(campaign, v, k) for k, v in terms(evaluation, coefficient, aircraft, x_cg_ft).items()}
    detail = {"aircraft": aircraft.name, "aircraft_file": str(aircraft.file), "bundled": aircraft.bundled,
              "jsbsim_version": evaluation.version, "inputs": record,
              "functions": {f: a for a in axes for f in aircraft.functions(a)},
              "coefficient_from": _from_text(coefficient, x_cg_ft is not None),
              "seconds_in_jsbsim": round(evaluation.seconds, 3), "samples": campaign.data.n_samples}
    if scales:
        detail["scales"] = dict(scales)
    total = np.sum(list(parts.values()), axis=0)
    return SimulatorBaseline(coefficient, f"{JSBSIM_PREFIX}{aircraft.name}", "jsbsim", total, detail, terms=parts,
                             term_signals=term_signals(aircraft, coefficient, record))


def _from_text(coefficient: str, campaign_cg: bool) -> str:
    if coefficient_record(coefficient).lateral:
        record = coefficient_record(coefficient)
        if not record.moment:
            return ("the SIDE axis functions (lbs, wind axes) over JSBSim's q S, plus sim:transfer, the rest of the "
                    "body-axis side force (the drag turned by the sideslip)")
        return (f"the {record.jsbsim_axis} axis functions (lbs ft, about the aerodynamic reference point) over q S b, "
                "plus sim:transfer, the aerodynamic force's moment about JSBSim's own cg")
    if coefficient == "CL":
        return "the LIFT axis functions (lbs) over JSBSim's q S (psf, sq ft)"
    if coefficient == "CD":
        return "the DRAG axis functions (lbs) over JSBSim's q S (psf, sq ft)"
    cg = "the campaign's x_cg (a station of the aircraft's structural frame)" if campaign_cg else "JSBSim's own cg"
    return ("the PITCH axis functions (lbs ft, about the aerodynamic reference point) over q S cbar, plus "
            f"sim:transfer, the aerodynamic force's moment about {cg}")
