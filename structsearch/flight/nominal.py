"""Nominal (attached-flow) maneuvers across the Citation II's envelope (``simulate --nominal``): what the pilot
flies and where.

Four inputs, each at six conditions (three altitudes, a slow and a fast equivalent airspeed), so that Mach number
and dynamic pressure span the envelope (about Mach 0.2-0.6, 3-10 kPa) where the stall maneuvers stay below Mach
0.36 and 4.8 kPa:

* ``doublet``: the elevator one pulse up, one down (stick fixed otherwise);
* ``3211``: pulses of 3, 2, 1 and 1 time units of alternating sign (stick fixed otherwise);
* ``speed``: a change of airspeed by about 15 %, the pilot holding the angle of attack the new speed trims at while
  the throttle moves to the new trim setting;
* ``altitude``: a climb (or, from a fast condition, a descent) on a throttle change, the angle of attack held.

Each maneuver is written with ``kind = "nominal"`` (docs/interfaces.md 7.5); its input is the end of its id
(``n03-speed``). Nothing here draws from the stall maneuvers' random streams.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import aircraft as ac
from ..data.reduction import air_data
from .aero import AeroModel
from .flying import DT, SLOW_ERROR_STALL_GAIN, Flown, fly_batch, reconstruction_error
from .measurement import measure
from .simulation import Condition, trim
from .synthetic import smooth_noise

NOMINAL_KIND = "nominal"
INPUTS = ("doublet", "3211", "speed", "altitude")
DURATION_S = {"doublet": 20.0, "3211": 20.0, "speed": 40.0, "altitude": 40.0}
# The conditions: flight levels and equivalent airspeeds [m/s] (slow, fast), each drawn within a small band
FLIGHT_LEVELS = (60, 150, 240)
EAS = (80.0, 125.0)
FL_BAND = 10
EAS_BAND = 4.0
# The validation maneuvers: per input, two conditions (index level * 2 + speed), a slow and a fast one at different
# levels, so that every input and every level is validated somewhere
VALIDATION_CONDITIONS = {"doublet": (1, 4), "3211": (3, 0), "speed": (5, 2), "altitude": (1, 4)}
# Elevator pulses [rad] at a dynamic pressure of 3.5 kPa, smaller in proportion above it (the same load factor)
PULSE_RAD = (0.02, 0.03)
PULSE_QBAR_PA = 3500.0
WIGGLE_RAD = 0.002   # small quasi-random elevator inputs on top, as flown by hand
GAINS = (2.0, 1.5, 0.8)  # the alpha-holding pilot of the speed and altitude changes


@dataclass(frozen=True)
class NominalManeuver:
    """One planned nominal maneuver: its input, split and condition (index into levels x speeds)."""

    number: int
    input: str
    split: str
    condition: int

    @property
    def id(self) -> str:
        return f"n{self.number:02d}-{self.input}"

    @property
    def kind(self) -> str:
        return NOMINAL_KIND

    @property
    def flight_level(self) -> int:
        return FLIGHT_LEVELS[self.condition // 2]

    @property
    def eas(self) -> float:
        return EAS[self.condition % 2]


def nominal_plan(scale: float = 1.0) -> list[NominalManeuver]:
    """24 maneuvers (every input at every condition; 8 for validation), or about ``scale`` of each input's
    training and validation maneuvers (at least one of each)."""
    if not 0 < scale <= 1:
        raise ValueError("scale must lie in (0, 1]")
    plan, number = [], 0
    for condition in range(len(FLIGHT_LEVELS) * len(EAS)):
        for name in INPUTS:
            number += 1
            split = "validation" if condition in VALIDATION_CONDITIONS[name] else "train"
            plan.append(NominalManeuver(number, name, split, condition))
    keep = []
    for name in INPUTS:
        for split in ("train", "validation"):
            group = [p for p in plan if p.input == name and p.split == split]
            count = max(1, int(round(scale * len(group))))
            keep += [group[i] for i in np.unique(np.linspace(0, len(group) - 1, count).round().astype(int))]
    return sorted(keep, key=lambda p: p.number)


def pulses(t: np.ndarray, start: float, unit: float, widths: tuple[int, ...], amplitude: float) -> np.ndarray:
    """Elevator pulses of ``widths`` time units each (of ``unit`` s), alternating in sign from +``amplitude``."""
    out = np.zeros_like(t)
    edge = start
    for i, w in enumerate(widths):
        out[(t >= edge) & (t < edge + w * unit)] = amplitude * (-1) ** i
        edge += w * unit
    return out


def fly_nominal(model: AeroModel, p: NominalManeuver, rng: np.random.Generator, mass: float, x_cg: float,
                dt: float, aircraft: ac.Aircraft = ac.CITATION) -> tuple:
    """The profiles of one nominal maneuver, in the field order of :class:`.flighttest.Flown`: condition, theta0,
    V0, alpha_ref, elevator input, throttle, pilot gains, trim elevator, alpha0."""
    n = int(round(DURATION_S[p.input] / dt))
    t = np.arange(n) * dt
    h = ac.flight_level_altitude(p.flight_level + rng.uniform(-FL_BAND, FL_BAND))
    V = (p.eas + rng.uniform(-EAS_BAND, EAS_BAND)) / np.sqrt(ac.density(h) / ac.RHO0)
    cond = Condition(mass, x_cg, h, V)
    tr = trim(model, cond, aircraft=aircraft)
    wiggle = WIGGLE_RAD * smooth_noise(rng, n, dt, 1.0)
    qbar = 0.5 * ac.density(h) * V * V
    amplitude = rng.uniform(*PULSE_RAD) * min(1.0, PULSE_QBAR_PA / qbar) * rng.choice((-1.0, 1.0))
    fast = p.condition % 2 == 1
    if p.input in ("doublet", "3211"):
        widths, unit = ((1, 1), rng.uniform(0.8, 1.2)) if p.input == "doublet" else ((3, 2, 1, 1),
                                                                                       rng.uniform(0.4, 0.6))
        de_extra = pulses(t, 2.0, unit, widths, amplitude) + wiggle
        return (cond, tr.alpha, V, np.full(n, tr.alpha), de_extra, np.full(n, tr.throttle), (0.0, 0.0, 0.0),
                tr.de, tr.alpha)
    ramp = np.clip((t - 5.0) / 10.0, 0.0, 1.0)
    ramp = ramp * ramp * (3 - 2 * ramp)
    if p.input == "speed":
        target = trim(model, Condition(mass, x_cg, h, V * (0.85 if fast else 1.15)), aircraft=aircraft)
        alpha_ref = tr.alpha + (target.alpha - tr.alpha) * ramp
        throttle = tr.throttle + (target.throttle - tr.throttle) * ramp
    else:
        alpha_ref = np.full(n, tr.alpha)
        step = -0.25 if fast else 0.3
        throttle = np.clip(tr.throttle + step * ramp, 0.05, 1.0)
    return cond, tr.alpha, V, alpha_ref, wiggle, throttle, GAINS, tr.de, tr.alpha


def simulate_nominal(plan: list[NominalManeuver], model: AeroModel, seed: int = 0, slow_errors: float = 1.0,
                     aircraft: ac.Aircraft = ac.CITATION, fuel: tuple[float, float] = (1500.0, 450.0),
                     cg_range: tuple[float, float] | None = None) -> list[dict]:
    """Fly and measure the nominal maneuvers ``plan`` of ``aircraft`` (its procedures' ``fuel`` at the first and last
    maneuver and the range each flight's cg is drawn from; None: one cg nobody recorded, NaN), one loading per flight
    level; returns their column dicts in plan order. Their random streams are their own: the stall maneuvers of the
    same seed are flown and measured as without them."""
    rng = np.random.default_rng([seed, 4])
    fuel = np.linspace(*fuel, len(plan))
    # one flight per flight level, each at its own loading (a single cg would leave C_m's cg term unplaced)
    levels = sorted({p.flight_level for p in plan})
    x_cg = {fl: rng.uniform(*cg_range) if cg_range else np.nan for fl in levels}
    mass = aircraft.empty_mass + aircraft.crew_mass + fuel
    flown = [Flown(*fly_nominal(model, p, rng, mass[i], x_cg[p.flight_level], DT, aircraft))
             for i, p in enumerate(plan)]
    error_rng = np.random.default_rng([seed, 5])
    errors = [reconstruction_error(error_rng, len(f.alpha_ref), slow_errors) for f in flown]
    traj = fly_batch(model, flown, aircraft)
    out = []
    for i, f in enumerate(flown):
        duration = len(f.alpha_ref)
        truth = {name: getattr(traj, name)[:duration, i] for name in
                 ("V", "alpha", "q", "theta", "h", "de", "thrust", "qbar", "mass", "x_cg", "CL", "CD", "Cm",
                  "q_dot")}
        truth["states"] = {sym: traj.X[sym][:duration, i] for sym in ("X_ss", "X_w")}
        out.append(measure(rng, traj.t[:duration], truth, errors[i], SLOW_ERROR_STALL_GAIN, aircraft))
    return out


def with_air_data(columns: dict) -> dict:
    """A maneuver's columns with ``Mach`` and ``qbar`` [Pa] from its recorded airspeed and altitude (ISA), as the
    air-data computer gives them: what the attached-flow terms of a global model read."""
    mach, qbar = air_data(columns["V"], columns["h"])
    return {**columns, "Mach": mach, "qbar": qbar}
