"""The lateral maneuvers ``simulate --jsbsim NAME --lateral`` flies besides the stall plan, near and through the
stall, each trimmed wings level and flown open loop over the trim commands, with a pilot who holds the bank (the
aileron also takes ``BANK_GAIN`` per radian of bank error and ``ROLL_DAMPING`` per rad/s of roll rate: without
him most light aircraft are spirally unstable and a 40 s record ends inverted):

* ``aileron-doublet``: a slow pull toward the stall (to 80 % of the travel from trim to the nose-up stop) with
  aileron doublets at four points of it, the last near the stall;
* ``rudder-doublet``: the same pull with rudder doublets;
* ``sideslip``: a steady-heading sideslip: the rudder ramped to half its travel, held and released, the pilot's
  aileron holding the wings level, at a pull to half the travel;
* ``wind-up-turn``: a bank to 35 deg, then a slow pull to the stop (the stall in the turn), the recovery and the
  roll back;
* ``lateral-stall``: the quasi-steady stall with aileron and rudder multisines (random phases) throughout: the
  record a wing drop shows in.

Every input is a fraction of its control's travel (JSBSim's ``fcs/*-cmd-norm``); the signs are JSBSim's: a
positive aileron command rolls right, a positive rudder command yaws left.
"""
from __future__ import annotations

import numpy as np

# maneuvers of each lateral kind at scale 1, and their lengths [s]
LATERAL_PLAN = {"aileron-doublet": (6, 30.0), "rudder-doublet": (6, 30.0), "sideslip": (4, 35.0),
                "wind-up-turn": (4, 45.0), "lateral-stall": (6, 45.0)}
# the share of the travel from trim to the nose-up stop each kind pulls to
LATERAL_REACH = {"aileron-doublet": 0.8, "rudder-doublet": 0.8, "sideslip": 0.5, "wind-up-turn": 1.0,
                 "lateral-stall": 1.0}
BANK_GAIN = 0.8          # aileron travel per radian of bank error
ROLL_DAMPING = 0.25      # aileron travel per rad/s of roll rate
DOUBLET = 0.35           # a doublet's amplitude, of the travel
MULTISINE_HZ = (0.23, 0.41, 0.67, 0.97, 1.31)
MULTISINE = 0.06         # each sine's amplitude, of the travel


def ramp(s: np.ndarray, a: float, b: float) -> np.ndarray:
    """0 before ``a``, 1 after ``b``, linear between."""
    return np.clip((s - a) / max(b - a, 1e-9), 0.0, 1.0)


def _doublets(s: np.ndarray, starts) -> np.ndarray:
    """Unit doublets (one second each way) starting at ``starts``."""
    return sum(ramp(s, a, a + 0.2) - 2 * ramp(s, a + 1.0, a + 1.2) + ramp(s, a + 2.0, a + 2.2) for a in starts)


def _multisine(s: np.ndarray, phases: np.ndarray) -> np.ndarray:
    return MULTISINE * sum(np.sin(2 * np.pi * f * s + ph) for f, ph in zip(MULTISINE_HZ, phases))


def lateral_commands(kind: str, s: np.ndarray, pull: float, phases: np.ndarray) -> dict[str, np.ndarray]:
    """The commands of one lateral maneuver over the profile's time ``s`` (seconds at nominal pace): ``elevator``
    over trim (``pull`` the travel from trim to the stop: negative), ``aileron`` and ``rudder`` excitation, and the
    ``bank`` [rad] the pilot holds. ``phases``: ten random phases (the multisines')."""
    zero = np.zeros_like(s)
    reach = pull * LATERAL_REACH[kind]
    if kind in ("aileron-doublet", "rudder-doublet"):
        doublets = DOUBLET * _doublets(s, (3.0, 9.0, 15.0, 21.0))
        return {"elevator": reach * (ramp(s, 2, 22) - ramp(s, 25, 27)), "bank": zero,
                "aileron": doublets if kind == "aileron-doublet" else zero,
                "rudder": doublets if kind == "rudder-doublet" else zero}
    if kind == "sideslip":
        return {"elevator": reach * (ramp(s, 2, 8) - ramp(s, 28, 30)), "bank": zero, "aileron": zero,
                "rudder": 0.5 * (ramp(s, 4, 9) - ramp(s, 19, 24)) - 0.5 * (ramp(s, 24, 27) - ramp(s, 29, 31))}
    if kind == "wind-up-turn":
        return {"elevator": reach * (ramp(s, 8, 30) - ramp(s, 33, 35)), "aileron": zero, "rudder": zero,
                "bank": np.radians(35.0) * (ramp(s, 2, 6) - ramp(s, 36, 41))}
    if kind == "lateral-stall":
        return {"elevator": reach * (ramp(s, 3, 33) - ramp(s, 37, 39)), "bank": zero,
                "aileron": _multisine(s, phases[:5]), "rudder": _multisine(s, phases[5:])}
    raise ValueError(f"no lateral maneuver kind {kind!r}")


def pilot_aileron(excitation: float, bank: float, phi: float, p: float) -> float:
    """The aileron command of the frame: the excitation and the pilot holding ``bank``, within the travel."""
    return float(np.clip(excitation + BANK_GAIN * (bank - phi) - ROLL_DAMPING * p, -1.0, 1.0))
