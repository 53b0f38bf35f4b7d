"""A forward replay with its uncertainty band (issue 29): the maneuver replayed through the simulator
(:func:`structsearch.flight.replay.replay`) with the estimated lift, drag and pitch models, and again with each of
``samples`` parameter vectors drawn from the joint fit's covariance. The pointwise equal-tailed interval of the
sampled replays is the replay's confidence band: the spread of the simulated states that the parameters'
uncertainty alone causes.

Why sampling and not the delta method: a replay integrates the equations of motion over several seconds, so the
states depend on the parameters through the whole trajectory (and a stall through the separation states'
thresholds); drawing and replaying needs no sensitivity equations and no linearisation. A joint fit is needed
because the replay flies all three coefficients, whose estimates are correlated through the shared separation
parameters: only the joint covariance draws them together.

What the band does not hold: the aircraft's own unmodelled forcing (turbulence, buffet, the coefficients'
coloured residual), which an open-loop replay cannot be given as it was flown; the band covers the replay the
model would give with the true parameters, not the measured trajectory. A draw whose replay is not finite
(diverged: a state not finite or alpha 20 deg from the measurement) is left out of the interval and counted; with more
than a tenth of the draws diverged the band is null.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..data.errors import DeclarationError
from ..data.flightdata import FlightData
from ..engine.bands import parameter_draws
from ..fitting.models import build_model, model_with_lift
from .aero import AeroModel
from .replay import STATES, divergence, replay

DEFAULT_WINDOW_S = 5.0
# The share of draws that may diverge (a state not finite, alpha 20 deg off: flight.replay.divergence) before the
# band is null
MAX_DIVERGED = 0.1


@dataclass(frozen=True)
class ReplayBand:
    """One maneuver's replay at the estimate and the pointwise interval of the sampled replays, per state."""

    maneuver: str
    t: np.ndarray
    measured: Mapping[str, np.ndarray]
    estimate: Mapping[str, np.ndarray]
    low: Mapping[str, np.ndarray]
    high: Mapping[str, np.ndarray]
    level: float
    draws: int
    diverged: int             # draws whose replay was not finite (left out of the interval)
    seed: int
    window_s: float

    def to_dict(self) -> dict:
        return {"maneuver": self.maneuver, "level": self.level, "draws": self.draws, "diverged": self.diverged,
                "seed": self.seed, "window_s": self.window_s, "method": "parameter sampling (joint covariance)",
                "t": self.t.tolist(),
                "states": {s: {"measured": self.measured[s].tolist(), "estimate": self.estimate[s].tolist(),
                               "confidence_low": self.low[s].tolist(), "confidence_high": self.high[s].tolist()}
                           for s in STATES}}


def joint_aero(joint, params: Mapping[str, float]) -> AeroModel:
    """The lift, drag and pitch structures of a joint fit as one simulator model at ``params``."""
    by = {c.coefficient: c for c in joint.candidates}
    if set(by) != {"CL", "CD", "Cm"}:
        raise DeclarationError(f"a replay flies C_L, C_D and C_m: the joint fit {joint.name} has "
                               f"{', '.join(sorted(by))} only")
    return AeroModel(build_model(by["CL"]), model_with_lift(by["CD"], {}), model_with_lift(by["Cm"], {}),
                     dict(params), name=joint.name)


def deepest_maneuver(data: FlightData) -> int:
    """The maneuver that reaches the highest angle of attack (the one whose replay tells most about the stall)."""
    return int(np.argmax([np.max(data["alpha"][sl]) for sl in data.segment_slices()]))


def replay_band(joint, data: FlightData, maneuver: str | None = None, samples: int = 100, seed: int = 0,
                level: float = 0.95, window_s: float = DEFAULT_WINDOW_S) -> ReplayBand:
    """Replay ``maneuver`` of ``data`` (default: the one that flies deepest) with the joint estimate and with
    ``samples`` draws from the joint covariance (module docstring)."""
    if maneuver is None:
        index = deepest_maneuver(data)
    elif maneuver in data.names:
        index = list(data.names).index(maneuver)
    else:
        raise DeclarationError(f"--replay-maneuver {maneuver!r}: no such maneuver (have "
                               f"{', '.join(list(data.names)[:8])}{', ...' if len(data.names) > 8 else ''})")
    one = data.select([index])
    est = joint.result.estimates
    at_estimate = replay(one, joint_aero(joint, est.params), window_s)[0]
    runs = []
    for d in parameter_draws(est.values, est.covariance, samples, seed):
        try:
            with np.errstate(all="ignore"):
                run = replay(one, joint_aero(joint, dict(zip(est.names, d))), window_s)[0]
        except (DeclarationError, FloatingPointError, ValueError):
            continue   # a draw the simulator cannot fly (a state kind's parameter out of its domain): diverged
        runs.append(run)
    if divergence(at_estimate) is not None:
        raise DeclarationError(f"the replay of {at_estimate.name} at the joint estimate diverges "
                               f"({divergence(at_estimate)[1]} at {divergence(at_estimate)[0]:.1f} s): it has no band")
    finite = [r for r in runs if divergence(r) is None]
    tail = 100.0 * (0.5 - level / 2.0)
    low, high = {}, {}
    # an interval over the draws that stayed in the flight is conditional on staying there: with more than a tenth
    # of the draws gone it would not be the parameters' band, so it is null (and says how many diverged)
    usable = len(finite) >= 2 and samples - len(finite) <= MAX_DIVERGED * samples
    for s in STATES:
        if usable:
            low[s], high[s] = np.percentile(np.array([r.simulated[s] for r in finite]), [tail, 100.0 - tail], axis=0)
        else:
            low[s] = high[s] = np.full(len(at_estimate.t), np.nan)
    return ReplayBand(at_estimate.name, at_estimate.t, at_estimate.measured, at_estimate.simulated, low, high,
                      level, samples, samples - len(finite), seed, window_s)
