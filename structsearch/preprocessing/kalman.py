"""Extended Kalman filter and Rauch-Tung-Striebel smoother over a sequence of records (maneuvers).

Generic numerics, no I/O: a :class:`StateSpace` model gives the discrete transition and the measurement with
their Jacobians; states split into *kinematic* ones, re-initialised from the measurements at the start of every
record (states never run across maneuver boundaries), and *parameter* ones (sensor errors), constant and carried
from record to record, so that every record informs the same sensor errors.

Why not filterpy: its ``rts_smoother`` predicts with ``F @ x``, which is the linear smoother; the extended
smoother needs the nonlinear prediction f(x) and per-step Jacobians, and record resets. The tests check this
implementation against filterpy's linear filter and smoother on a linear model, where the two must agree.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np


class StateSpace(Protocol):
    n_states: int
    kinematic: slice      # the states re-initialised at every record start

    def transition(self, x: np.ndarray, u0: np.ndarray, u1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """State one step on, given the inputs at the step's start and end, and its Jacobian."""

    def measure(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted measurements and their Jacobian (n_measurements x n_states)."""

    def initial(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Kinematic states at a record start from its first measurements and the current parameters."""


@dataclass(frozen=True)
class Smoothed:
    """Filtered and smoothed states with covariances, and the filter's innovations."""

    filtered: np.ndarray           # (N, n)
    smoothed: np.ndarray           # (N, n)
    smoothed_cov: np.ndarray       # (N, n, n)
    innovation: np.ndarray         # (N, m); NaN where the channel was not used at that step
    innovation_var: np.ndarray     # (N, m); predicted variance H P H' + R of each innovation
    process_var: np.ndarray        # (n,) expected squared process noise per step (NaN without smoothing)


def filter_smooth(model: StateSpace, inputs: np.ndarray, y: np.ndarray, use: np.ndarray, starts: np.ndarray,
                  x0: np.ndarray, p0: np.ndarray, q: np.ndarray, r: np.ndarray,
                  progress: Callable[[float], None] | None = None, smooth: bool = True) -> Smoothed:
    """Run the extended Kalman filter forward and the RTS smoother backward over all steps.

    ``inputs`` (N, k) and ``y`` (N, m) per step; ``use`` (N, m) marks the measurements to update with (each
    channel at its own rate, so that its errors are nearly independent from update to update); ``starts``
    (N,) marks record starts; ``x0``, ``p0`` the prior of every state (the kinematic block of ``p0`` is also
    the covariance at each record start); ``q`` (n, n) the process noise per step, ``r`` (m,) the
    measurement noise variances. Measurements update one at a time (``r`` is diagonal), each about the
    state the previous one left, as an iterated update would. ``smooth=False`` skips the backward pass (the
    "smoothed" fields then hold the filtered ones).
    """
    n_steps, n = len(y), model.n_states
    kin = model.kinematic
    eye = np.eye(n)
    x_pred = np.empty((n_steps, n))
    x_filt = np.empty((n_steps, n))
    p_pred = np.empty((n_steps, n, n))
    p_filt = np.empty((n_steps, n, n))
    jac = np.empty((n_steps, n, n))
    innovation = np.full(y.shape, np.nan)
    innovation_var = np.full(y.shape, np.nan)
    reset = eye.copy()
    reset[kin, kin] = 0.0
    q_reset = np.zeros((n, n))
    q_reset[kin, kin] = p0[kin, kin]
    x, p = x0.astype(float).copy(), p0.astype(float).copy()
    report_every = max(1, n_steps // 20)
    for k in range(n_steps):
        if starts[k]:
            x = x.copy()
            x[kin] = model.initial(x, y[k])
            f = reset
            p = f @ p @ f.T + q_reset
        else:
            x, f = model.transition(x, inputs[k - 1], inputs[k])
            p = f @ p @ f.T + q
        x_pred[k], p_pred[k], jac[k] = x, p, f
        x, p = _update(model, x, p, y[k], use[k], r, innovation[k], innovation_var[k])
        x_filt[k], p_filt[k] = x, p
        if progress is not None and k % report_every == 0:
            progress(0.5 * k / n_steps)
    xs, ps, process_var = _smooth(model, inputs, starts, x_pred, x_filt, p_pred, p_filt, jac, smooth,
                                  progress, report_every)
    return Smoothed(x_filt, xs, ps, innovation, innovation_var, process_var)


def _update(model: StateSpace, x: np.ndarray, p: np.ndarray, y_k: np.ndarray, use_k: np.ndarray, r: np.ndarray,
            innovation_k: np.ndarray, innovation_var_k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One step's measurements, one at a time, each about the state the previous one left; their innovations and
    variances are written into ``innovation_k`` and ``innovation_var_k``."""
    for j in np.flatnonzero(use_k):
        predicted, h = model.measure(x)
        hj = h[j]
        ph = p @ hj
        s = hj @ ph + r[j]
        gain = ph / s
        nu = y_k[j] - predicted[j]
        innovation_k[j], innovation_var_k[j] = nu, s
        x = x + gain * nu
        p = p - np.outer(gain, ph)
        p = 0.5 * (p + p.T)
    return x, p


def _smooth(model: StateSpace, inputs, starts, x_pred, x_filt, p_pred, p_filt, jac, smooth: bool, progress,
            report_every: int):
    """The RTS smoother's backward pass (the filtered states when not ``smooth``) and the process-noise variance
    the smoothed states imply (NaN without a transition)."""
    n_steps, n = x_filt.shape
    xs, ps = x_filt.copy(), p_filt.copy()
    # E[(x[k+1] - f(x[k]))^2] under the smoothed distribution, summed over the transitions within records
    # (Shumway and Stoffer's M-step for the process noise, linearised): the squared mean plus
    # P[k+1] - 2 F C[k] P[k+1] + F P[k] F' on the diagonal, C the smoother gain
    process_sum, transitions = np.zeros(n), 0
    for k in range(n_steps - 2, -1, -1) if smooth else ():
        f = jac[k + 1]
        gain = np.linalg.solve(p_pred[k + 1], f @ p_filt[k]).T
        xs[k] = x_filt[k] + gain @ (xs[k + 1] - x_pred[k + 1])
        ps[k] = p_filt[k] + gain @ (ps[k + 1] - p_pred[k + 1]) @ gain.T
        if not starts[k + 1]:
            mean = xs[k + 1] - model.transition(xs[k], inputs[k], inputs[k + 1])[0]
            process_sum += (mean * mean + np.diag(ps[k + 1]) - 2.0 * np.einsum("ij,jk,ki->i", f, gain, ps[k + 1])
                            + np.einsum("ij,jk,ik->i", f, ps[k], f))
            transitions += 1
        if progress is not None and k % report_every == 0:
            progress(1.0 - 0.5 * k / n_steps)
    return xs, ps, process_sum / transitions if transitions else np.full(n, np.nan)
