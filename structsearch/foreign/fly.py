"""``simulate --jsbsim NAME_OR_DIR``: a stall campaign flown in JSBSim, through the project's measurement chain.

A campaign flown in JSBSim is the aircraft *model* flown, not a flight: what a diagnosis against the same aircraft
finds is what the modification (``--modify``) changed, and nothing of the real aircraft.

Each maneuver is flown by JSBSim itself (its integration, flight controls, engine and stall latch; the private
copy only applies ``--modify`` and drops ``<output>`` directives) at 100 Hz: trimmed in level flight with the
engine running at the maneuver's airspeed and altitude, then an open-loop elevator profile over the trim command
(``fcs/elevator-cmd-norm``; negative pulls): ``quasi-steady`` a slow ramp to the stop, a hold and the recovery,
``dynamic`` a faster ramp (to 70 % of the travel from trim to the stop) with a doublet after the recovery,
``deep-dynamic`` a pull (to 85 %) in two seconds, a hold through the stall and a push to recover. The throttle stays at its trim setting.

The truth histories (airspeed, alpha, q, theta, h, the elevator position, thrust, dynamic pressure, mass, cg,
C_L and C_D from the LIFT and DRAG axes, C_m from JSBSim's aerodynamic moment about its cg) go through
:func:`structsearch.flight.measurement.measure` (sensor rates, noise and biases, buffet while JSBSim's stall latch is
set, the pre-filter and the reconstruction of the coefficients from specific forces and pitch acceleration; the
slow reconstruction errors are left out). C_m is reconstructed from the measured pitch acceleration, less the
engine's pitching moment (JSBSim's ``moments/m-prop-lbsft`` over q S cbar: the reduction removes the engine's moment
as it removes its thrust). The campaign's ``x_cg`` is JSBSim's cg station
[m] (structural frame, x aft), and the column ``prop_induced_fps`` records the propeller's induced velocity
(``propulsion/engine/prop-induced-velocity_fps``), which some aircraft's elevator power reads.

With ``lateral`` the lateral maneuvers of :mod:`.lateral_plan` follow the stall plan, and every maneuver goes
through the lateral measurement chain too (:mod:`structsearch.flight.lateral_measurement`: beta, p, r, phi, the
aileron and rudder positions, C_Y, C_l and C_n reconstructed, their truths from JSBSim's body-axis aerodynamic side
force and its aerodynamic moments about the cg; C_m gains the inertial coupling of the rates); the manifest gains
I_xx and I_zz and the campaign a ``qbar`` column.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping
import numpy as np

from ..data.campaign import Campaign, Maneuver, make_campaign
from ..data.errors import StructSearchError
from ..flight.aircraft import Aircraft
from ..flight.measurement import measure
from .aircraft_xml import AircraftFile, read_aircraft
from .evaluate import need_jsbsim
from .lateral_plan import LATERAL_PLAN, lateral_commands, pilot_aileron
from .modify import LAG_ACTIVE, Lag, Modification
from .private_copy import make_copy
from .wing_drop import STATES as WING_DROP_STATES

FT, LBF, SLUG, SLUGFT2, PSF, LBFFT = 0.3048, 4.4482216152605, 14.593902937, 1.3558179483, 47.880258889, 1.3558179483
RATE_HZ = 100.0
# maneuvers of each kind at scale 1, and their lengths [s]
PLAN = {"quasi-steady": (8, 60.0), "dynamic": (10, 35.0), "deep-dynamic": (8, 25.0)}
# the share of the travel from trim to the nose-up stop each kind pulls to (a fast pull to the stop departs)
REACH = {"quasi-steady": 1.0, "dynamic": 0.7, "deep-dynamic": 0.85}
PROP_INDUCED = "propulsion/engine/prop-induced-velocity_fps"


@dataclass(frozen=True)
class Planned:
    id: str
    kind: str
    split: str
    duration: float
    v_kts: float
    h_ft: float
    pace: float        # the profile's time scale (1: nominal)


def plan(scale: float, seed: int, lateral: bool = False) -> list[Planned]:
    """The maneuvers flown: at scale 1 :data:`PLAN` (and with ``lateral`` then
    :data:`~.lateral_plan.LATERAL_PLAN`), at least one of each kind; every fourth one validates."""
    rng = np.random.default_rng([seed, 53])
    out = []
    for kind, (count, duration) in (PLAN | LATERAL_PLAN if lateral else PLAN).items():
        for _ in range(max(1, round(count * scale))):
            k = len(out)
            out.append(Planned(f"j{k + 1:02d}", kind, "validation" if k % 4 == 3 else "train", duration,
                               float(rng.uniform(60.0, 80.0)), float(rng.uniform(4000.0, 7000.0)),
                               float(rng.uniform(0.8, 1.25))))
    return out


def elevator_profile(p: Planned, t: np.ndarray, trim: float) -> np.ndarray:
    """The elevator command over trim (module docstring), from trim to the nose-up stop (-1) and back."""
    full = (-1.0 - trim) * REACH[p.kind]
    s = t / p.pace

    def ramp(a, b):
        return np.clip((s - a) / max(b - a, 1e-9), 0.0, 1.0)
    if p.kind == "quasi-steady":
        u = full * (ramp(3, 38) - ramp(43, 45))
    elif p.kind == "dynamic":
        u = full * (ramp(2, 12) - ramp(15, 16)) + 0.25 * (ramp(22, 22.5) - 2 * ramp(23.5, 24) + ramp(25, 25.5))
    else:
        u = full * (ramp(2, 4) - ramp(9, 10)) + 0.3 * (ramp(9, 10) - ramp(12, 13))
    return np.clip(trim + u, -1.0, 1.0) - trim


def _start(jsbsim, root: str, aircraft: AircraftFile, p: Planned, lags: tuple[Lag, ...] = ()):
    fdm = jsbsim.FGFDMExec(root)
    fdm.set_debug_level(0)
    manager = fdm.get_property_manager()
    for prop in [LAG_ACTIVE] * bool(lags) + [lag.lagged for lag in lags]:   # read by the copy: made before it loads
        manager.get_node(prop, True).set_double_value(0.0)
    if not fdm.load_model(aircraft.name):
        raise StructSearchError(f"JSBSim could not load the aircraft {aircraft.name!r} ({aircraft.file})")
    fdm.set_dt(1.0 / RATE_HZ)
    fdm["ic/h-sl-ft"] = p.h_ft
    fdm["ic/vc-kts"] = p.v_kts
    fdm["ic/gamma-deg"] = 0.0
    fdm["propulsion/set-running"] = -1
    fdm.run_ic()
    try:
        fdm["simulation/do_simple_trim"] = 1
    except Exception as exc:   # JSBSim's trim failure
        raise StructSearchError(f"JSBSim could not trim {aircraft.name} at {p.v_kts:.0f} kt, {p.h_ft:.0f} ft for "
                                f"maneuver {p.id}: {exc}") from None
    if lags:   # trimmed without the lags (in equilibrium a lagged input is the input): they start there
        for lag in lags:
            fdm[lag.lagged] = float(fdm[lag.input])
        fdm[LAG_ACTIVE] = 1.0
    return fdm


def _hold_lags(fdm, lags: tuple[Lag, ...]) -> None:
    """Each lag's value of the frame just run, kept for the next (:func:`.private_copy.make_copy` steps it)."""
    for lag in lags:
        fdm[lag.lagged] = fdm[lag.read]


RECORD = ("velocities/vt-fps", "aero/alpha-rad", "velocities/q-rad_sec", "attitude/theta-rad", "position/h-sl-ft",
          "fcs/elevator-pos-rad", "propulsion/engine/thrust-lbs", "aero/qbar-psf", "inertia/mass-slugs",
          "inertia/cg-x-in", "moments/m-aero-lbsft", "inertia/iyy-slugs_ft2", "aero/stall-hyst-norm",
          PROP_INDUCED, "moments/m-prop-lbsft")
LATERAL_RECORD = ("aero/beta-rad", "velocities/p-rad_sec", "velocities/r-rad_sec", "attitude/phi-rad",
                  "fcs/left-aileron-pos-rad", "fcs/rudder-pos-rad", "forces/fby-aero-lbs", "moments/l-aero-lbsft",
                  "moments/n-aero-lbsft", "forces/fby-prop-lbs", "moments/l-prop-lbsft", "moments/n-prop-lbsft",
                  "inertia/ixx-slugs_ft2", "inertia/izz-slugs_ft2", "inertia/ixz-slugs_ft2")


def _commands(p: Planned, t: np.ndarray, trim: float, phases: np.ndarray,
              hold_bank: bool = False) -> dict[str, np.ndarray]:
    """A maneuver's commands: the elevator's (absolute) and, for a lateral kind (or any kind with ``hold_bank``),
    the aileron and rudder excitations over their trim and the bank the pilot holds (:mod:`.lateral_plan`)."""
    if p.kind not in LATERAL_PLAN:
        zero = np.zeros_like(t)
        return {"elevator": trim + elevator_profile(p, t, trim)} | (
            {"aileron": zero, "rudder": zero, "bank": zero} if hold_bank else {})
    out = lateral_commands(p.kind, t / p.pace, -1.0 - trim, phases)
    out["elevator"] = np.clip(trim + out["elevator"], -1.0, 1.0)
    return out


def _fly_frames(fdm, commands: dict, names: tuple[str, ...], lags: tuple[Lag, ...], lift, drag) -> np.ndarray:
    """Run the maneuver frame by frame; returns the recorded ``names`` and the summed LIFT and DRAG functions."""
    n = len(commands["elevator"])
    lateral = "aileron" in commands
    trim_aileron, trim_rudder = float(fdm["fcs/aileron-cmd-norm"]), float(fdm["fcs/rudder-cmd-norm"])
    rec = np.empty((len(names) + 2, n))
    for k in range(n):
        fdm["fcs/elevator-cmd-norm"] = commands["elevator"][k]
        if lateral:
            fdm["fcs/aileron-cmd-norm"] = pilot_aileron(trim_aileron + commands["aileron"][k], commands["bank"][k],
                                                        fdm["attitude/phi-rad"], fdm["velocities/p-rad_sec"])
            fdm["fcs/rudder-cmd-norm"] = float(np.clip(trim_rudder + commands["rudder"][k], -1.0, 1.0))
        fdm.run()
        _hold_lags(fdm, lags)
        for j, name in enumerate(names):
            rec[j, k] = fdm[name]
        rec[-2, k] = sum(fdm[f] for f in lift)
        rec[-1, k] = sum(fdm[f] for f in drag)
    return rec


def fly_one(jsbsim, root: str, aircraft: AircraftFile, p: Planned, lags: tuple[Lag, ...] = (),
            lateral: bool = False, phases: np.ndarray | None = None, states: Mapping[str, str] | None = None) -> dict:
    """The truth histories of one maneuver (module docstring), in SI units; ``lags`` those of ``--modify``;
    ``lateral``: with the lateral truths (key ``lateral``); ``phases`` a lateral kind's multisine phases;
    ``states``: separation states the modification flies (symbol -> property), recorded beside the stall latch's;
    with them the pilot holds the wings level on every maneuver (a wing drop flown open loop departs into a
    spiral dive)."""
    states = dict(states or {})
    fdm = _start(jsbsim, root, aircraft, p, lags)
    t = np.arange(int(round(p.duration * RATE_HZ))) / RATE_HZ
    commands = _commands(p, t, float(fdm["fcs/elevator-cmd-norm"]), np.zeros(10) if phases is None else phases,
                         hold_bank=bool(states))
    names = RECORD + LATERAL_RECORD * lateral + tuple(states.values())
    rec = _fly_frames(fdm, commands, names, lags, aircraft.functions("LIFT"), aircraft.functions("DRAG"))
    s_ft2, cbar_ft, b_ft = float(fdm["metrics/Sw-sqft"]), float(fdm["metrics/cbarw-ft"]), float(fdm["metrics/bw-ft"])
    r = dict(zip(names, rec))
    qs = r["aero/qbar-psf"] * s_ft2
    iyy = r["inertia/iyy-slugs_ft2"] * SLUGFT2
    out = {"t": t, "V": r["velocities/vt-fps"] * FT, "alpha": r["aero/alpha-rad"], "q": r["velocities/q-rad_sec"],
           "theta": r["attitude/theta-rad"], "h": r["position/h-sl-ft"] * FT, "de": r["fcs/elevator-pos-rad"],
           "thrust": r["propulsion/engine/thrust-lbs"] * LBF, "qbar": r["aero/qbar-psf"] * PSF,
           "mass": r["inertia/mass-slugs"] * SLUG, "x_cg": r["inertia/cg-x-in"] * 0.0254,
           "CL": rec[-2] / qs, "CD": rec[-1] / qs, "Cm": r["moments/m-aero-lbsft"] / (qs * cbar_ft),
           "q_dot": r["moments/m-aero-lbsft"] * LBFFT / iyy, "iyy": iyy,
           "states": {"X": 1.0 - r["aero/stall-hyst-norm"], **{s: r[prop] for s, prop in states.items()}},
           "prop_induced_fps": r[PROP_INDUCED],
           "engine_cm": r["moments/m-prop-lbsft"] / (qs * cbar_ft),
           "geometry": (s_ft2 * FT ** 2, cbar_ft * FT, b_ft * FT)}
    if lateral:
        out["lateral"] = _lateral_truth(r, out, qs, b_ft)
    return out


def _lateral_truth(r: dict, out: dict, qs: np.ndarray, b_ft: float) -> dict:
    """The lateral truths (:func:`structsearch.flight.lateral_measurement.measure_lateral`'s ``truth``) in SI
    units. JSBSim's ``inertia/ixz-slugs_ft2`` is minus the product of inertia of the standard convention (the
    moment equations close on JSBSim's moments with its sign flipped)."""
    qsb = qs * b_ft
    return {"beta": r["aero/beta-rad"], "p": r["velocities/p-rad_sec"], "r": r["velocities/r-rad_sec"],
            "phi": r["attitude/phi-rad"], "da": r["fcs/left-aileron-pos-rad"], "dr": r["fcs/rudder-pos-rad"],
            "CY": r["forces/fby-aero-lbs"] / qs, "Cl": r["moments/l-aero-lbsft"] / qsb,
            "Cn": r["moments/n-aero-lbsft"] / qsb, "fy_engine": r["forces/fby-prop-lbs"] * LBF,
            "cl_engine": r["moments/l-prop-lbsft"] / qsb, "cn_engine": r["moments/n-prop-lbsft"] / qsb,
            "Ixx": r["inertia/ixx-slugs_ft2"] * SLUGFT2, "Iyy": out["iyy"], "Izz": r["inertia/izz-slugs_ft2"] * SLUGFT2,
            "Ixz": -r["inertia/ixz-slugs_ft2"] * SLUGFT2, "qbar": out["qbar"], "mass": out["mass"],
            "states": out["states"]}


def fly_campaign(target: str, modification: Modification | Mapping[str, float] | None = None, *,
                 scale: float = 1.0, seed: int = 0, lateral: bool = False) -> Campaign:
    """The campaign flown in JSBSim (module docstring), with the aircraft changed by ``modification``
    (``--modify``: :mod:`.modify`; a mapping function -> factor scales functions alone); ``lateral``: the lateral
    maneuvers too (:mod:`.lateral_plan`) and every maneuver with the lateral channels
    (:mod:`structsearch.flight.lateral_measurement`)."""
    if modification is not None and not isinstance(modification, Modification):
        modification = Modification(dict(modification))
    jsbsim = need_jsbsim()
    jsbsim.FGJSBBase().debug_lvl = 0
    aircraft = read_aircraft(target)
    modification = modification or Modification()
    missing = [f for f in modification.functions if not any(f in aircraft.functions(a) for a in aircraft.axes)]
    if missing:
        raise StructSearchError(f"--modify: the aircraft {aircraft.name} has no axis function {missing[0]!r}")
    holder = make_copy(aircraft, modification.scales, rewrite=False, lags=modification.lags, frame_s=1.0 / RATE_HZ,
                       tables=modification.tables, states=modification.states, wing_drops=modification.wing_drops)
    flown_states = WING_DROP_STATES if modification.wing_drops else {}
    # the lateral chain draws from a generator of its own: the longitudinal columns are those of a campaign without
    rng, lateral_rng = np.random.default_rng(seed), np.random.default_rng([seed, 56])
    maneuvers, segments, craft, inertia = [], [], None, []
    try:
        for p in plan(scale, seed, lateral):
            phases = lateral_rng.uniform(0.0, 2 * np.pi, 10) if p.kind in LATERAL_PLAN else None
            truth = fly_one(jsbsim, holder.name, aircraft, p, modification.lags, lateral, phases, flown_states)
            craft = craft or _aircraft(aircraft.name, truth)
            columns = _measured(rng, lateral_rng, truth, craft)
            if lateral:
                inertia.append([float(np.median(truth["lateral"][k])) for k in ("Ixx", "Izz")])
            maneuvers.append(Maneuver(p.id, f"{p.id}.csv", p.kind, p.split))
            segments.append(columns)
    finally:
        holder.cleanup()
    manifest = {"S": craft.S, "cbar": craft.cbar, "b": craft.b, "Iyy": round(craft.iyy_empty, 1)}
    if lateral:
        manifest.update(zip(("Ixx", "Izz"), (round(float(v), 1) for v in np.median(inertia, axis=0))))
    source = {"simulator": "jsbsim", "aircraft": aircraft.name, "jsbsim_version": jsbsim.__version__,
              "modify": modification.digest()}
    name = f"JSBSim {aircraft.name} stall campaign (seed {seed}" + (", modified)" if modification else ")")
    return make_campaign(name, manifest, maneuvers, segments, extra={"source": source, "seed": seed,
                                                                     "scale": float(scale)})


def _aircraft(name: str, truth: dict) -> Aircraft:
    """The aircraft record the measurement chain reads (geometry, first mass, median pitch inertia)."""
    s, cbar, b = truth["geometry"]
    return Aircraft(name, f"JSBSim {name}", s, cbar, b, float(truth["mass"][0]), 0.0, float(np.median(truth["iyy"])),
                    0.0, 1.0, 0.0)


def _measured(rng: np.random.Generator, lateral_rng: np.random.Generator, truth: dict, craft: Aircraft) -> dict:
    """One maneuver's columns through the measurement chain; the lateral ones where ``truth`` has them."""
    from ..flight.lateral_measurement import measure_lateral, pitch_coupling
    lateral = truth.get("lateral")
    plain = {k: v for k, v in truth.items() if k not in ("geometry", "iyy", "t", "prop_induced_fps", "engine_cm",
                                                         "lateral")}
    columns = measure(rng, truth["t"], plain, None, 1.0, craft, record_qbar=lateral is not None)
    # the reduction removes the engine's pitching moment as it removes its thrust (known, as the thrust is)
    columns["Cm"] = columns["Cm"] - truth["engine_cm"]
    columns["prop_induced_fps"] = truth["prop_induced_fps"]
    if lateral is not None:
        measured = measure_lateral(lateral_rng, truth["t"], lateral, columns, craft.b, craft.S)
        # with p and r measured the pitch equation's inertial coupling is known too
        columns["Cm"] = columns["Cm"] + pitch_coupling(measured, lateral, columns, craft.S, craft.cbar)
        columns.update(measured)
    return columns
