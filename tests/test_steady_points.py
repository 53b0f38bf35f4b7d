"""Steady points (a static polar, trim points) beside time series: a maneuver declared ``steady = true`` is a set of
equilibria of the separation states. Its states equal their static value X0(alpha) at every sample, whatever the
time constants; its alpha_dot is zero; the fit places the static curve from it and leaves the dynamics to the
cycles. The truths here are integrated by scipy's Runge-Kutta (tests/airfoil_truths.py), not by the engine."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from structsearch.api import fit
from structsearch.data.campaign import read_campaign, write_campaign
from structsearch.data.errors import DataError
from structsearch.data.flightdata import STEADY, from_segments
from structsearch.engine.separation import SeparationState, evaluate_state, first_order_lag

sys.path.insert(0, str(Path(__file__).parent))
from airfoil_truths import SPEED, TRUTHS, _static, write_campaign as write_truth  # noqa: E402


def _steady_file(directory: Path, truth, alphas, noise: float, seed: int, name: str = "polar") -> None:
    """The truth's static lift at ``alphas`` (X = X0(alpha), no rate) as a steady maneuver of ``directory``."""
    rng = np.random.default_rng(seed)
    x = _static(truth, alphas)
    cl = truth.cl0 + truth.cl_kl * ((1 + np.sqrt(x)) / 2) ** 2 * alphas + rng.normal(0.0, noise, len(alphas))
    rows = ["alpha,q,V,de,CL,CD,Cm"] + [f"{a:.9g},0,{SPEED},0,{c:.9g},0.02,-0.01" for a, c in zip(alphas, cl)]
    (directory / f"{name}.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    with open(directory / "campaign.toml", "a", encoding="utf-8") as manifest:
        manifest.write(f'\n[[maneuver]]\nid = "{name}"\nfile = "{name}.csv"\nkind = "quasi-steady"\nsplit = "train"\n'
                       "steady = true\n")


# ----- the engine: equilibrium at every steady sample ---------------------------------------------------------
def test_a_steady_maneuver_is_its_static_value_with_no_time_constant_acting():
    rng = np.random.default_rng(3)
    t = np.concatenate([np.arange(40) * 0.01, np.arange(15, dtype=float)])
    u = rng.uniform(0, 1, len(t))
    du = rng.normal(size=(len(t), 2))
    bounds = np.array([0, 40, 55])
    x, dx, dtau = first_order_lag(t, u, du, 0.2, bounds, periods=[np.nan, STEADY])
    np.testing.assert_array_equal(x[40:], u[40:])
    np.testing.assert_array_equal(dx[40:], du[40:])
    np.testing.assert_array_equal(dtau[40:], 0.0)
    # the other maneuver is the ordinary lag from equilibrium, untouched by its neighbour
    alone = first_order_lag(t[:40], u[:40], du[:40], 0.2, np.array([0, 40]))
    np.testing.assert_allclose(x[:40], alone[0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(dtau[:40], alone[2], rtol=0, atol=1e-15)
    # and without steady points the last maneuver would lag (the test can fail)
    assert not np.allclose(first_order_lag(t, u, du, 0.2, bounds)[0][40:], u[40:])


@pytest.mark.parametrize("kind", ["U", "L", "V"])
def test_every_lagged_kind_sits_at_its_static_curve_on_steady_points(kind):
    alpha = np.linspace(0.05, 0.45, 12)
    t = np.arange(12, dtype=float)
    state = SeparationState("X", kind)
    values = {"a1": 18.0, "a_star": 0.3, "tau1": 0.4, "tau2": 0.05, "tau_v": 0.3}
    x, dx = evaluate_state(state, values, alpha, np.zeros(12), t, np.array([0, 12]), periods=[STEADY])
    expected = np.zeros(12) if kind == "V" else 0.5 * (1 - np.tanh(18.0 * (alpha - 0.3)))
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-14)
    for name in ("tau1", "tau2", "tau_v"):
        if name in state.base_parameters:
            np.testing.assert_array_equal(dx[:, state.base_parameters.index(name)], 0.0)


# ----- the campaign: reading, writing, refusing ----------------------------------------------------------------
def test_a_steady_file_needs_no_time_and_reads_with_zero_rate_and_infinite_period(tmp_path):
    truth = TRUTHS["symmetric"]
    write_truth(truth, tmp_path, seed=5)
    _steady_file(tmp_path, truth, np.radians(np.arange(-4.0, 26.0, 2.0)), 0.01, seed=6)
    campaign = read_campaign(tmp_path)
    assert campaign.maneuvers[-1].steady
    rows = campaign.data.segment_slices()[-1]
    np.testing.assert_array_equal(campaign.data["alpha_dot"][rows], 0.0)
    assert campaign.data.period_array[-1] == np.inf
    assert np.isnan(campaign.data.period_array[0])
    again = read_campaign(write_campaign(campaign, tmp_path / "copy"))
    assert again.maneuvers[-1].steady and again.data.period_array[-1] == np.inf
    np.testing.assert_array_equal(again.data["CL"], campaign.data["CL"])


@pytest.mark.parametrize("entry, column, words", [
    ('steady = "yes"', "steady", "true or false"),
    ("steady = true\nfrequency = 1.0", "steady", "no cycle"),
    ('steady = true\nsegment = "cycles"', "segment", "not cut"),
])
def test_a_bad_steady_declaration_is_one_error_naming_its_key(tmp_path, entry, column, words):
    truth = TRUTHS["symmetric"]
    write_truth(truth, tmp_path, seed=5)
    _steady_file(tmp_path, truth, np.radians(np.arange(0.0, 20.0, 2.0)), 0.01, seed=6)
    text = (tmp_path / "campaign.toml").read_text(encoding="utf-8").replace("steady = true", entry)
    (tmp_path / "campaign.toml").write_text(text, encoding="utf-8")
    with pytest.raises(DataError) as err:
        read_campaign(tmp_path)
    assert err.value.column == column and words in str(err.value)


def test_a_moving_alpha_at_a_steady_point_names_its_row(tmp_path):
    truth = TRUTHS["symmetric"]
    write_truth(truth, tmp_path, seed=5)
    _steady_file(tmp_path, truth, np.radians(np.arange(0.0, 20.0, 2.0)), 0.01, seed=6)
    polar = tmp_path / "polar.csv"
    lines = polar.read_text(encoding="utf-8").splitlines()
    lines[0] += ",alpha_dot"
    lines[1:] = [line + (",0.3" if i == 4 else ",0") for i, line in enumerate(lines[1:])]
    polar.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(DataError) as err:
        read_campaign(tmp_path)
    assert err.value.column == "alpha_dot" and err.value.row == 4 and "polar.csv" in str(err.value)


def test_steady_points_in_memory_have_no_rate():
    alpha = np.linspace(0.0, 0.3, 6)
    data = from_segments([{"t": np.arange(6.0), "alpha": alpha}], periods=[STEADY])
    np.testing.assert_array_equal(data["alpha_dot"], 0.0)


# ----- the fit: the static curve from the polar, the dynamics from the cycles ---------------------------------
SPEC = """name = "one-state"
coefficient = "CL"
prefix = "S-"

[[entry]]
name = "S-U"
states = { "" = "U" }
regressors = { CL_KL = "K_L(X)" }
"""


def _one_run(directory: Path) -> None:
    """Keep one training run of the truth's campaign (a cycle too few to place the static curve well)."""
    text = (directory / "campaign.toml").read_text(encoding="utf-8")
    head, *entries = text.split("[[maneuver]]")
    kept = [e for e in entries if "train_1p00hz" in e or 'split = "validation"' in e]
    (directory / "campaign.toml").write_text(head + "".join("[[maneuver]]" + e for e in kept), encoding="utf-8")


def test_a_static_polar_beside_one_cycle_places_the_static_curve(tmp_path):
    """One training run of three cycles at 1 Hz, with and without the polar's steady points (every 1.5 deg, noise
    0.01): with them the static curve's standard errors shrink to half or less (measured on seeds 21, 31, 41:
    a1 by 3.7 to 5.6 times, a_star by 2 to 2.5 times), and every parameter stays near the truth's."""
    truth = TRUTHS["symmetric"]
    spec = tmp_path / "one.toml"
    spec.write_text(SPEC, encoding="utf-8")
    alone, with_polar = tmp_path / "alone", tmp_path / "polar"
    for directory in (alone, with_polar):
        write_truth(truth, directory, seed=21)
        _one_run(directory)
    _steady_file(with_polar, truth, np.radians(np.arange(-12.0, 28.0, 1.5)), 0.01, seed=22)
    estimates = {d.name: fit(d, str(spec)).result.estimates for d in (alone, with_polar)}
    for name in ("a1", "a_star"):
        assert estimates["polar"].stderr[name] < 0.5 * estimates["alone"].stderr[name], name
    params = estimates["polar"].params
    assert abs(np.degrees(params["a_star"] - truth.a_star)) < 0.5
    for name, value in (("a1", truth.a1), ("tau1", truth.tau1), ("tau2", truth.tau2), ("CL_KL", truth.cl_kl)):
        assert abs(params[name] - value) / value < 0.1, name
