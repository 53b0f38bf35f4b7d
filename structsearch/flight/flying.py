"""Flying maneuvers in batches: what the pilot does in one maneuver (:class:`Flown`), the batch integration of
several (:func:`fly_batch`), and the slow reconstruction errors every measured maneuver carries. Shared by the stall
campaign (:mod:`.flighttest`) and the nominal maneuvers (:mod:`.nominal`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .aero import AeroModel
from .aircraft import CITATION, Aircraft
from .simulation import Condition, Pilot, simulate

DT = 0.01  # truth and output sample time [s]
# Slow errors of the reconstructed coefficients that no candidate model explains (accelerometer bias
# instability, flight-path-reconstruction drift, aerodynamics outside the model): band-limited C_L,
# C_D, C_m errors growing with the flow separation. They are added to the measurements, not fed
# through the pilot, so they carry no closed-loop bias. Their size makes the final models' standard
# deviations on the default campaign those of thesis Tables 11, 13 and 15 within a factor of 2 (README)
# while the residual MSEs stay near Table 11.1.
SLOW_ERROR_SIGMA = (0.03, 0.003, 0.006)  # C_L, C_D, C_m at attached flow
SLOW_ERROR_BAND_HZ = (0.02, 0.3)
SLOW_ERROR_STALL_GAIN = 1.0              # per unit of separation (1 - X summed over the states)


@dataclass(frozen=True)
class Flown:
    """What the pilot does in one maneuver and where it starts."""

    condition: Condition
    theta0: float
    V0: float
    alpha_ref: np.ndarray
    de_extra: np.ndarray
    throttle: np.ndarray
    gains: tuple[float, float, float]
    de_trim: float
    alpha0: float


def reconstruction_error(rng: np.random.Generator, n: int, size: float = 1.0) -> np.ndarray:
    """(n, 3) slow C_L, C_D, C_m errors at attached flow: ``size`` times SLOW_ERROR_SIGMA."""
    from .measurement import band_noise
    return np.column_stack([size * sigma * band_noise(rng, n, 1.0 / DT, *SLOW_ERROR_BAND_HZ)
                            for sigma in SLOW_ERROR_SIGMA])


def fly_batch(model: AeroModel, flown: list[Flown], aircraft: Aircraft = CITATION):
    """Integrate maneuvers together (of any durations: each is padded with its final inputs and held
    once it ends); returns the truth Trajectory, (longest duration, maneuvers)."""
    lengths = np.array([len(f.alpha_ref) for f in flown])
    n = int(lengths.max())

    def stack(attr):
        return np.column_stack([np.pad(getattr(f, attr), (0, n - len(f.alpha_ref)), mode="edge") for f in flown])
    pilot = Pilot(stack("alpha_ref"), stack("de_extra"), stack("throttle"),
                  np.array([f.de_trim for f in flown]), np.array([f.gains for f in flown]))
    alpha0 = np.array([f.alpha0 for f in flown])
    h0 = np.array([f.condition.h for f in flown])
    x0 = model.separation_targets(alpha0, np.zeros_like(alpha0), h0)
    y0 = {"V": np.array([f.V0 for f in flown]), "alpha": alpha0, "q": np.zeros(len(flown)),
          "theta": np.array([f.theta0 for f in flown]), "h": h0}
    y0.update({s.symbol: x0[s.symbol] for s in model.unsteady})
    masses = np.array([f.condition.mass for f in flown])
    # fuel burnt along the maneuver
    burn = np.cumsum(stack("throttle"), axis=0) * DT * aircraft.max_fuel_flow
    mass = masses[None, :] - burn
    return simulate(model, y0, pilot, mass, np.array([f.condition.x_cg for f in flown]), DT, aircraft, lengths)
