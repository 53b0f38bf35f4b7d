"""Periodic maneuvers: a lag that starts at its periodic solution (docs/interfaces.md 7.5), exact and differentiated."""
import numpy as np
import pytest

from structsearch.engine.separation import SeparationState, evaluate_state, first_order_lag

from conftest import assert_matches_finite_difference


def step_lag(x_prev, u_prev, u_next, h, tau):
    """One step of the first-order-hold recursion, written out (the reference the tests hold the engine to)."""
    a = np.exp(-h / tau)
    g = tau * (1 - a) / h
    return a * x_prev + (g - a) * u_prev + (1 - g) * u_next


def reference_periodic(t, u, tau, period):
    """A cycle's periodic state by brute force: run the sample loop from X0 = 0 and X0 = 1 up to t0 + T (the last
    step wrapping to the first input), then solve the affine one-period map X_end = Phi X0 + r for its fixed point."""
    def run(x0):
        x = [x0]
        for k in range(1, len(u)):
            x.append(step_lag(x[-1], u[k - 1], u[k], t[k] - t[k - 1], tau))
        return np.array(x), step_lag(x[-1], u[-1], u[0], t[0] + period - t[-1], tau)
    _, r = run(0.0)
    _, end_one = run(1.0)
    phi = end_one - r
    return run(r / (1 - phi))[0]


def cycle(n, period, uniform=True, seed=0):
    """One cycle of n samples over ``period`` and an input with a steep rise (a stall) on it."""
    rng = np.random.default_rng(seed)
    if uniform:
        t = np.arange(n) * period / n
    else:
        t = np.sort(rng.uniform(0, period * (1 - 0.5 / n), n))
        t[0] = 0.0
    phase = 2 * np.pi * t / period
    u = 1 / (1 + np.exp(-8 * np.sin(phase))) + 0.02 * rng.standard_normal(n)
    return t + 3.0, u   # a cycle need not start at t = 0


@pytest.mark.parametrize("uniform", [True, False])
@pytest.mark.parametrize("ratio", [0.01, 0.3, 5.0, 300.0])   # tau1 / period, up to a lag that forgets little
def test_a_cycle_starts_at_the_state_it_reaches_one_period_later(uniform, ratio):
    period = 0.83
    t, u = cycle(64, period, uniform)
    tau = ratio * period
    x, _, _ = first_order_lag(t, u, u[:, None].copy(), tau, np.array([0, len(t)]), periods=[period])
    one_period_later = step_lag(x[-1], u[-1], u[0], t[0] + period - t[-1], tau)
    assert abs(one_period_later - x[0]) < 1e-9   # the target is 1e-6
    np.testing.assert_allclose(x, reference_periodic(t, u, tau, period), rtol=0, atol=1e-9)


def test_a_record_of_several_cycles_starts_at_its_state_one_period_on():
    """A record longer than its period: the state at t0 + T, on the record's own input (linear between samples),
    is the start; three cycles of 40 samples each, the period on a sample (row 40) and between samples."""
    period = 1.0
    t = np.arange(120) * period / 40
    rng = np.random.default_rng(3)
    u = 0.5 + 0.4 * np.sin(2 * np.pi * t / period) + 0.01 * rng.standard_normal(len(t))
    for tau in (0.05, 0.7, 40.0):
        x, _, _ = first_order_lag(t, u, u[:, None].copy(), tau, np.array([0, len(t)]), periods=[period])
        assert abs(x[40] - x[0]) < 1e-9
        off = period * 1.013   # t0 + T between rows 40 and 41
        x, _, _ = first_order_lag(t, u, u[:, None].copy(), tau, np.array([0, len(t)]), periods=[off])
        h = off - t[40]
        u_end = u[40] + (u[41] - u[40]) * h / (t[41] - t[40])
        assert abs(step_lag(x[40], u[40], u_end, h, tau) - x[0]) < 1e-9


def test_only_periodic_maneuvers_change_and_the_others_stay_bit_for_bit():
    period = 0.5
    t1, u1 = cycle(50, period, seed=1)
    t2 = np.arange(300) * 0.01
    u2 = np.sin(3 * t2)
    t, u = np.concatenate([t2, t1, t2]), np.concatenate([u2, u1, u2])
    du = np.column_stack([u, u ** 2])
    bounds = np.array([0, 300, 350, 650])
    plain = first_order_lag(t, u, du, 0.2, bounds)
    nan = first_order_lag(t, u, du, 0.2, bounds, periods=[np.nan] * 3)
    mixed = first_order_lag(t, u, du, 0.2, bounds, periods=[np.nan, period, np.nan])
    outside = np.r_[0:300, 350:650]
    for a, b, c in zip(plain, nan, mixed):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a[outside], c[outside])
    assert not np.allclose(plain[0][300:350], mixed[0][300:350])


@pytest.mark.parametrize("uniform", [True, False])
@pytest.mark.parametrize("kind", ["U", "V"])
@pytest.mark.parametrize("tau1", [0.02, 0.41, 30.0])
def test_periodic_sensitivities_match_finite_differences(uniform, kind, tau1):
    """dX/dtheta and dX/dtau1 include the derivative of the periodic start (a cycle beside a record that is not
    periodic and a record of two cycles)."""
    period = 0.9
    t1, _ = cycle(45, period, uniform, seed=2)
    t2 = np.arange(200) * 0.009
    t3 = np.arange(100) * period / 50
    t = np.concatenate([t1, t2, t3])
    alpha = np.concatenate([0.2 + 0.1 * np.sin(2 * np.pi * t1 / period), 0.18 + 0.1 * np.sin(1.3 * t2),
                            0.2 + 0.1 * np.sin(2 * np.pi * t3 / period + 0.3)])
    alpha_dot = np.concatenate([np.gradient(alpha[:45], t1), np.gradient(alpha[45:245], t2),
                                np.gradient(alpha[245:], t3)])
    bounds = np.array([0, 45, 245, 345])
    periods = [period, np.nan, period]
    state = SeparationState("ss", kind)
    # U: tau1, tau2, a1, a_star; V: tau1, tau_v, a1, a_star
    theta = np.array([tau1, 0.05 if kind == "U" else 0.3, 40.0, 0.21])

    def value(th):
        return evaluate_state(state, dict(zip(state.base_parameters, th)), alpha, alpha_dot, t, bounds,
                              sensitivities=False, periods=periods)[0]

    x, analytic = evaluate_state(state, dict(zip(state.base_parameters, theta)), alpha, alpha_dot, t, bounds,
                                 periods=periods)
    np.testing.assert_array_equal(value(theta), x)
    assert_matches_finite_difference(analytic, value, theta)


def test_a_lag_at_tau1_zero_is_the_input_and_stays_periodic():
    """tau1 -> 0: X = u; a record of several cycles starts at its input one period later (the limit of the
    periodic start), and dX/dtau1 at the start is the limit of the periodic solution's."""
    t = np.arange(90) * 0.01
    u = np.sin(2 * np.pi * t / 0.3) + 0.05 * t
    bounds = np.array([0, 90])
    period = 0.3 + 0.004
    x, dx, dtau = first_order_lag(t, u, u[:, None].copy(), 0.0, bounds, periods=[period])
    u_end = u[30] + (u[31] - u[30]) * 0.4
    assert x[0] == pytest.approx(u_end, abs=1e-12) and dx[0, 0] == pytest.approx(u_end, abs=1e-12)
    np.testing.assert_array_equal(x[1:], u[1:])
    tiny = 1e-6
    x_tiny, _, _ = first_order_lag(t, u, u[:, None].copy(), tiny, bounds, periods=[period])
    assert (x_tiny[0] - x[0]) / tiny == pytest.approx(dtau[0], rel=1e-3)


@pytest.mark.parametrize("form", ["goman", "two_break", "spline:4"])
def test_a_state_of_another_static_form_starts_periodic_too(form):
    """The periodic start is the lag's, whatever static curve feeds it: a goman, two-break or spline state on one
    cycle starts where it is one period later."""
    from structsearch.engine.static_forms import SEPARATION_STARTS as DEFAULT_START
    period = 0.9
    t = np.arange(72) * period / 72 + 1.0
    alpha = 0.2 + 0.12 * np.sin(2 * np.pi * t / period)
    alpha_dot = 0.12 * 2 * np.pi / period * np.cos(2 * np.pi * t / period)
    state = SeparationState("", "U", form)
    values = {p: DEFAULT_START[p] for p in state.base_parameters}
    values["tau1"] = 0.4
    x, _ = evaluate_state(state, values, alpha, alpha_dot, t, np.array([0, len(t)]), periods=[period])
    u = evaluate_state(SeparationState("", "Q", form), {k: v for k, v in values.items() if k != "tau1"},
                       alpha, alpha_dot, t, np.array([0, len(t)]), sensitivities=False)[0]
    one_period_later = step_lag(x[-1], u[-1], u[0], t[0] + period - t[-1], values["tau1"])
    assert abs(one_period_later - x[0]) < 1e-9
