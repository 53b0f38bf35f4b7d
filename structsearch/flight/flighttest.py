"""The flight-test campaign: the thesis' maneuver list (Table 4) and how the pilot flies each maneuver,
for the Citation II and for the twin-jet transport (same maneuver kinds, its own speeds and angles)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from . import aircraft as ac
from .aircraft import CITATION, Aircraft, cg_band
from .transport import TRANSPORT
from .aero import AeroModel
from .simulation import Condition, trim
from .flying import DT, SLOW_ERROR_STALL_GAIN, Flown, fly_batch, reconstruction_error
from .synthetic import smooth_noise
from ..data.errors import DeclarationError

# Quasi-random elevator corrections of the quasi-steady stalls, as flown by hand while bleeding off 1 kt/s
# (about 0.6 deg, band-limited to 1 Hz), and a gentle recovery. Their size sets how much C_m varies within a
# quasi-steady stall: the pitching moment of a trimmed, slowly decelerating aircraft is otherwise its pitch
# acceleration's noise, and with corrections of 0.003 rad at 0.3 Hz (which the alpha loop cancels) the final
# pitch model's worst validation maneuver had R^2 -0.06. With these the default campaign's C_m has validation
# R^2 0.78 pooled and 0.18 at the worst maneuver, thesis Table 11.1's 0.71 and 0.18, with the standard
# deviations still within a factor of 2 of the thesis' (results/thesis_stderr.md).
QS_WIGGLE_RAD = 0.010
QS_WIGGLE_HZ = 1.0
QS_RECOVERY_S = 8.0
# Dynamic stall: repeated entries around the stall-strip boundary, small enough to stay in the
# linear range of X0 (a1 ~ 70/rad) and fast enough (omega*tau1 ~ 1-2) to tell lag from delay
DYN_CENTRE = (0.19, 0.20)
DYN_AMPLITUDE = (0.02, 0.03)
DYN_FREQ_HZ = (0.3, 1.2)  # frequency sweep from the first to the second value
DYN_OSCILLATION_S = 45.0
# Each flight's centre of gravity: a narrow band inside the 276-286 in envelope, as loaded for the
# test flights ("the center of gravity is relatively constant", thesis Table 16: C_m,cg and C_m,K0
# correlate at -1.00); it sets how well C_m,cg can be told from C_m,K0.
FLOWN_CG_RANGE = (280.5 * ac.INCH, 282.0 * ac.INCH)
GAINS = (2.0, 1.5, 0.8)  # pilot PID on alpha: kp [-], ki [1/s], kd [s]
# Flights of a campaign with flight-level errors (``build_campaign(flights=N)``): consecutive maneuvers of one
# loading, about this many per flight when the number of flights is chosen for a plan (:func:`flights_for`); each
# flight shares a mass, cg, engine-model and vane-calibration error (:data:`.measurement.FLIGHT_ERROR_SD`).
MANEUVERS_PER_FLIGHT = 4


@dataclass(frozen=True)
class Procedures:
    """How one aircraft flies the maneuver kinds: airspeed ranges [m/s], angles of attack [rad], gains.

    The defaults are the Citation II's (thesis chapter 6); each range is drawn from uniformly.
    """

    aircraft: Aircraft = CITATION
    qs_speed: tuple[float, float] = (85.0, 95.0)
    qs_peak: tuple[float, float] = (0.24, 0.32)
    dyn_speed: tuple[float, float] = (82.0, 90.0)
    dyn_centre: tuple[float, float] = DYN_CENTRE
    dyn_amplitude: tuple[float, float] = DYN_AMPLITUDE
    dyn_freq_hz: tuple[float, float] = DYN_FREQ_HZ
    deep_centre: tuple[float, float] = (0.32, 0.35)
    deep_amplitude: tuple[float, float] = (0.025, 0.04)
    pullup_speed: tuple[float, float] = (95.0, 110.0)
    pushover_speed: tuple[float, float] = (80.0, 90.0)
    phugoid_speed: tuple[float, float] = (85.0, 95.0)
    gains: tuple[float, float, float] = GAINS
    fuel: tuple[float, float] = (1500.0, 450.0)   # [kg] at the first and last maneuver of the campaign
    flown_cg_range: tuple[float, float] | None = FLOWN_CG_RANGE  # None: one fixed cg, not recorded
    qs_wiggle: tuple[float, float] = (QS_WIGGLE_RAD, QS_WIGGLE_HZ)  # [rad], [Hz] of the quasi-steady corrections


# The transport stalls at about 95 m/s: entries at about 1.4 times that, the quasi-steady stalls taken
# only to 16-18 deg (alpha* = 15 deg), the dynamic stalls around alpha* at the frequencies where its
# lag (0.65 s) matters, a pilot with the higher gains a less agile aircraft needs.
TRANSPORT_PROCEDURES = Procedures(
    aircraft=TRANSPORT, qs_speed=(122.0, 135.0), qs_peak=(0.28, 0.31), dyn_speed=(118.0, 128.0),
    dyn_centre=(0.25, 0.27), dyn_amplitude=(0.03, 0.04), dyn_freq_hz=(0.2, 0.7), deep_centre=(0.29, 0.31),
    deep_amplitude=(0.025, 0.035), pullup_speed=(140.0, 160.0), pushover_speed=(118.0, 128.0),
    phugoid_speed=(122.0, 135.0), gains=(5.0, 3.5, 2.5), fuel=(9000.0, 5000.0), flown_cg_range=None,
    qs_wiggle=(0.003, 0.3))   # slow, small corrections: no flight data of the transport to match
PROCEDURES = {"citation": Procedures(), "transport": TRANSPORT_PROCEDURES}
DURATION = {"quasi-steady": 55.0, "dynamic": 50.0, "deep-dynamic": 50.0, "pullup": 25.0,
            "pushover": 25.0, "phugoid": 125.0}


@dataclass(frozen=True)
class PlannedManeuver:
    number: int
    kind: str
    split: str
    fl_band: tuple[int, int]

    @property
    def id(self) -> str:
        return f"m{self.number:02d}"


def thesis_plan(extras: bool = False) -> list[PlannedManeuver]:
    """46 maneuvers of thesis Table 4 ("This work"), optionally 11 pullup/pushover/phugoid maneuvers."""
    validation = {7, 12, 16, 22, 23, 25, 38, 39, 46}
    plan = []
    for n in range(1, 47):
        if n <= 34:
            kind = "quasi-steady"
            band = (80, 110) if n <= 2 else (110, 150) if n <= 6 else (150, 200)
        elif n <= 39:
            kind, band = "dynamic", (150, 200)
        else:
            kind, band = "deep-dynamic", (150, 200)
        plan.append(PlannedManeuver(n, kind, "validation" if n in validation else "train", band))
    if extras:
        kinds = ["pullup"] * 5 + ["pushover"] * 3 + ["phugoid"] * 3
        held_out = {51, 54, 57}
        for i, kind in enumerate(kinds):
            n = 47 + i
            plan.append(PlannedManeuver(n, kind, "validation" if n in held_out else "train", (150, 200)))
    return plan


def scaled_plan(plan: list[PlannedManeuver], scale: float) -> list[PlannedManeuver]:
    """Keep about ``scale`` of each kind's maneuvers, at least one per kind and split present."""
    if not 0 < scale <= 1:
        raise ValueError("scale must lie in (0, 1]")
    keep = []
    for kind in dict.fromkeys(p.kind for p in plan):
        for split in ("train", "validation"):
            group = [p for p in plan if p.kind == kind and p.split == split]
            if group:
                count = max(1, int(round(scale * len(group))))
                idx = np.unique(np.linspace(0, len(group) - 1, count).round().astype(int))
                keep += [group[i] for i in idx]
    return sorted(keep, key=lambda p: p.number)


def loading_of(p: PlannedManeuver) -> int:
    """The loading (centre of gravity) a maneuver is flown at: thesis maneuvers 1-17, 18-34 and 35-46 and the extras
    were flown at one loading each."""
    return 0 if p.number <= 17 else 1 if p.number <= 34 else 2 if p.number <= 46 else 3


def flights_for(plan: list[PlannedManeuver]) -> int:
    """A realistic number of flights for ``plan``: about :data:`MANEUVERS_PER_FLIGHT` maneuvers each, at least one
    per loading."""
    return max(len({loading_of(p) for p in plan}), int(round(len(plan) / MANEUVERS_PER_FLIGHT)))


def assign_flights(plan: list[PlannedManeuver], n_flights: int) -> list[str]:
    """Each planned maneuver's flight, ``F1`` to ``FN`` in the order flown: consecutive maneuvers (training and
    validation mixed, as the plan numbers them), never across a change of loading; the flights are shared out
    over the loadings in proportion to their maneuvers (at least one each, D'Hondt)."""
    loadings = sorted({loading_of(p) for p in plan})
    if not len(loadings) <= n_flights <= len(plan):
        raise DeclarationError(f"flights: {n_flights} flights for {len(plan)} maneuvers flown at {len(loadings)} "
                               f"loadings; choose between {len(loadings)} (one flight per loading) and {len(plan)} "
                               "(one maneuver per flight)")
    members = {g: [i for i, p in enumerate(plan) if loading_of(p) == g] for g in loadings}
    share = {g: 1 for g in loadings}
    for _ in range(n_flights - len(loadings)):
        open_ = [g for g in loadings if share[g] < len(members[g])]
        g = max(open_, key=lambda g: (len(members[g]) / (share[g] + 1), -g))
        share[g] += 1
    labels = [""] * len(plan)
    number = 0
    for g in loadings:
        for chunk in np.array_split(np.array(members[g]), share[g]):
            number += 1
            for i in chunk:
                labels[int(i)] = f"F{number}"
    return labels


def flight_errors(seed: int, flights: list[str]) -> dict:
    """The shared errors of each flight (:class:`.measurement.FlightErrors`), drawn from a stream of their own in the
    order the flights are first flown: the same seed, the same errors."""
    from .measurement import FlightErrors
    rng = np.random.default_rng([seed, 3])
    return {f: FlightErrors.draw(rng) for f in dict.fromkeys(flights)}


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _quasi_steady(rng: np.random.Generator, t: np.ndarray, n: int, trimmed, proc: Procedures):
    """A quasi-steady approach: alpha raised slowly to its peak, held, then recovered; a small elevator wiggle.
    (speed, trim, alpha reference, throttle, elevator beyond the loop's), drawn from ``rng`` in this order."""
    V = rng.uniform(*proc.qs_speed)
    tr = trimmed(V)
    peak = rng.uniform(*proc.qs_peak)
    t_up = rng.uniform(36.0, 42.0)
    alpha_ref = tr.alpha + (peak - tr.alpha) * _smoothstep(t / t_up)
    recover = t_up + rng.uniform(2.0, 4.0)
    alpha_ref = np.where(t < recover, alpha_ref,
                         0.06 + (peak - 0.06) * (1 - _smoothstep((t - recover) / QS_RECOVERY_S)))
    throttle = np.where(t < recover, 0.45 * tr.throttle, 0.6)
    de_extra = proc.qs_wiggle[0] * smooth_noise(rng, n, DT, proc.qs_wiggle[1])
    return V, tr, alpha_ref, throttle, de_extra


def _dynamic(rng: np.random.Generator, t: np.ndarray, wiggle: np.ndarray, trimmed, proc: Procedures, deep: bool):
    """A dynamic (or deep) stall, entered like a stall approach (power reduced, alpha raised as the speed bleeds
    off), then an oscillation of alpha about its centre: a sweep, or one frequency when deep."""
    V = rng.uniform(*proc.dyn_speed)
    tr = trimmed(V)
    centre = rng.uniform(*proc.deep_centre) if deep else rng.uniform(*proc.dyn_centre)
    amplitude = rng.uniform(*proc.deep_amplitude) if deep else rng.uniform(*proc.dyn_amplitude)
    f_lo, f_hi = proc.dyn_freq_hz
    f0, f1 = rng.uniform(f_lo, f_lo + 0.2), rng.uniform(f_hi - 0.2, f_hi)
    t_up, t_osc = 18.0, 21.0
    t_end = t_osc + (DYN_OSCILLATION_S if not deep else 23.0)
    alpha_ref = tr.alpha + (centre - tr.alpha) * _smoothstep(t / t_up)
    osc = (t >= t_osc) & (t < t_end)
    if deep:
        phase = 2 * np.pi * f0 * (t - t_osc)
    else:  # linear sweep: a pilot speeding up the elevator oscillation
        tau = np.clip(t - t_osc, 0, t_end - t_osc)
        phase = 2 * np.pi * (f0 * tau + 0.5 * (f1 - f0) * tau ** 2 / (t_end - t_osc))
    alpha_ref = alpha_ref + np.where(osc, amplitude * np.sin(phase), 0.0)
    alpha_ref = np.where(t < t_end, alpha_ref, 0.06 + (centre - 0.06) * (1 - _smoothstep((t - t_end) / 3.0)))
    throttle = np.where(t < t_end, 0.3 * tr.throttle, 0.6)
    # sequential steps on the elevator during the approach, then small quasi-random inputs
    de_extra = 0.004 * wiggle + np.where((t > 4.0) & (t < 5.5), 0.015, 0.0) \
        - np.where((t > 6.0) & (t < 7.5), 0.015, 0.0)
    return V, tr, alpha_ref, throttle, de_extra


def fly(model: AeroModel, p: PlannedManeuver, rng: np.random.Generator, mass: float, x_cg: float,
        proc: Procedures = Procedures()) -> Flown:
    """Reference profiles for one maneuver (pilot-like, seeded), flown as ``proc`` says."""
    duration = DURATION[p.kind] + (DYN_OSCILLATION_S - 23.0 if p.kind == "dynamic" else 0.0)
    n = int(round(duration / DT))
    t = np.arange(n) * DT
    h = ac.flight_level_altitude(rng.uniform(*p.fl_band))
    wiggle = smooth_noise(rng, n, DT, 1.5)
    gains = proc.gains
    craft = proc.aircraft

    def trimmed(V):
        return trim(model, Condition(mass, x_cg, h, V), aircraft=craft)

    if p.kind == "quasi-steady":
        V, tr, alpha_ref, throttle, de_extra = _quasi_steady(rng, t, n, trimmed, proc)
    elif p.kind in ("dynamic", "deep-dynamic"):
        V, tr, alpha_ref, throttle, de_extra = _dynamic(rng, t, wiggle, trimmed, proc, p.kind == "deep-dynamic")
    elif p.kind in ("pullup", "pushover"):
        V = rng.uniform(*proc.pullup_speed) if p.kind == "pullup" else rng.uniform(*proc.pushover_speed)
        tr = trimmed(V)
        target = tr.alpha + (0.04 if p.kind == "pullup" else -0.07)
        alpha_ref = tr.alpha + (target - tr.alpha) * _smoothstep(t / 2.0)
        throttle = np.full(n, tr.throttle if p.kind == "pullup" else 0.2 * tr.throttle)
        de_extra = 0.003 * wiggle
        theta0 = np.deg2rad(-10.0 if p.kind == "pullup" else 25.0)
        return Flown(Condition(mass, x_cg, h, V), theta0, V, alpha_ref, de_extra, throttle, gains,
                     tr.de, tr.alpha)
    elif p.kind == "phugoid":
        V = rng.uniform(*proc.phugoid_speed)
        tr = trimmed(V)
        alpha_ref = np.full(n, tr.alpha)
        throttle = np.full(n, tr.throttle)
        de_extra = np.zeros(n)
        # off-trim airspeed, elevator released at its trim position
        return Flown(Condition(mass, x_cg, h, V), tr.alpha, V * rng.uniform(1.08, 1.14), alpha_ref, de_extra,
                     throttle, (0.0, 0.0, 0.0), tr.de, tr.alpha)
    else:
        raise ValueError(f"no flying procedure for maneuver kind {p.kind!r}")
    return Flown(Condition(mass, x_cg, h, V), tr.alpha, V, alpha_ref, de_extra, throttle, gains, tr.de, tr.alpha)


def simulate_campaign(plan: list[PlannedManeuver], model: AeroModel, seed: int = 0, slow_errors: float = 1.0,
                      proc: Procedures = Procedures(), anomaly=None, sensor_errors=None, flights=None):
    """Fly every planned maneuver and measure it; returns (plan, list of column dicts) in plan order.

    ``slow_errors`` scales the slow reconstruction errors (1: realistic, 0: a laboratory-clean
    campaign with sensor noise, buffet and biases only, for tests of mechanisms). ``anomaly``
    (:mod:`.anomalies`; ``model`` already flies it when it acts on the aerodynamics) adds the truth
    alpha as the column ``alpha_true`` and, when it lags the alpha vane, lags it in the measurement.
    With ``sensor_errors`` (:class:`.raw.SensorErrors`) the maneuvers are recorded as raw channels
    (:func:`.raw.raw_channels`) instead of measured coefficients. ``flights`` (each maneuver's flight, as
    :func:`assign_flights` gives) adds the errors each flight's maneuvers share (:func:`flight_errors`); the
    flown profiles and every other error stay those of the same seed without them.
    """
    from .measurement import measure
    rng = np.random.default_rng(seed)
    # fuel burns down over the test sequence; each flight has its own centre of gravity
    craft = proc.aircraft
    fuel = np.linspace(*proc.fuel, len(plan))
    cg_by_flight = {k: (rng.uniform(*proc.flown_cg_range) if proc.flown_cg_range else np.nan) for k in range(4)}
    flown = []
    for i, p in enumerate(plan):
        mass = craft.empty_mass + craft.crew_mass + fuel[i]
        flown.append(fly(model, p, rng, mass, cg_by_flight[loading_of(p)], proc))
    shared = flight_errors(seed, list(flights)) if flights is not None else None
    # a stream of its own, so that the flown profiles and sensor errors do not depend on it
    error_rng = np.random.default_rng([seed, 1])
    errors = [reconstruction_error(error_rng, len(f.alpha_ref), slow_errors) for f in flown]
    results: list[dict | None] = [None] * len(plan)
    traj = fly_batch(model, flown, craft)
    # measured in order of duration, then plan order: the order the noise streams have always been drawn in
    for i in sorted(range(len(flown)), key=lambda i: (len(flown[i].alpha_ref), i)):
        duration = len(flown[i].alpha_ref)
        truth = {name: getattr(traj, name)[:duration, i] for name in
                 ("V", "alpha", "q", "theta", "h", "de", "thrust", "qbar", "mass", "x_cg", "CL", "CD", "Cm",
                  "q_dot")}
        # a withheld second state is recorded as attached flow
        symbols = ("X_ss", "X_w") if craft.name == "citation" else tuple(traj.X)
        truth["states"] = {sym: traj.X[sym][:duration, i] if sym in traj.X else np.ones(duration) for sym in symbols}
        t = traj.t[:duration]
        if sensor_errors is not None:
            from .raw import raw_channels
            columns = raw_channels(rng, t, truth, sensor_errors, craft)
        else:
            columns = measure(rng, t, truth, errors[i], SLOW_ERROR_STALL_GAIN, craft,
                              vane_lag_s=getattr(anomaly, "vane_lag_s", 0.0), record_alpha=anomaly is not None,
                              flight=None if shared is None else shared[flights[i]])
        results[i] = _cut(plan[i], columns)
    return results


def _check_nominal(anomaly: bool, raw: bool, flights: int) -> None:
    if anomaly or raw or flights:
        what = "an anomaly" if anomaly else "raw channels" if raw else "flights"
        raise DeclarationError(f"nominal maneuvers cannot be combined with {what}: the global model is fitted "
                               "on reduced coefficients of one truth, flown without flight-shared errors")


def _with_nominal(maneuvers: list, segments: list, model: AeroModel, seed: int, scale: float, slow_errors: float,
                  proc: Procedures) -> tuple[list, list]:
    """The stall maneuvers followed by the nominal ones (:mod:`.nominal`), every one with its air data."""
    from ..data.campaign import Maneuver
    from .nominal import nominal_plan, simulate_nominal, with_air_data
    plan = nominal_plan(scale)
    flown = simulate_nominal(plan, model, seed, slow_errors, proc.aircraft, proc.fuel, proc.flown_cg_range)
    segments = [with_air_data(c) for c in segments + flown]
    return maneuvers + [Maneuver(p.id, f"{p.id}.csv", p.kind, p.split) for p in plan], segments


def _cut(p: PlannedManeuver, columns: dict) -> dict:
    """Pullups and pushovers end where the pilot recovers (pitch attitude limit)."""
    if p.kind not in ("pullup", "pushover"):
        return columns
    theta = np.rad2deg(columns["theta"])
    over = np.flatnonzero(theta >= 30.0) if p.kind == "pullup" else np.flatnonzero(theta <= -20.0)
    end = int(over[0]) if over.size and over[0] > 500 else len(theta)
    return {k: v[:end] for k, v in columns.items()}


def _chosen_anomaly(anomaly: str | None, aircraft: str, withhold: tuple):
    """The anomaly named ``anomaly`` (None: none), refused for another aircraft or beside withheld effects."""
    if anomaly is None:
        return None
    from .anomalies import anomaly_named
    chosen = anomaly_named(anomaly)
    if aircraft != "citation":
        raise DeclarationError(f"anomaly {anomaly!r}: anomalies are declared for the Citation II only, "
                               f"not the {aircraft}")
    if withhold:
        raise DeclarationError(f"anomaly {anomaly!r} cannot be combined with withheld effects "
                               f"({', '.join(withhold)}): a campaign tests one departure from the final model")
    return chosen


def _manifest_keys(seed, scale, extras, truth: str, withhold: tuple, slow_errors, aircraft: str, chosen,
                   flights: int | None, cg_spread, cg_moment: str, sensor_errors) -> dict:
    """The free keys of a simulated campaign's manifest; a key a default leaves unsaid is absent, so a campaign
    simulated before the key existed reads the same."""
    extra = {"seed": int(seed), "scale": float(scale), "extras": bool(extras), "truth": truth,
             "withheld": ",".join(withhold) or "none", "slow_errors": float(slow_errors)}
    if aircraft != "citation":  # campaigns written before the second aircraft carry no such key
        extra["simulated_aircraft"] = aircraft
    if chosen is not None:  # nor do campaigns without an anomaly
        extra["anomaly"] = chosen.name
    if flights is not None:  # nor do campaigns without flights
        extra["flights"] = flights
    if cg_spread is not None:   # nor do campaigns flown in the default cg band
        extra["cg_spread"] = float(cg_spread)
    if cg_moment != "thesis":
        extra["cg_moment"] = cg_moment
    if sensor_errors is not None:
        extra.pop("slow_errors")
        extra.update(sensor_errors.manifest(), format="raw")
    return extra


def build_campaign(seed: int = 0, withhold=(), scale: float = 1.0, extras: bool = False,
                   slow_errors: float = 1.0, aircraft: str = "citation", anomaly: str | None = None,
                   raw: bool = False, flights: int = 0, nominal: bool = False, cg_spread: float | None = None,
                   cg_moment: str = "thesis"):
    """The simulated flight-test campaign (thesis Table 4) of ``aircraft`` (``citation`` or ``transport``),
    ready for :func:`write_campaign`.

    ``slow_errors`` scales the slow reconstruction errors (see :func:`simulate_campaign`). ``anomaly``
    (a name of :data:`.anomalies.ANOMALIES`, Citation only, not with ``withhold``) flies a truth with an
    effect outside the diagnosis' library; the same seed flies the same profiles and draws the same
    errors as without it. Such a campaign also carries the truth alpha (``alpha_true``) and its manifest
    the key ``anomaly``. ``raw`` records the raw channels of docs/interfaces.md 5.2 instead (``format = "raw"``,
    the injected sensor errors as ``injected_*`` keys; no slow reconstruction errors: there is no
    reconstruction yet).

    ``flights`` = N > 0 groups the maneuvers into N flights (:func:`assign_flights`; each maneuver's ``flight`` is
    recorded) whose maneuvers share a mass, cg, engine-model and vane-calibration error on top of the per-maneuver
    ones (:data:`.measurement.FLIGHT_ERROR_SD`; the truth columns ``alpha_true``, ``mass_true``, ``x_cg_true`` and
    ``CT_true`` are added, the manifest gets ``flights = N``). 0 (the default): no flights, and the campaign is the
    one simulated before flights existed, bit for bit.

    ``nominal``: nominal (attached-flow) maneuvers across the envelope too (:mod:`.nominal`; ``kind = "nominal"``
    in the manifest, after the stall maneuvers), flown with the truth's envelope terms (:mod:`.envelope`, zero
    wherever a stall maneuver flies), and every maneuver carries the air data ``Mach`` and ``qbar``. Citation II
    only, not with an anomaly, raw channels or flights.
    ``cg_spread`` [m]: each loading's cg drawn from a band this wide (:func:`.aircraft.cg_band`; the same draws);
    ``cg_moment`` (:data:`.aero.CG_MOMENTS`): how the truth's C_m depends on the cg. Both go to the manifest."""
    from .aero import truth_model
    from ..data.campaign import Maneuver, make_campaign
    withhold = tuple(withhold)
    chosen = _chosen_anomaly(anomaly, aircraft, withhold)
    if nominal:
        _check_nominal(chosen is not None, raw, flights)
    model = truth_model(withhold, aircraft, chosen if chosen is not None and chosen.flies else None,
                        envelope=nominal, cg_moment=cg_moment)
    proc = PROCEDURES[aircraft]
    if cg_spread is not None:
        proc = dataclasses.replace(proc, flown_cg_range=cg_band(cg_spread, proc.aircraft, proc.flown_cg_range))
    plan = scaled_plan(thesis_plan(extras), scale)
    if flights and raw:
        raise DeclarationError("flights: flight-level errors are errors of the reduced coefficients; a raw campaign "
                               "records the channels before any reduction (its sensor errors are per installation)")
    labels = assign_flights(plan, int(flights)) if flights else None
    sensor_errors = None
    if raw:
        from .raw import SensorErrors
        sensor_errors = SensorErrors.draw(np.random.default_rng([seed, 2]))
    segments = simulate_campaign(plan, model, seed, slow_errors, proc, chosen, sensor_errors, labels)
    maneuvers = [Maneuver(p.id, f"{p.id}.csv", p.kind, p.split, None if labels is None else labels[i])
                 for i, p in enumerate(plan)]
    if nominal:
        maneuvers, segments = _with_nominal(maneuvers, segments, model, seed, scale, slow_errors, proc)
    extra = _manifest_keys(seed, scale, extras, model.name, withhold, slow_errors, aircraft, chosen,
                           int(flights) if labels is not None else None, cg_spread, cg_moment, sensor_errors)
    name = f"simulated {proc.aircraft.label} stall {'and nominal ' if nominal else ''}campaign (seed {seed}" \
        + (f", anomaly {chosen.name})" if chosen is not None else ")")
    return make_campaign(name, _aircraft_manifest(proc, raw), maneuvers, segments, extra)


def _aircraft_manifest(proc: Procedures, raw: bool) -> dict:
    """The aircraft data of docs/interfaces.md 5.1 the simulator knows: pitch inertia, the cg envelope (and, for
    raw channels, where the accelerometer sits; the simulated thrust acts through the cg)."""
    manifest = proc.aircraft.manifest(proc.aircraft.empty_mass + proc.aircraft.crew_mass + float(np.mean(proc.fuel)))
    if raw:
        from .raw import ACCELEROMETER
        manifest.update(accelerometer=ACCELEROMETER, thrust_line_z=0.0)
    return manifest
