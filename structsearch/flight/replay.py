"""Forward simulation: replay recorded inputs through the simulator with an identified model.

Each maneuver is cut into windows; every window starts from the measured
states (V, alpha, q, theta, h; separation states in equilibrium with the
measured alpha and alpha_dot) and is driven open loop by the recorded elevator
and thrust. Windows keep stall maneuvers from diverging trivially while still
showing how the model's dynamics differ from the aircraft's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import aircraft as ac
from .aircraft import aircraft_of_campaign
from .aero import AeroModel
from ..data.flightdata import FlightData
from ..data.errors import DataError
from .simulation import Pilot, simulate

STATES = ("V", "alpha", "q", "theta", "h")
REQUIRED = STATES + ("t", "de", "CT", "mass", "alpha_dot")


@dataclass(frozen=True)
class Replay:
    """Measured and simulated state histories of one maneuver, and their RMS differences."""

    name: str
    t: np.ndarray
    measured: dict
    simulated: dict
    window_starts: np.ndarray

    @property
    def rms(self) -> dict[str, float]:
        return {s: float(np.sqrt(np.mean((self.simulated[s] - self.measured[s]) ** 2))) for s in STATES}


# A replayed alpha this far (rad, 20 deg) from the measured one has left the flight: each window restarts from the
# measured states, so a model that flies the aircraft keeps well inside it
DIVERGED_ALPHA = 0.35


def divergence(run: Replay) -> tuple[float, str] | None:
    """Where (seconds into the maneuver) and why a replay diverged, or None: the first sample at which a state is
    not finite or alpha is more than DIVERGED_ALPHA from the measurement."""
    bad = np.zeros(len(run.t), bool)
    why = ""
    for s in ("V", "alpha", "q", "theta"):
        off = ~np.isfinite(run.simulated[s])
        if off.any() and (not bad.any() or np.argmax(off) < np.argmax(bad)):
            bad, why = off, f"{s} not finite"
    far = np.abs(run.simulated["alpha"] - run.measured["alpha"]) > DIVERGED_ALPHA
    far &= np.isfinite(run.simulated["alpha"])
    if far.any() and (not bad.any() or np.argmax(far) < np.argmax(bad)):
        bad, why = far, f"alpha more than {np.degrees(DIVERGED_ALPHA):.0f} deg from the measurement"
    if not bad.any():
        return None
    k = int(np.argmax(bad))
    return float(run.t[k] - run.t[0]), why


def replay(data: FlightData, model: AeroModel, window_s: float = 10.0) -> list[Replay]:
    """Replay every maneuver of ``data`` in windows of ``window_s`` seconds; the aircraft's S, cbar and
    pitch inertia Iyy come from the campaign (``data.constants``), x_cg only when the model uses it."""
    craft = aircraft_of_campaign(data.constants, data.source)
    for col in REQUIRED + (("x_cg",) if "x_cg" in model.columns else ()):
        if col not in data:
            hint = " (simulated campaigns carry it; add a mass column to real ones)" if col == "mass" else ""
            raise DataError(f"forward simulation needs this column{hint}", source=data.source, column=col)
    if window_s <= 0:
        raise DataError(f"window length must be positive, not {window_s}")
    windows = []  # (position, samples, sample time, window starts, sample indices)
    for sl in data.segment_slices():
        t = data["t"][sl]
        dt = np.diff(t)
        if not np.allclose(dt, dt[0], rtol=1e-6):
            raise DataError("forward simulation needs a uniform time grid", source=data.source, column="t")
        step = float(dt[0])
        n = len(t)
        per = max(2, int(round(window_s / step)))
        starts = np.arange(0, n, per)
        # (per, windows) sample indices, the last window padded with its final sample
        index = sl.start + np.minimum(starts[None, :] + np.arange(per)[:, None], n - 1)
        windows.append((len(windows), sl, step, starts, index))
    # the windows of every maneuver with one sample time fly as one batch: a simulation step costs the
    # same for one window or hundreds
    simulated = {}
    for step in dict.fromkeys(w[2] for w in windows):
        group = [w for w in windows if w[2] == step]
        index = np.concatenate([w[4] for w in group], axis=1)
        first_index = index[0]
        col = lambda c: data[c][index]  # noqa: E731
        first = lambda c: data[c][first_index]  # noqa: E731
        qbar = 0.5 * ac.density(col("h")) * col("V") ** 2
        thrust = col("CT") * qbar * craft.S
        n_win = index.shape[1]
        pilot = Pilot(np.zeros(index.shape), col("de"), np.zeros(index.shape), np.zeros(n_win),
                      np.zeros((n_win, 3)), thrust=thrust)
        x0 = model.separation_targets(first("alpha"), first("alpha_dot"), first("h"))
        y0 = {s: first(s) for s in STATES}
        y0.update({s.symbol: x0[s.symbol] for s in model.unsteady})
        x_cg = first("x_cg") if "x_cg" in data else np.full(n_win, np.nan)
        traj = simulate(model, y0, pilot, col("mass"), x_cg, step, craft)
        column = 0
        for position, sl, _, starts, _ in group:
            n = sl.stop - sl.start
            cols = slice(column, column + len(starts))
            column += len(starts)
            # window after window
            simulated[position] = {s: getattr(traj, s)[:, cols].T.reshape(-1)[:n] for s in STATES}
    out = []
    for name, (position, sl, _, starts, _) in zip(data.names, windows):
        measured = {s: data[s][sl] for s in STATES}
        out.append(Replay(name, data["t"][sl], measured, simulated[position], starts))
    return out
