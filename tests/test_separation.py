"""Separation states: exact lag discretisation, per-maneuver initial conditions, sensitivities."""
import numpy as np
import pytest

from structsearch.engine import separation as sep
from structsearch.engine.separation import KINDS, SeparationState, evaluate_state, first_order_lag, linear_recurrence

from conftest import central_difference


def reference_lag(t, u, tau):
    """Straight loop over samples of the first-order-hold recursion."""
    x = np.empty_like(u)
    x[0] = u[0]
    for k in range(1, len(u)):
        h = t[k] - t[k - 1]
        a = np.exp(-h / tau)
        g = tau * (1 - a) / h
        x[k] = a * x[k - 1] + (g - a) * u[k - 1] + (1 - g) * u[k]
    return x


def test_lag_is_exact_for_piecewise_linear_input():
    # tau x' + x = u with u = c t has the closed form x = c (t - tau) + (x0 - c(0 - tau)) e^{-t/tau}
    tau, c = 0.37, 2.0
    t = np.cumsum(np.r_[0.0, np.random.default_rng(1).uniform(0.005, 0.02, 999)])
    u = c * t
    x, _, _ = first_order_lag(t, u, u[:, None].copy(), tau, np.array([0, len(t)]))
    exact = c * (t - tau) + (0.0 + c * tau) * np.exp(-t / tau)
    assert np.max(np.abs(x - exact)) < 1e-12


@pytest.mark.parametrize("uniform", [True, False])
def test_lag_matches_reference_loop_per_maneuver(uniform):
    rng = np.random.default_rng(2)
    lengths = [700, 1300, 400]
    ts = []
    for n in lengths:
        steps = np.full(n - 1, 0.01) if uniform else rng.uniform(0.004, 0.016, n - 1)
        ts.append(np.r_[0.0, np.cumsum(steps)])
    t = np.concatenate(ts)
    u = np.sin(3 * t) + 0.2 * rng.standard_normal(len(t))
    bounds = np.r_[0, np.cumsum(lengths)]
    x, _, _ = first_order_lag(t, u, u[:, None].copy(), 0.3, bounds)
    expect = np.concatenate([reference_lag(t[s:e], u[s:e], 0.3) for s, e in zip(bounds[:-1], bounds[1:])])
    assert np.max(np.abs(x - expect)) < 1e-12
    # every maneuver starts in equilibrium with its first input
    assert np.allclose(x[bounds[:-1]], u[bounds[:-1]])


def test_one_pass_filter_equals_per_maneuver_filter(monkeypatch):
    rng = np.random.default_rng(3)
    t = np.concatenate([np.arange(500) * 0.01, np.arange(800) * 0.01 + 3.0])
    u = rng.uniform(0, 1, len(t))
    du = rng.standard_normal((len(t), 3))
    bounds = np.array([0, 500, 1300])
    fast = first_order_lag(t, u, du, 0.25, bounds)
    monkeypatch.setattr(sep, "common_step", lambda *a: None)
    slow = first_order_lag(t, u, du, 0.25, bounds)
    for a, b in zip(fast, slow):
        assert np.max(np.abs(a - b)) < 1e-12


def test_maneuvers_do_not_leak_into_each_other():
    t = np.concatenate([np.arange(300) * 0.01, np.arange(300) * 0.01])
    u = np.concatenate([np.zeros(300), np.ones(300)])
    bounds = np.array([0, 300, 600])
    x, _, _ = first_order_lag(t, u, u[:, None].copy(), 0.5, bounds)
    assert np.max(np.abs(x[300:] - 1.0)) < 1e-14
    u2 = u.copy()
    u2[:300] = 0.9
    x2, _, _ = first_order_lag(t, u2, u2[:, None].copy(), 0.5, bounds)
    assert np.max(np.abs(x[300:] - x2[300:])) < 1e-14


def test_linear_recurrence_long_and_stiff():
    # decay far beyond what one cumulative product could represent
    rng = np.random.default_rng(4)
    n = 20000
    a = np.exp(-rng.uniform(0.5, 2.0, n))
    f = rng.standard_normal(n)
    y = linear_recurrence(a, f, 0.3)
    ref = np.empty(n)
    ref[0] = 0.3
    for k in range(1, n):
        ref[k] = a[k] * ref[k - 1] + f[k]
    assert np.all(np.isfinite(y))
    assert np.max(np.abs(y - ref)) < 1e-12


def test_static_separation_limits():
    a = np.array([-1.0, 0.2, 3.0])
    x = sep.static_separation(a, 70.0, 0.2)
    assert x[0] == pytest.approx(1.0) and x[1] == pytest.approx(0.5) and 0 < x[2] < 1e-100


@pytest.mark.parametrize("kind", list(KINDS))
@pytest.mark.parametrize("uniform", [True, False])
def test_state_sensitivities_match_finite_differences(kind, uniform):
    rng = np.random.default_rng(5)
    n = 600
    steps = np.full(n - 1, 0.01) if uniform else rng.uniform(0.006, 0.014, n - 1)
    t = np.r_[0.0, np.cumsum(steps)]
    t = np.concatenate([t, t])
    alpha = np.concatenate([0.2 + 0.08 * np.sin(2.1 * t[:n]), 0.18 + 0.1 * np.sin(1.3 * t[n:] + 0.4)])
    alpha_dot = np.gradient(alpha, t)
    alpha_dot[n:] = np.gradient(alpha[n:], t[n:])
    bounds = np.array([0, n, 2 * n])
    state = SeparationState("ss", kind)
    truth = {"tau1": 0.41, "tau2": 0.33, "tau_v": 0.27, "a1": 40.0, "a_star": 0.21}
    theta = np.array([truth[p] for p in state.base_parameters])

    def value(th):  # the value-only path a prediction takes
        return evaluate_state(state, dict(zip(state.base_parameters, th)), alpha, alpha_dot, t, bounds,
                              sensitivities=False)[0]

    x, analytic = evaluate_state(state, dict(zip(state.base_parameters, theta)), alpha, alpha_dot, t, bounds)
    assert np.max(np.abs(value(theta) - x)) <= 1e-14
    numeric = central_difference(value, theta)
    scale = np.max(np.abs(numeric), axis=0)
    assert np.all(np.max(np.abs(analytic - numeric), axis=0) <= 1e-6 * scale + 1e-10)


def test_state_declaration_errors():
    from structsearch.data.errors import DeclarationError
    with pytest.raises(DeclarationError, match="kind"):
        SeparationState("ss", "X")
    assert SeparationState("", "U").parameters == ("tau1", "tau2", "a1", "a_star")
    assert SeparationState("w", "S").parameters == ("a1_w", "a_star_w")


@pytest.mark.parametrize("tau", [0.01, 0.4])
def test_a_long_time_gap_inside_a_maneuver_gives_finite_exact_states(tau):
    """10 s gaps in the time stamps (1000 tau1 for tau1 = 0.01, beyond exp underflow) keep the recursion exact."""
    rng = np.random.default_rng(5)
    t = np.r_[np.arange(0.0, 2.0, 0.01), 12.0 + np.arange(0.0, 2.0, 0.01), 24.0 + np.arange(0.0, 1.0, 0.01)]
    u = 0.5 + 0.4 * np.sin(1.3 * t) + 0.01 * rng.standard_normal(len(t))
    du = np.column_stack([np.cos(t), t / 10])
    bounds = np.array([0, len(t)])
    x, dx, dtau = first_order_lag(t, u, du, tau, bounds)
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(dx)) and np.all(np.isfinite(dtau))
    np.testing.assert_allclose(x, reference_lag(t, u, tau), rtol=0, atol=1e-12)
    np.testing.assert_allclose(dx[:, 0], reference_lag(t, du[:, 0], tau), rtol=0, atol=1e-12)
    h = 1e-6 * tau
    fd = (reference_lag(t, u, tau + h) - reference_lag(t, u, tau - h)) / (2 * h)
    np.testing.assert_allclose(dtau, fd, rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("uniform", [True, False])
def test_a_lag_at_tau1_zero_is_the_quasi_steady_state_and_its_derivative_is_the_limit(uniform):
    """Issue 30: tau1 -> 0 is where an unsteady state nests the quasi-steady one, so the box starts at 0: the lag
    is then X = u, and dX/dtau1 its limit -(u_k - u_{k-1}) / dt, which lags of a few microseconds approach."""
    rng = np.random.default_rng(4)
    t = np.linspace(0.0, 3.0, 301) if uniform else np.sort(rng.uniform(0.0, 3.0, 301))
    u = np.sin(2 * t) + 0.1 * t
    bounds = np.array([0, 120, 301])
    x, dx, dtau = first_order_lag(t, u, u[:, None].copy(), 0.0, bounds)
    np.testing.assert_array_equal(x, u)
    np.testing.assert_array_equal(dx[:, 0], u)
    assert dtau[0] == 0.0 and dtau[120] == 0.0
    tiny = 1e-6
    x_tiny, _, _ = first_order_lag(t, u, u[:, None].copy(), tiny, bounds)
    # the limit derivative is the one-sided difference quotient at 0, to O(tau1 / dt)
    np.testing.assert_allclose((x_tiny - x) / tiny, dtau, rtol=1e-3, atol=1e-3 * np.max(np.abs(dtau)))


def test_a_vortex_builds_while_the_flow_separates_and_convects_away_after():
    """V (the dynamic-stall vortex): zero in steady flow; positive while alpha ramps through stall, peaking
    before the ramp ends when tau_v is short; decaying as exp(-t/tau_v) once alpha holds; and the difference
    of the two lags it is defined by (checked against a plain Euler integration on a fine grid)."""
    dt, tau1, tau_v = 1e-4, 0.05, 0.08
    t = np.arange(0, 1.5, dt)
    alpha = np.clip(0.1 + 0.5 * t, 0.1, 0.4)            # ramp from 0.1 to 0.4 rad in 0.6 s, then hold
    alpha_dot = np.gradient(alpha, t)
    bounds = np.array([0, len(t)])
    values = {"tau1": tau1, "tau_v": tau_v, "a1": 30.0, "a_star": 0.25}
    v = evaluate_state(SeparationState("v", "V"), values, alpha, alpha_dot, t, bounds, sensitivities=False)[0]
    x0 = sep.static_separation(alpha, 30.0, 0.25)
    xs, y = np.empty_like(t), np.empty_like(t)
    xs[0] = y[0] = x0[0]
    for k in range(1, len(t)):
        xs[k] = xs[k - 1] + dt * (x0[k - 1] - xs[k - 1]) / tau1
        y[k] = y[k - 1] + dt * (xs[k - 1] - y[k - 1]) / tau_v
    assert np.max(np.abs(v - (y - xs))) < 2e-3        # Euler's error at dt/tau = 1e-3
    assert v[0] == 0.0 and np.all(v[t < 0.1] < 1e-3)  # attached (X0 > 0.99): no vortex
    peak = int(np.argmax(v))
    assert v[peak] > 0.1 and 0.3 < t[peak] < 0.7
    late = (t > 1.0)
    assert np.all(v[late] >= 0) and v[late][-1] < 0.01 * v[peak]
    steady = evaluate_state(SeparationState("v", "V"), values, np.full(50, 0.3), np.zeros(50),
                            np.arange(50) * 0.01, np.array([0, 50]), sensitivities=False)[0]
    assert np.max(np.abs(steady)) < 1e-15


def test_which_kind_holds_which():
    """A richer kind holds a simpler one it reaches at a zero time constant; Q and L do not hold each other,
    and a vortex state holds, and is held by, no other kind (staging warm-starts a structure only from one it
    holds)."""
    from structsearch.engine.separation import nests
    from structsearch.fitting.candidates import Candidate
    from structsearch.fitting.staging import contains
    assert nests("S", "Q") and nests("S", "L") and nests("Q", "U") and nests("L", "U") and nests("V", "V")
    assert not nests("Q", "L") and not nests("L", "Q") and not nests("U", "L")
    assert not any(nests("V", k) or nests(k, "V") for k in ("S", "Q", "L", "U"))
    regs = (("CL_KL", "K_L(X)"),)
    q, lag = (Candidate(f"c{k}", "g", "CL", regs, (("", k),)) for k in ("Q", "L"))
    assert not contains(lag, q) and not contains(q, lag)
