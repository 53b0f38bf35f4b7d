"""Anomalies (effects outside the library) the simulator flies, and truth-based differences."""
import dataclasses

import numpy as np
import pytest

from structsearch.data.errors import DeclarationError
from structsearch.engine.separation import SeparationState, evaluate_state, static_separation
from structsearch.flight.aero import WITHHOLDABLE, truth_model
from structsearch.flight.anomalies import (ANOMALIES, COMPRESSIBILITY_GAIN, EFFECT_COEFFICIENT, ELEVATOR_LOSS_GAIN,
                                           H_REF, V_REF, flown_states, truth_difference)
from structsearch.data.campaign import Maneuver, make_campaign
from structsearch.flight.aircraft import CITATION
from structsearch.flight.flighttest import build_campaign, simulate_campaign, thesis_plan
from structsearch.flight.reference import FINAL_LIFT, FINAL_PITCH

SEED, SCALE = 4, 0.05
TRUTH_COLUMNS = ("t", "V", "q", "de", "h", "theta", "CT", "mass", "x_cg", "Cm", "CL_true", "CD_true", "Cm_true",
                 "X_ss_true", "X_w_true")


@pytest.fixture(scope="module")
def default():
    return build_campaign(seed=SEED, scale=SCALE)


@pytest.fixture(scope="module")
def vane(default):
    return build_campaign(seed=SEED, scale=SCALE, anomaly="vane_lag")


_built = {}


def flown(anomaly, numbers=(1, 7)):
    """Maneuvers of one duration (one batch of the simulator; default: two quasi-steady stalls, at FL 80-110
    and 150-200) flown with ``anomaly``, assembled as build_campaign does; built once per module run."""
    if anomaly not in _built:
        a = ANOMALIES[anomaly]
        plan = [p for p in thesis_plan() if p.number in numbers]
        segments = simulate_campaign(plan, truth_model(anomaly=a), SEED, anomaly=a)
        _built[anomaly] = make_campaign(
            f"two stalls with {anomaly}", CITATION.manifest(5500.0),
            [Maneuver(p.id, f"{p.id}.csv", p.kind, p.split) for p in plan], segments,
            {"withheld": "none", "anomaly": anomaly})
    return _built[anomaly]


def K_L(x):
    return ((1 + np.sqrt(x)) / 2) ** 2


def final_cl(alpha, x_ss, x_w, data):
    p = FINAL_LIFT
    return (p["CL0"] + p["CL_KL_ss"] * K_L(x_ss) * alpha + p["CL_KL_w"] * K_L(x_w) * alpha
            + p["CL_qstar"] * data["q"] * data.constants["cbar"] / data["V"] + p["CL_de"] * data["de"])


# ----- registry and default campaigns ---------------------------------------------------------------------
def test_registry(default):
    assert {"reattachment_delay", "vane_lag", "compressibility", "reynolds_stall", "tail_aeroelastic"} <= set(ANOMALIES)
    for name, a in ANOMALIES.items():
        assert a.name == name and a.coefficient in ("CL", "CD", "Cm") and a.description.endswith(".")
        assert a.signal in default.data.columns
        assert a.name not in WITHHOLDABLE


def test_effect_coefficients_agree_with_the_withheld_benchmark():
    from structsearch.diagnosis.withheld import WITHHELD
    assert set(EFFECT_COEFFICIENT) == set(WITHHOLDABLE)
    for effect, (coefficient, _, _) in WITHHELD.items():
        assert EFFECT_COEFFICIENT[effect] == coefficient


def test_default_campaign_is_unchanged_and_carries_no_anomaly(default):
    again = build_campaign(seed=SEED, scale=SCALE, anomaly=None)
    assert again.name == default.name and dict(again.extra) == dict(default.extra)
    assert set(again.data.columns) == set(default.data.columns)
    for k in default.data.columns:
        assert np.array_equal(again.data[k], default.data[k]), k
    assert "anomaly" not in default.extra and default.name.endswith("(seed 4)")
    assert "alpha_true" not in default.data and "alpha_unlagged_true" not in default.data


def test_an_anomaly_is_recorded_and_leaves_the_random_streams_alone(default, vane):
    c = vane
    assert c.extra["anomaly"] == "vane_lag" and "anomaly vane_lag" in c.name
    assert {k: v for k, v in c.extra.items() if k != "anomaly"} == dict(default.extra)
    assert "alpha_true" in c.data and "alpha_unlagged_true" in c.data
    # a measurement-side anomaly flies the same truth with the same profiles and sensor errors
    for k in TRUTH_COLUMNS:
        assert np.array_equal(c.data[k], default.data[k]), k
    assert not np.array_equal(c.data["alpha"], default.data["alpha"])
    # the chain without the lag reads what the default campaign recorded
    assert np.array_equal(c.data["alpha_unlagged_true"], default.data["alpha"])


# ----- each anomaly changes the truth as described --------------------------------------------------------
def test_vane_lag_lags_the_recorded_alpha(vane):
    c = vane
    tau = ANOMALIES["vane_lag"].vane_lag_s
    inner = np.concatenate([np.arange(s.start + 300, s.stop - 300) for s in c.data.segment_slices()])
    # a first-order lag: reading + tau * d(reading)/dt = input (the pre-filter is linear and commutes)
    gap = (c.data["alpha_unlagged_true"] - c.data["alpha"])[inner]
    rate = c.data["alpha_dot"][inner]
    estimate = float(gap @ rate / (rate @ rate))
    assert estimate == pytest.approx(tau, rel=0.03)
    assert np.max(np.abs(gap - tau * rate)) < 0.1 * np.max(np.abs(gap))
    d = truth_difference(c, "vane_lag")
    assert ANOMALIES["vane_lag"].coefficient == "Cm" and np.sqrt(np.mean(d ** 2)) > 1e-3
    d_cl = truth_difference(c, "vane_lag", "CL")
    # the lift the lag hides grows with the rate: C_L,alpha * tau * alpha_dot at attached flow
    attached = inner[(c.data["X_w_true"][inner] > 0.99) & (c.data["X_ss_true"][inner] > 0.9999)]
    slope = np.polyfit(c.data["alpha_dot"][attached], d_cl[attached], 1)[0]
    assert slope == pytest.approx((FINAL_LIFT["CL_KL_ss"] + FINAL_LIFT["CL_KL_w"]) * tau, rel=0.25)


def test_reattachment_delay_acts_only_while_alpha_falls():
    c = flown("reattachment_delay", (46,))  # a deep dynamic stall: oscillations around alpha*_w
    data = c.data
    delay = dict(ANOMALIES["reattachment_delay"].reattachment)["X_w"]
    static = static_separation(data["alpha_true"], FINAL_LIFT["a1_w"], FINAL_LIFT["a_star_w"])
    # (the measured alpha_dot, off the truth's by a little: its sign is the truth's but near zero crossings)
    rising, falling = data["alpha_dot"] > 0.01, data["alpha_dot"] < -0.01
    assert rising.sum() > 1000 and falling.sum() > 1000
    assert np.mean(data["X_w_true"][rising] == static[rising]) > 0.99        # no delay while separating
    assert np.mean(data["X_w_true"][falling] < static[falling]) > 0.99       # reattaches late
    late = static_separation(data["alpha_true"] + delay * np.abs(data["alpha_dot"]), FINAL_LIFT["a1_w"],
                             FINAL_LIFT["a_star_w"])
    assert np.median(np.abs(data["X_w_true"] - late)[falling]) < 0.1 * np.median((static - late)[falling])
    # on the flown states: the wing's state is the final model's while alpha rises, lower while it falls
    actual = flown_states(truth_model(anomaly=ANOMALIES["reattachment_delay"]), data)
    final = flown_states(truth_model(), data)
    up, down = data["alpha_dot"] > 0, data["alpha_dot"] < 0
    assert np.array_equal(actual["X_w"][up], final["X_w"][up]) and np.all(actual["X_w"][down] < final["X_w"][down])
    d = truth_difference(c, "reattachment_delay")
    assert np.all(d[data["alpha"] > 0] <= 1e-12)   # less lift wherever the flow reattaches late
    assert np.sqrt(np.mean(d ** 2)) > 0.01


def test_reynolds_stall_lowers_alpha_star_with_altitude():
    c = flown("reynolds_stall")
    data = c.data
    shift = dict(ANOMALIES["reynolds_stall"].stall_shift)["X_w"]
    x = data["X_w_true"]
    ok = (x > 0.02) & (x < 0.98)
    implied = data["alpha_true"][ok] - np.log(1 / x[ok] - 1) / (2 * FINAL_LIFT["a1_w"])
    expected = FINAL_LIFT["a_star_w"] + shift * (data["h"][ok] - H_REF) / 1000
    assert np.max(np.abs(implied - expected)) < 1e-3
    h = data["h"][ok]
    assert h.max() - h.min() > 1500 and np.corrcoef(h, implied)[0, 1] < -0.99
    d = truth_difference(c, "reynolds_stall")
    positive = data["alpha"] > 0
    assert np.all(d[positive & (data["h"] > H_REF + 50)] <= 1e-12)
    assert np.all(d[positive & (data["h"] < H_REF - 50)] >= -1e-12)
    assert np.min(d) < -0.02 and np.max(d) > 0.02


def test_compressibility_grows_the_lift_slope_with_airspeed():
    c = flown("compressibility")
    data = c.data
    factor = (data["V"] / V_REF) ** 2 - 1
    kirchhoff = (FINAL_LIFT["CL_KL_ss"] * K_L(data["X_ss_true"]) + FINAL_LIFT["CL_KL_w"] * K_L(data["X_w_true"])) \
        * data["alpha_true"]
    # the truth minus the final model on the same (truth) states
    gap = data["CL_true"] - final_cl(data["alpha_true"], data["X_ss_true"], data["X_w_true"], data)
    k = COMPRESSIBILITY_GAIN
    assert np.std(k * factor * kirchhoff) > 0.05
    assert np.max(np.abs(gap - k * factor * kirchhoff)) < 0.02
    assert np.corrcoef(gap, data["V"])[0, 1] > 0.8
    d = truth_difference(c, "compressibility")
    positive = data["alpha"] > 0
    assert np.all(d[positive & (data["V"] > V_REF)] > 0) and np.all(d[positive & (data["V"] < V_REF)] < 0)


def test_two_break_stall_flies_a_two_step_strip_of_more_lift():
    from structsearch.engine.static_forms import static_value
    from structsearch.flight.anomalies import TWO_BREAK_LIFT, TWO_BREAK_SS
    c = flown("two_break_stall")
    data = c.data
    p = FINAL_LIFT
    # the strips' state lags the two-break curve as the final model's lags its tanh (tau1 0.42 s): where alpha is
    # slow and away from both breaks, the state is the curve's value (the plateau's between them)
    a = data["alpha_true"]
    breaks = np.array([0.12, 0.28])
    steady = (np.abs(data["alpha_dot"]) < 0.002) & (np.min(np.abs(a[:, None] - breaks), axis=1) > 0.04)
    assert np.any(steady & (a > 0.16) & (a < 0.24))
    assert np.max(np.abs(data["X_ss_true"][steady] - static_value("two_break", data["alpha_true"][steady],
                                                                  dict(TWO_BREAK_SS)))) < 0.05
    # the truth minus the final model on the same (truth) states: the strips' extra lift (measured signals in
    # final_cl: a few 1e-4 apart)
    gap = data["CL_true"] - final_cl(a, data["X_ss_true"], data["X_w_true"], data)
    extra = (TWO_BREAK_LIFT - 1) * p["CL_KL_ss"] * K_L(data["X_ss_true"]) * a
    assert np.std(extra) > 0.05 and np.max(np.abs(gap - extra)) < 0.005
    # the plateau: the curve holds x_mid over most of the 0.16 rad between its breaks
    plateau = static_value("two_break", np.array([0.15, 0.2, 0.25]), dict(TWO_BREAK_SS))
    assert np.all(np.abs(plateau - dict(TWO_BREAK_SS)["x_mid"]) < 0.01)


def test_tail_aeroelastic_loses_elevator_effectiveness_with_airspeed():
    c = flown("tail_aeroelastic")
    data = c.data
    model = truth_model()
    values = {k: data[k] for k in data.columns}
    values.update(data.constants)
    values.update(alpha=data["alpha_true"], CL=data["CL_true"], X_ss=data["X_ss_true"], X_w=data["X_w_true"])
    gap = data["Cm_true"] - model.coefficient("Cm", values)
    k = ELEVATOR_LOSS_GAIN
    expected = -k * ((data["V"] / V_REF) ** 2 - 1) * FINAL_PITCH["Cm_de"] * data["de"]
    assert np.std(expected) > 0.005
    assert np.max(np.abs(gap - expected)) < 0.1 * np.max(np.abs(expected))
    d = truth_difference(c, "tail_aeroelastic")
    assert np.corrcoef(d, expected)[0, 1] > 0.99
    # C_L is untouched: the lift difference is exactly zero
    assert np.array_equal(truth_difference(c, "tail_aeroelastic", "CL"), np.zeros(data.n_samples))


# ----- truth differences of withheld effects --------------------------------------------------------------
def test_pitch_rate_difference_is_the_q_star_term(default):
    data = default.data
    d = truth_difference(default, "pitch_rate")
    expected = FINAL_LIFT["CL_qstar"] * data["q"] * data.constants["cbar"] / data["V"]
    np.testing.assert_allclose(d, expected, rtol=1e-12, atol=1e-15)
    # a campaign flown without the effect: the data lack it, the sign turns
    withheld = dataclasses.replace(default, extra=dict(default.extra, withheld="pitch_rate"))
    np.testing.assert_allclose(truth_difference(withheld, "pitch_rate"), -expected, rtol=1e-12, atol=1e-15)


def test_cp_shift_difference_by_hand(default):
    data = default.data
    p = FINAL_LIFT
    x_ss = evaluate_state(SeparationState("ss", "U"),
                          {"tau1": p["tau1_ss"], "tau2": p["tau2_ss"], "a1": p["a1_ss"], "a_star": p["a_star_ss"]},
                          data["alpha"], data["alpha_dot"], data["t"], data.bounds)[0]
    x_w = static_separation(data["alpha"], p["a1_w"], p["a_star_w"])
    cl = final_cl(data["alpha"], x_ss, x_w, data)
    effect = (FINAL_PITCH["Cm_1mX_ssCL"] * (1 - x_ss) + FINAL_PITCH["Cm_1mX_wCL"] * (1 - x_w)) * cl
    d = truth_difference(default, "cp_shift")
    np.testing.assert_allclose(d, effect, rtol=1e-9, atol=1e-14)
    # zero where the flow is attached (to rounding), nonzero where it separates
    attached = (1 - x_ss < 1e-9) & (1 - x_w < 1e-9)
    assert np.all(np.abs(d[attached]) <= 1e-9)
    bound = (abs(FINAL_PITCH["Cm_1mX_ssCL"]) * (1 - x_ss) + abs(FINAL_PITCH["Cm_1mX_wCL"]) * (1 - x_w)) * np.abs(cl)
    assert np.all(np.abs(d) <= bound * (1 + 1e-9) + 1e-15)
    assert np.all(np.abs(d[1 - x_w > 0.1]) > 1e-4)
    # the flown states are the engine's
    states = flown_states(truth_model(), data)
    np.testing.assert_allclose(states["X_ss"], x_ss, rtol=0, atol=1e-12)


def test_second_state_and_lag_differences(default):
    data = default.data
    x_w = static_separation(data["alpha"], FINAL_LIFT["a1_w"], FINAL_LIFT["a_star_w"])
    d = truth_difference(default, "second_separation_state")
    np.testing.assert_allclose(d, FINAL_LIFT["CL_KL_w"] * data["alpha"] * (K_L(x_w) - 1), rtol=1e-9, atol=1e-14)
    lag = truth_difference(default, "unsteady_lag")
    assert np.sqrt(np.mean(lag ** 2)) > 1e-3
    # a drag or pitch difference of a lift effect goes through each model's own C_L
    assert np.sqrt(np.mean(truth_difference(default, "unsteady_lag", "Cm") ** 2)) > 1e-4


# ----- errors ---------------------------------------------------------------------------------------------
def test_errors(default):
    with pytest.raises(DeclarationError, match="reattachment_delay.*tail_aeroelastic"):
        build_campaign(seed=1, scale=0.05, anomaly="gust")
    with pytest.raises(DeclarationError, match="Citation II only"):
        build_campaign(seed=1, scale=0.05, anomaly="vane_lag", aircraft="transport")
    with pytest.raises(DeclarationError, match="withheld"):
        build_campaign(seed=1, scale=0.05, anomaly="compressibility", withhold=["pitch_rate"])
    with pytest.raises(DeclarationError, match="not flown with the anomaly"):
        truth_difference(default, "compressibility")
    with pytest.raises(DeclarationError, match="no effect 'gust'"):
        truth_difference(default, "gust")
    with pytest.raises(DeclarationError, match="X_w"):
        truth_model(aircraft="transport", anomaly=ANOMALIES["reynolds_stall"])


def test_a_campaign_read_from_disk_knows_its_anomaly(vane, tmp_path):
    from structsearch.data.campaign import read_campaign, write_campaign
    from structsearch.flight.anomalies import flown_with
    write_campaign(vane, tmp_path / "c")
    back = read_campaign(tmp_path / "c")
    assert flown_with(back)["anomaly"] == "vane_lag"
    np.testing.assert_allclose(truth_difference(back, "vane_lag"), truth_difference(vane, "vane_lag"), atol=1e-12)
