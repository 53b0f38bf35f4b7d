"""Wing states: the lift model's wing state read at each wing's own angle of attack, alpha + drive p*, declared in a
lateral grid (``states = ["X_left", "X_right"]``, ``drive = {...}``) and fitted with the lift model's parameters
fixed; the two-step covariance moves them with the lift parameters they copy."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conftest import assert_matches_finite_difference
from structsearch.data.errors import DeclarationError
from structsearch.data.flightdata import FlightData
from structsearch.engine.separation import driven_alpha
from structsearch.engine.snls import model_jacobian
from structsearch.engine.stallmodel import StallModel
from structsearch.fitting.candidates import Candidate, parse_drives
from structsearch.fitting.enumeration import expand
from structsearch.flight.synthetic import campaign

B = 11.0


def _with_roll(data: FlightData) -> FlightData:
    cols = dict(data.columns)
    cols["p"] = 0.4 * np.sin(1.7 * data["t"]) + 0.1 * np.cos(0.3 * data["t"])
    return FlightData(cols, data.starts, data.names, data.source, {**data.constants, "b": B})


def test_a_wing_reads_alpha_plus_its_drive_times_the_reduced_roll_rate():
    data = _with_roll(campaign({"quasi-steady": 1, "dynamic": 1}, duration=10.0, seed=2))
    alpha, rate = driven_alpha(data, -0.5)
    pstar = data["p"] * B / (2 * data["V"])
    np.testing.assert_allclose(alpha, data["alpha"] - 0.5 * pstar, rtol=0, atol=1e-15)
    for a, b in zip(data.bounds[:-1], data.bounds[1:]):
        expected = data["alpha_dot"][a:b] - 0.5 * np.gradient(pstar[a:b], data["t"][a:b], edge_order=2)
        np.testing.assert_allclose(rate[a:b], expected, rtol=0, atol=1e-12)
    assert driven_alpha(data, 0.0)[0] is data["alpha"]


def test_the_lift_sensitivity_moves_the_wing_states_with_the_lift_state_they_copy():
    """d(roll output)/d(lift parameter) through both wings' states (copies of the lift's X) and nothing else,
    against central differences."""
    from structsearch.fitting.lift_uncertainty import lift_sensitivity
    data = _with_roll(campaign({"quasi-steady": 1, "dynamic": 2}, duration=20.0, seed=3))
    lift = StallModel.declare("L", "CL", states={"": "U"}, regressors={"CL0": "1", "CL_KL": "K_L(X)"})
    lift_params = {"tau1": 0.3, "tau2": 0.05, "a1": 25.0, "a_star": 0.2, "CL0": 0.1, "CL_KL": 4.0}
    copied = {f"{p}_{w}": lift_params[p] for p in ("tau1", "tau2", "a1", "a_star") for w in ("left", "right")}
    roll = StallModel.declare("R", "Cl", states={"left": "U", "right": "U"}, drives={"left": -0.5, "right": 0.5},
                              regressors={"Cl_p": "pstar", "Cl_drop": "X_left - X_right"}, fixed=copied)
    params = {"Cl_p": -0.4, "Cl_drop": 0.06}

    def output(values):
        moved = dataclasses.replace(roll, fixed={k: values[k.rsplit("_", 1)[0]] for k in roll.fixed})
        return moved.predict(data, params)

    names = lift.nonlinear_names + lift.linear_names
    theta = np.array([lift_params[n] for n in lift.nonlinear_names])
    coef = np.array([lift_params[n] for n in lift.linear_names])
    jac1 = model_jacobian(lift.bind(data).evaluate(theta), coef, len(theta))
    analytic = lift_sensitivity(roll, params, data, jac1, names, lift_params, names,
                                aliases={k: k.rsplit("_", 1)[0] for k in copied})
    assert np.max(np.abs(analytic[:, names.index("a_star")])) > 1e-3     # the wings do move with the lift's a_star
    assert_matches_finite_difference(analytic, lambda x: output(dict(zip(names, x))),
                                     [lift_params[n] for n in names])


GRID = {"name": "r", "coefficient": "Cl", "prefix": "r-", "lift": "CL-II",
        "blocks": {"base": {"Cl0": "1", "Cl_p": "pstar"}, "drop": {"Cl_drop": "X_left - X_right"}},
        "entry": [{"states": ["X_left", "X_right"], "drive": {"X_left": "alpha - 0.5*pstar",
                                                              "X_right": "alpha + 0.5 * pstar"},
                   "always": ["base"], "combinations": [["drop"]]}]}


def test_wing_states_are_declared_parsed_and_written_back():
    (c,) = expand(GRID, "r.toml").candidates
    assert c.wings == (("left", -0.5), ("right", 0.5))
    assert Candidate.from_dict(c.to_dict()) == c
    assert c.to_dict()["drive"] == {"X_left": "alpha - 0.5*pstar", "X_right": "alpha + 0.5*pstar"}
    assert parse_drives({"X_right": "alpha+pstar*0.4"}, "x") == (("right", 0.4),)


@pytest.mark.parametrize("change, words", [
    ({"drive": {"X_left": "alpha - 0.5*pstar", "X_right": "beta + 0.5*pstar"}}, "a wing state X_<name> read at"),
    ({"drive": {"X_left": "alpha - 0.5*pstar", "X_right": "alpha + eta*pstar"}}, "a wing state X_<name> read at"),
    ({"drive": {"left": "alpha - 0.5*pstar"}}, "a wing state X_<name> read at"),
    ({"drive": {"X_left": "alpha - 0.5*pstar", "X_right": "alpha + 0.5*pstar"}, "states": ["X_left", "X_up"]},
     "name different wing states"),
    ({"drive": None}, "give each one's angle of attack"),
    ({"lift": ""}, "give the entry a lift model"),
])
def test_a_malformed_wing_declaration_is_one_error_naming_the_entry(change, words):
    entry = {**GRID["entry"][0], **{k: v for k, v in change.items() if v is not None}}
    if change.get("drive", 1) is None:
        entry.pop("drive")
    grid = {**GRID, "entry": [entry]}
    if change.get("lift") == "":
        grid = {k: v for k, v in grid.items() if k != "lift"}
        entry.pop("lift", None)
    with pytest.raises(DeclarationError, match=words) as err:
        expand(grid, "r.toml")
    assert "r.toml [[entry]] #1" in str(err.value)


def test_a_wing_drop_campaign_is_fitted_best_by_the_wing_pair(tmp_path):
    """c172p flown with a wing drop whose lift stalls with the wings: among the roll grid's structures the lowest
    cross-validated error is one with the wing pair (X_left - X_right), not one with a symmetric state."""
    pytest.importorskip("jsbsim", reason="the jsbsim extra is not installed")
    import structsearch as ss
    from structsearch.foreign.fly import fly_campaign
    from structsearch.foreign.modify import read_modify
    (tmp_path / "drop.toml").write_text(
        "[[wing_drop]]\na_star = 0.30\na1 = 30.0\ntau1 = 0.1\neta = 0.5\nasymmetry = 0.01\nroll = 0.05\n"
        "yaw = 0.01\nfunction = \"aero/coefficient/CLwbh\"\ninput = \"aero/stall-hyst-norm\"\n", encoding="utf-8")
    campaign = fly_campaign("c172p", read_modify(tmp_path / "drop.toml"), scale=0.25, seed=5, lateral=True)
    ranking = ss.search(campaign, "roll", settings=ss.Settings(jobs=2), out=tmp_path / "s", refine=False)
    fitted = [r for r in ranking.grids["roll"] if not r.failed]
    best = min(fitted, key=lambda r: r.cv.mse if r.cv is not None else np.inf)
    assert "Cl_drop" in best.estimates.params, best.name
