"""Longitudinal flight simulation of an aircraft (:class:`.Aircraft`) with separation states.

States per maneuver: V, alpha, q, theta, h, the pilot's integrator and every
unsteady separation state. All maneuvers of a batch are integrated together
(fixed-step RK4; the loop runs over time steps, the maneuvers are array
elements). The pilot is a PID on angle of attack tracking a reference
profile, with additive elevator inputs (quasi-random wiggles, steps) and a
throttle schedule; the phugoid flies with the elevator fixed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from . import aircraft as ac
from ..engine.separation import is_lagged
from .aero import AeroModel
from .aircraft import CITATION, Aircraft

ELEVATOR_LIMITS = (-0.40, 0.30)  # rad, trailing edge up / down


@dataclass(frozen=True)
class Condition:
    """Flight condition: mass [kg], centre of gravity [m], altitude [m], airspeed [m/s]."""

    mass: float
    x_cg: float
    h: float
    V: float


@dataclass(frozen=True)
class Trim:
    alpha: float
    de: float
    throttle: float
    residual: float


def _forces(model: AeroModel, aircraft: Aircraft, V, alpha, q, h, de, throttle, mass, x_cg, X: dict, thrust=None):
    """Coefficients and forces (vectorised over maneuvers); ``thrust`` [N] overrides the throttle."""
    rho = ac.density(h)
    qbar = 0.5 * rho * V * V
    if thrust is None:
        thrust = throttle * aircraft.max_thrust(h, rho)
    ct = thrust / (qbar * aircraft.S)
    values = {"alpha": alpha, "q": q, "V": V, "de": de, "CT": ct, "x_cg": x_cg, "cbar": aircraft.cbar,
              "S": aircraft.S, "b": aircraft.b, "h": h, "qbar": qbar}
    if "Mach" in model.columns:  # the envelope's truth (structsearch.flight.envelope)
        values["Mach"] = V / ac.speed_of_sound(h)
    values.update(X)
    cl, cd, cm = model.coefficients(values)
    return qbar, thrust, ct, cl, cd, cm


def _rates(model, aircraft, V, alpha, q, theta, h, de, throttle, mass, x_cg, X, thrust=None):
    qbar, thrust, ct, cl, cd, cm = _forces(model, aircraft, V, alpha, q, h, de, throttle, mass, x_cg, X, thrust)
    gamma = theta - alpha
    qs = qbar * aircraft.S
    lift, drag, moment = qs * cl, qs * cd, qs * aircraft.cbar * cm
    v_dot = (thrust * np.cos(alpha) - drag - mass * ac.G * np.sin(gamma)) / mass
    alpha_dot = q - (lift + thrust * np.sin(alpha) - mass * ac.G * np.cos(gamma)) / (mass * V)
    q_dot = moment / aircraft.inertia(mass)
    return v_dot, alpha_dot, q_dot, (qbar, thrust, ct, cl, cd, cm)


def algebraic_states(model: AeroModel, alpha, alpha_dot, lagged: dict, h=None) -> dict:
    """Separation states: lagged ones from the state vector, the others from alpha (and alpha_dot; the
    altitude ``h`` for a truth with an anomaly that depends on it)."""
    targets = model.separation_targets(alpha, alpha_dot, h, [s for s in model.states if not is_lagged(s.kind)])
    # a lagged state integrated with a time constant near the step may overshoot [0, 1] by a hair; sqrt(X)
    # in K_L must not see it
    return {s.symbol: (np.clip(lagged[s.symbol], 0.0, 1.0) if is_lagged(s.kind) else targets[s.symbol])
            for s in model.states}


def trim(model: AeroModel, cond: Condition, gamma: float = 0.0, aircraft: Aircraft = CITATION) -> Trim:
    """Steady straight flight (level when gamma = 0): alpha, elevator and throttle."""
    def residual(x):
        alpha, de, throttle = x
        X = model.separation_targets(np.array([alpha]), np.zeros(1), np.array([cond.h]))
        v_dot, alpha_dot, q_dot, _ = _rates(model, aircraft, np.array([cond.V]), np.array([alpha]), np.zeros(1),
                                            np.array([alpha + gamma]), np.array([cond.h]), np.array([de]),
                                            np.array([throttle]), cond.mass, cond.x_cg, X)
        return np.array([v_dot[0] / ac.G, alpha_dot[0], q_dot[0]])

    sol = least_squares(residual, [0.1, -0.05, 0.4], bounds=([-0.1, ELEVATOR_LIMITS[0], 0.0],
                                                            [0.4, ELEVATOR_LIMITS[1], 1.0]),
                        xtol=1e-14, ftol=1e-14, gtol=1e-14)
    return Trim(float(sol.x[0]), float(sol.x[1]), float(sol.x[2]), float(np.max(np.abs(sol.fun))))


@dataclass(frozen=True)
class Pilot:
    """Per-maneuver pilot: reference alpha, extra elevator and throttle at every sample; PID gains."""

    alpha_ref: np.ndarray     # (n_steps, n_maneuvers)
    de_extra: np.ndarray      # (n_steps, n_maneuvers)
    throttle: np.ndarray      # (n_steps, n_maneuvers)
    de_trim: np.ndarray       # (n_maneuvers,)
    gains: np.ndarray         # (n_maneuvers, 3): kp, ki, kd; zero for a released elevator
    thrust: np.ndarray | None = None  # (n_steps, n_maneuvers) [N]; overrides the throttle (replay)


@dataclass(frozen=True)
class Trajectory:
    """Truth time histories (n_steps, n_maneuvers) on a uniform grid."""

    t: np.ndarray
    V: np.ndarray
    alpha: np.ndarray
    q: np.ndarray
    theta: np.ndarray
    h: np.ndarray
    de: np.ndarray
    throttle: np.ndarray
    thrust: np.ndarray
    CT: np.ndarray
    qbar: np.ndarray
    alpha_dot: np.ndarray
    q_dot: np.ndarray
    V_dot: np.ndarray
    CL: np.ndarray
    CD: np.ndarray
    Cm: np.ndarray
    X: dict
    mass: np.ndarray
    x_cg: np.ndarray


def _iterations(model) -> int:
    """Fixed-point iterations for alpha_dot: 1 unless an algebraic state depends on alpha_dot."""
    rate_dependent = getattr(model.anomaly, "rate_states", ())  # an anomaly may make a steady state depend on it
    return 4 if any(s.kind == "Q" or (s.kind == "S" and s.symbol in rate_dependent) for s in model.states) else 1


def _alpha_dot_with_states(model, aircraft, V, alpha, q, theta, h, de, throttle, mass, x_cg, lagged, thrust=None,
                           iterations=None):
    """alpha_dot and the separation states consistently (quasi-steady states depend on alpha_dot)."""
    alpha_dot = np.zeros_like(alpha)
    for _ in range(_iterations(model) if iterations is None else iterations):
        X = algebraic_states(model, alpha, alpha_dot, lagged, h)
        v_dot, alpha_dot, q_dot, extra = _rates(model, aircraft, V, alpha, q, theta, h, de, throttle, mass, x_cg,
                                                X, thrust)
    return X, v_dot, alpha_dot, q_dot, extra


# A separation lag shorter than this many integration steps is flown as its tau1 -> 0 limit, the quasi-steady
# state (a fit may end there: tau1 -> 0 is where an unsteady state nests the quasi-steady one).
FAST_LAG_STEPS = 0.5


def _rk4(rhs, y: np.ndarray, n_steps: int, dt: float, ends: np.ndarray) -> np.ndarray:
    """The states at every step of the classical Runge-Kutta scheme from ``y``, the maneuvers side by side; a
    maneuver past its end (``ends``, in steps) keeps its final state rather than flying on unpiloted.

    One batch over time steps: a Python step costs the same for 1 or 50 maneuvers, so the fewer steps the better."""
    out = np.empty((n_steps,) + y.shape)
    for k in range(n_steps):
        out[k] = y
        if k == n_steps - 1:
            break
        k1 = rhs(k, y)
        k2 = rhs(k, y + 0.5 * dt * k1)
        k3 = rhs(k, y + 0.5 * dt * k2)
        k4 = rhs(k, y + dt * k3)
        y = np.where(k + 1 < ends, y + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4), y)
    return out


def simulate(model: AeroModel, y0: dict, pilot: Pilot, mass: np.ndarray, x_cg: np.ndarray,
             dt: float = 0.01, aircraft: Aircraft = CITATION, lengths: np.ndarray | None = None) -> Trajectory:
    """Integrate all maneuvers of a batch for ``len(pilot.alpha_ref)`` steps.

    ``y0`` holds V, alpha, q, theta, h (arrays over maneuvers) and the unsteady
    separation states by symbol; ``mass`` is (n_steps, n_maneuvers). ``lengths`` (samples per
    maneuver, default all ``n_steps``) lets maneuvers of different durations fly in one batch: a
    maneuver's state is held at its last sample once it ends, and its inputs should be padded (with
    their last values, say), so that what follows its end stays finite; the trajectory past a
    maneuver's length is not part of it.
    """
    fast = [s for s in model.unsteady if s.tau1 < FAST_LAG_STEPS * dt]
    if fast:   # a lag much shorter than the step: its quasi-steady limit (RK4 would be unstable below dt / 2.78)
        model = model.with_quasi_steady(fast)
    lagged_names = [s.symbol for s in model.unsteady]
    n_steps, n_man = pilot.alpha_ref.shape
    y = np.vstack([y0["V"], y0["alpha"], y0["q"], y0["theta"], y0["h"], np.zeros(n_man)]
                  + [y0[s] for s in lagged_names]).astype(float)
    taus = {s.symbol: s.tau1 for s in model.unsteady}
    unsteady = model.unsteady
    iterations = _iterations(model)
    kp, ki, kd = pilot.gains.T

    def elevator(k, y):
        alpha, q, z = y[1], y[2], y[5]
        de = pilot.de_trim + pilot.de_extra[k] + kp * (alpha - pilot.alpha_ref[k]) + ki * z + kd * q
        return np.clip(de, *ELEVATOR_LIMITS)

    def rhs(k, y):
        V, alpha, q, theta, h, z = y[:6]
        lagged = dict(zip(lagged_names, y[6:]))
        de = elevator(k, y)
        X, v_dot, alpha_dot, q_dot, extra = _alpha_dot_with_states(
            model, aircraft, V, alpha, q, theta, h, de, pilot.throttle[k], mass[k], x_cg, lagged,
            None if pilot.thrust is None else pilot.thrust[k], iterations)
        targets = model.separation_targets(alpha, alpha_dot, h, unsteady)
        gamma = theta - alpha
        out = np.empty_like(y)
        out[0], out[1], out[2], out[3], out[4], out[5] = v_dot, alpha_dot, q_dot, q, V * np.sin(gamma), \
            alpha - pilot.alpha_ref[k]
        for i, s in enumerate(lagged_names):
            out[6 + i] = (targets[s] - lagged[s]) / taus[s]
        return out

    out = _rk4(rhs, y, n_steps, dt, np.full(n_man, n_steps) if lengths is None else np.asarray(lengths))
    # outputs recomputed on the stored states
    V, alpha, q, theta, h = out[:, 0], out[:, 1], out[:, 2], out[:, 3], out[:, 4]
    lagged = {s: out[:, 6 + i] for i, s in enumerate(lagged_names)}
    de = np.stack([elevator(k, out[k]) for k in range(n_steps)])
    X, v_dot, alpha_dot, q_dot, (qbar, thrust, ct, cl, cd, cm) = _alpha_dot_with_states(
        model, aircraft, V, alpha, q, theta, h, de, pilot.throttle, mass, x_cg[None, :], lagged, pilot.thrust)
    t = np.arange(n_steps) * dt
    return Trajectory(t, V, alpha, q, theta, h, de, pilot.throttle, thrust, ct, qbar, alpha_dot, q_dot,
                      v_dot, cl, cd, cm, X, mass, np.broadcast_to(x_cg, V.shape))
