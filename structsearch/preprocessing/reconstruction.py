"""Flight-path reconstruction (data-compatibility check): the sensor errors that make the recorded kinematics
consistent, by an extended Kalman filter and RTS smoother over :mod:`.kinematics` (issue 15 item 4).

Noise levels come from the data: the process noise from the input channels' noise floor in their attached-flow
spectra (white noise integrates into the velocities and attitude with the spectrum's low-frequency density),
the measurement noise by an expectation-maximisation step (a first pass's expected squared smoothed residuals).
Each measurement updates at about twice its pre-filter cut-off, where its filtered errors are nearly
independent. The consistency residuals (measurement minus the smoothed kinematics) are reported with the sensor
errors held at their nominal values ("before") and estimated ("after").
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from ..data.errors import FitError
from ..data.reduction import specific_force_at_cg
from .kalman import filter_smooth
from .kinematics import (INPUTS, MEASUREMENTS, NOMINAL, PRIOR_SD, SENSOR_ERRORS, START_SD, UNITS,
                         LongitudinalKinematics)

# Filter step [s]: the rigid-body kinematics are smooth at 25 Hz and the filter runs a quarter of the samples.
STEP_S = 0.04
# Process noise of the altitude (not driven by a measured input), per step [m^2].
H_PROCESS_VAR = 1e-4
EDGE_S = 4.0
# Expectation-maximisation steps for the measurement noise before the final pass.
EM_STEPS = 1
PRIOR_INFLATION = 100.0
# Groups of maneuvers of the jackknife standard deviations.
JACKKNIFE_GROUPS = 8
# Measurement noise variance floor relative to the first guess (covariance matching never reaches 0).
R_FLOOR = 1e-3


@dataclass(frozen=True)
class SensorError:
    """An estimated sensor error; ``sd`` is the larger of the smoother's and the maneuver jackknife's."""

    name: str
    unit: str
    estimate: float
    sd: float
    filter_sd: float       # from the smoother's covariance: as good as the noise model
    jackknife_sd: float    # from the spread over delete-a-group replicates of maneuvers: needs no noise model


@dataclass(frozen=True)
class Consistency:
    """RMS of measurement minus smoothed kinematics, sensor errors nominal and estimated."""

    channel: str
    before: float
    after: float


@dataclass(frozen=True)
class Reconstruction:
    errors: tuple[SensorError, ...]
    consistency: tuple[Consistency, ...]
    step_s: float
    n_steps: int
    process_psd: Mapping[str, float]       # two-sided noise density of each input [unit^2/Hz]
    measurement_sd: Mapping[str, float]    # noise of each measurement as estimated by the EM step

    def error(self, name: str) -> SensorError:
        return next(e for e in self.errors if e.name == name)

    def correct(self, channels: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The measured channels less the estimated errors (ax, az at the accelerometer or the cg alike)."""
        e = {x.name: x.estimate for x in self.errors}
        out = dict(channels)
        out["ax"] = channels["ax"] - e["ax_bias"]
        out["az"] = channels["az"] - e["az_bias"]
        out["q"] = channels["q"] - e["q_bias"]
        out["alpha"] = (channels["alpha"] - e["alpha_bias"]) / e["alpha_scale"]
        out["V"] = channels["V"] / e["V_scale"]
        return out


def _steps(slices: Sequence[slice], every: int) -> tuple[np.ndarray, np.ndarray]:
    """Sample indices of the filter steps and the record-start flags."""
    index, starts = [], []
    for sl in slices:
        i = np.arange(sl.start, sl.stop, every)
        index.append(i)
        starts.append(np.arange(len(i)) == 0)
    return np.concatenate(index), np.concatenate(starts)


def _jackknife_sd(model, inputs, y, use, starts, x0, p0, q, r, progress) -> np.ndarray:
    """Delete-a-group jackknife standard deviations of the sensor errors: maneuvers dealt into
    JACKKNIFE_GROUPS groups (every G-th maneuver), the filter rerun without each group. The smoother's
    covariance trusts the noise model (white inputs, independent updates); the jackknife does not."""
    record = np.cumsum(starts) - 1
    groups = min(JACKKNIFE_GROUPS, int(record[-1]) + 1)
    if groups < 2:
        return np.full(len(x0) - 4, np.nan)
    replicates = []
    for g in range(groups):
        keep = record % groups != g
        run = filter_smooth(model, inputs[keep], y[keep], use[keep], starts[keep], x0, p0, q, r, smooth=False)
        replicates.append(run.filtered[-1, 4:])
        if progress is not None:
            progress((g + 1) / groups)
    replicates = np.array(replicates)
    return np.sqrt((groups - 1) / groups * np.sum((replicates - replicates.mean(axis=0)) ** 2, axis=0))


def _expected_squared_residual(model, run, y, use) -> np.ndarray:
    """The measurement-noise variances of an EM step: E[(y - h(x))^2] under the smoothed states, i.e. the
    squared smoothed residual plus the smoothed state uncertainty H P H' (robust to the first maneuvers'
    large innovations while the sensor errors are still unknown)."""
    out = np.empty(y.shape[1])
    sums = np.zeros(y.shape[1])
    for k in np.flatnonzero(use.any(axis=1)):
        predicted, h = model.measure(run.smoothed[k])
        for j in np.flatnonzero(use[k]):
            sums[j] += (y[k, j] - predicted[j]) ** 2 + h[j] @ run.smoothed_cov[k] @ h[j]
    for j in range(y.shape[1]):
        out[j] = sums[j] / max(1, np.count_nonzero(use[:, j]))
    return out


def _residual_rms(model, smoothed, y, use) -> np.ndarray:
    out = np.empty(y.shape[1])
    predicted = np.array([model.measure(x)[0] for x in smoothed])
    for j in range(y.shape[1]):
        d = (y[:, j] - predicted[:, j])[use[:, j]]
        out[j] = np.sqrt(np.mean(d * d)) if d.size else np.nan
    return out


def _observations(filtered: Mapping[str, np.ndarray], slices: Sequence[slice], every: int, dt: float,
                  index: np.ndarray, cutoffs_hz: Mapping[str, float], accelerometer):
    """The filter's inputs (the specific forces moved to the cg, the rates) and measurements at its steps, and
    which measurement updates each step (each channel at its own rate, none near a maneuver's ends)."""
    zero = np.zeros(len(filtered["q"]))
    ax_cg, az_cg = specific_force_at_cg(filtered["ax"], filtered["az"], filtered["q"], filtered["q_dot"],
                                        accelerometer)
    channels = {"ax": ax_cg, "az": az_cg, "q": filtered["q"], "r": filtered.get("r", zero),
                "phi": filtered.get("phi", zero)}
    inputs = np.column_stack([channels[c][index] for c in INPUTS])
    y = np.column_stack([filtered[c][index] for c in MEASUREMENTS])
    step_number = np.concatenate([np.arange(len(range(sl.start, sl.stop, every))) for sl in slices])
    use = np.column_stack([step_number % max(1, int(round(1.0 / (2.0 * cutoffs_hz[c] * dt)))) == 0
                           for c in MEASUREMENTS])
    # the zero-phase filters' start-up transients at a maneuver's ends: no updates within EDGE_S of them
    steps_left = np.concatenate([np.arange(len(range(sl.start, sl.stop, every)))[::-1] for sl in slices])
    edge = int(round(EDGE_S / dt))
    use &= ((step_number >= edge) & (steps_left >= edge))[:, None]
    if not use.any():
        raise FitError(f"no maneuver is longer than {2 * EDGE_S:g} s: the flight-path reconstruction leaves "
                       f"{EDGE_S:g} s at each end to the filters' transients and has nothing left to compare")
    return inputs, y, use


def reconstruct(filtered: Mapping[str, np.ndarray], slices: Sequence[slice], fs: float,
                cutoffs_hz: Mapping[str, float], input_psd: Mapping[str, float], accelerometer=(0.0, 0.0, 0.0),
                progress: Callable[[float], None] | None = None) -> Reconstruction:
    """Estimate the sensor errors from the pre-filtered channels (``filtered``: ax, az at the accelerometer,
    q, q_dot, V, alpha, theta, h and optionally r, phi; one array over all maneuvers, ``slices`` the
    maneuvers). ``input_psd``: the one-sided noise floor of ax, az and q [unit^2/Hz]."""
    every = max(1, int(round(STEP_S * fs)))
    dt = every / fs
    index, starts = _steps(slices, every)
    inputs, y, use = _observations(filtered, slices, every, dt, index, cutoffs_hz, accelerometer)
    model = LongitudinalKinematics(dt)
    psd = {c: 0.5 * float(input_psd[c]) for c in ("ax", "az", "q")}   # two-sided
    q = np.zeros((model.n_states, model.n_states))
    q[0, 0], q[1, 1], q[2, 2], q[3, 3] = psd["ax"] * dt, psd["az"] * dt, psd["q"] * dt, H_PROCESS_VAR
    x0 = np.concatenate([np.zeros(4), NOMINAL])
    p0 = np.diag(np.concatenate([START_SD, PRIOR_SD]) ** 2)
    # a generous first guess of the measurement noise: each channel's spread about its 1-s moving mean, which
    # holds the motion as well (too small a guess lets the first pass diverge)
    window = np.ones(max(1, int(round(1.0 / dt)))) / max(1, int(round(1.0 / dt)))
    r = np.array([np.var(y[:, j] - np.convolve(y[:, j], window, mode="same")) + 1e-12
                  for j in range(len(MEASUREMENTS))])

    def stage(lo, hi):
        return None if progress is None else (lambda f: progress(lo + (hi - lo) * f))

    share = 0.6 / (EM_STEPS + 1)
    for i in range(EM_STEPS):
        run = filter_smooth(model, inputs, y, use, starts, x0, p0, q, r, stage(i * share, (i + 1) * share))
        r = np.maximum(_expected_squared_residual(model, run, y, use), R_FLOOR * r)
        # the process noise of the kinematic states likewise, never below the inputs' white noise
        q[:4, :4] = np.diag(np.maximum(run.process_var[:4], np.diag(q)[:4]))
        # the next pass starts from these sensor errors with PRIOR_INFLATION times their variance: from the
        # wide nominal prior, a pass with the tighter noise can diverge in the first maneuver, before the errors
        # are learnt (bilinear terms such as k_alpha * atan(w/u)); the prior then carries 1/PRIOR_INFLATION of
        # that pass's information, a small share
        x0 = np.concatenate([np.zeros(4), run.smoothed[0, 4:]])
        p0 = p0.copy()
        p0[4:, 4:] = PRIOR_INFLATION * run.smoothed_cov[0, 4:, 4:]
    final = filter_smooth(model, inputs, y, use, starts, x0, p0, q, r, stage(EM_STEPS * share, 0.6))
    held = np.diag(np.concatenate([START_SD, PRIOR_SD]) ** 2)
    held[4:, 4:] = np.diag((1e-9 * PRIOR_SD) ** 2)
    nominal = filter_smooth(model, inputs, y, use, starts, np.concatenate([np.zeros(4), NOMINAL]), held, q, r,
                            stage(0.6, 0.75))
    estimate, cov = final.smoothed[0, 4:], final.smoothed_cov[0, 4:, 4:]
    jackknife = _jackknife_sd(model, inputs, y, use, starts, x0, p0, q, r, stage(0.75, 1.0))
    if not np.all(np.isfinite(estimate)) or not np.all(np.isfinite(np.diag(cov))):
        raise FitError("the flight-path reconstruction diverged (non-finite sensor errors); check the channels' "
                       "units and the accelerometer position")
    # without a jackknife (one maneuver) the smoother's standard deviation stands alone; the record says so
    errors = tuple(SensorError(name, UNITS[name], float(v), float(np.fmax(np.sqrt(cov[i, i]), jackknife[i])),
                               float(np.sqrt(cov[i, i])), float(jackknife[i]))
                   for i, (name, v) in enumerate(zip(SENSOR_ERRORS, estimate)))
    before = _residual_rms(model, nominal.smoothed, y, use)
    after = _residual_rms(model, final.smoothed, y, use)
    consistency = tuple(Consistency(c, float(b), float(a)) for c, b, a in zip(MEASUREMENTS, before, after))
    return Reconstruction(errors, consistency, dt, len(index), {c: psd[c] for c in psd},
                          {c: float(np.sqrt(v)) for c, v in zip(MEASUREMENTS, r)})
