"""Lateral flights in JSBSim (``simulate --jsbsim NAME --lateral``): each input flown and the moment it makes
checked for the sign the data guide states; the lateral coefficients reconstructed from the measured rates and
lateral acceleration follow JSBSim's own (its body-axis aerodynamic side force and moments about the cg); the longitudinal columns are
those of the same campaign flown without the lateral plan."""
from __future__ import annotations

import numpy as np
import pytest

jsbsim = pytest.importorskip("jsbsim", reason="the jsbsim extra is not installed")

from structsearch.data.campaign import LATERAL_KINDS, read_campaign  # noqa: E402
from structsearch.foreign.fly import RATE_HZ, Planned, fly_campaign, fly_one  # noqa: E402
from structsearch.foreign.aircraft_xml import read_aircraft  # noqa: E402
from structsearch.foreign.lateral_plan import LATERAL_PLAN  # noqa: E402


def _fly(kind: str) -> dict:
    aircraft = read_aircraft("c172p")
    p = Planned("j01", kind, "train", 8.0, 70.0, 5000.0, 1.0)
    return fly_one(jsbsim, str(aircraft.root), aircraft, p, lateral=True)


def _window(truth: dict, a: float, b: float) -> slice:
    return slice(int(a * RATE_HZ), int(b * RATE_HZ))


def test_each_lateral_input_makes_the_moment_of_the_stated_sign():
    """The first doublet's onset (3.15 to 3.4 s, before the motion it starts feeds back): a positive aileron
    (JSBSim's left aileron trailing edge down) makes a rolling moment right wing down and the aircraft rolls right;
    a positive rudder (trailing edge left) a yawing moment nose left and a side force to the right, and the aircraft
    yaws left."""
    aileron = _fly("aileron-doublet")
    lat, w = aileron["lateral"], _window(aileron, 3.15, 3.4)
    assert np.all(lat["da"][w] > 0.01)
    assert np.all(lat["Cl"][w] > 0.002) and lat["p"][int(3.8 * RATE_HZ)] > 0.05
    rudder = _fly("rudder-doublet")
    lat, w = rudder["lateral"], _window(rudder, 3.15, 3.4)
    assert np.all(lat["dr"][w] > 0.01)
    assert np.all(lat["Cn"][w] < -0.001) and np.all(lat["CY"][w] > 0.002) and lat["r"][int(3.8 * RATE_HZ)] < -0.02


@pytest.fixture(scope="module")
def lateral_campaign(tmp_path_factory):
    from structsearch.data.campaign import write_campaign
    campaign = fly_campaign("c172p", scale=0.25, seed=3, lateral=True)
    return read_campaign(write_campaign(campaign, tmp_path_factory.mktemp("lateral") / "c"))


def test_the_lateral_plan_is_flown_and_every_maneuver_has_the_lateral_channels(lateral_campaign):
    assert set(LATERAL_PLAN) == set(LATERAL_KINDS)
    kinds = [m.kind for m in lateral_campaign.maneuvers]
    assert set(LATERAL_KINDS) <= set(kinds) and kinds.count("quasi-steady") == 2
    aircraft = lateral_campaign.aircraft
    assert aircraft["Ixx"] > 0 and aircraft["Izz"] > aircraft["Ixx"]
    data = lateral_campaign.data
    for column in ("beta", "p", "r", "da", "dr", "CY", "Cl", "Cn", "phi", "qbar"):
        assert np.all(np.isfinite(data[column])), column
    # the pilot holds the bank: no lateral maneuver rolls past 60 deg (open loop, c172p is spirally unstable)
    for m, rows in zip(lateral_campaign.maneuvers, data.segment_slices()):
        if m.kind in LATERAL_KINDS:
            assert np.max(np.abs(data["phi"][rows])) < np.radians(60), m.id


def test_the_lateral_coefficients_are_reconstructed_within_the_sensors_noise(lateral_campaign):
    """The reduction (moment equations with the measured rates' derivatives, the engine removed) against JSBSim's
    aerodynamic coefficients about the cg: on the lateral maneuvers the error's RMS is a small part of what the
    coefficient spans (the bounds: the sensor noise through the pre-filter, about a tenth of these)."""
    data = lateral_campaign.data
    rows = np.concatenate([np.arange(s.start, s.stop) for m, s in zip(lateral_campaign.maneuvers,
                                                                       data.segment_slices())
                           if m.kind in LATERAL_KINDS])
    for coefficient, share in (("CY", 0.08), ("Cl", 0.03), ("Cn", 0.03)):
        error = data[coefficient][rows] - data[f"{coefficient}_true"][rows]
        span = np.ptp(data[f"{coefficient}_true"][rows])
        assert np.sqrt(np.mean(error ** 2)) < share * span, coefficient
        assert abs(np.mean(error)) < 0.5 * share * span, coefficient


def test_the_longitudinal_columns_do_not_change_with_the_lateral_plan(lateral_campaign):
    plain = fly_campaign("c172p", scale=0.25, seed=3)
    flown = {m.id: rows for m, rows in zip(lateral_campaign.maneuvers, lateral_campaign.data.segment_slices())}
    for m, rows in zip(plain.maneuvers, plain.data.segment_slices()):
        lateral = {c: lateral_campaign.data[c][flown[m.id]] for c in ("Cm", "p", "r")}
        for column in ("alpha", "q", "V", "de", "CL", "CD"):
            # read back from the written files: equal to the written digits
            np.testing.assert_allclose(lateral_campaign.data[column][flown[m.id]], plain.data[column][rows],
                                       rtol=1e-12, atol=1e-15, err_msg=f"{m.id} {column}")
        # C_m gains the pitch equation's inertial coupling, which the roll and yaw rates measured make known:
        # a few thousandths where the stall rolls the aircraft off, following p r
        change = lateral["Cm"] - plain.data["Cm"][rows]
        assert 0 < np.max(np.abs(change)) < 0.01, m.id
        assert np.corrcoef(change, lateral["p"] * lateral["r"])[0, 1] < -0.9, m.id    # I_xx < I_zz
        assert "beta" not in plain.data


def test_lateral_without_jsbsim_is_one_error(tmp_path):
    from conftest import run_cli
    r = run_cli("simulate", "--lateral", "--out", tmp_path / "c")
    assert r.returncode == 2 and "--lateral goes with --jsbsim" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "c").exists()


GIVEN = {"fcs/flap-pos-deg": 0.0, "propulsion/engine/prop-induced-velocity_fps": "prop_induced_fps"}


def test_a_jsbsim_aircraft_s_lateral_coefficients_term_by_term_are_its_own(lateral_campaign):
    """The stock c172p evaluated term by term at the recorded states (``diagnose --simulator``'s baseline) against
    the coefficients JSBSim flew (its body-axis side force, its moments about the cg): they differ by what the
    sensors' noise moves the states by. Without the moment's transfer to the cg C_l would be off by the lift's arm
    (the cg 1.3 in left of the plane of symmetry: about -0.0025 on average); without the drag's turn by the
    sideslip C_Y by C_D beta."""
    from structsearch.foreign.baseline import jsbsim_baseline
    data = lateral_campaign.data
    for coefficient, max_mean in (("CY", 1e-3), ("Cl", 3e-4), ("Cn", 2e-4)):
        baseline = jsbsim_baseline("c172p", lateral_campaign, coefficient, GIVEN)
        truth = data[f"{coefficient}_true"]
        error = baseline.values - truth
        assert 1 - np.mean(error ** 2) / np.var(truth) > 0.99, coefficient
        assert abs(np.mean(error)) < max_mean, (coefficient, np.mean(error))
        assert "sim:transfer" in baseline.terms and f"sim:aero/coefficient/{coefficient}b" in baseline.terms


def test_roll_damping_the_flight_lacks_is_found_as_the_simulator_s_clp_rescaled(tmp_path):
    """c172p flown with half its roll damping (``--modify``: Clp x 0.5) and diagnosed against the stock aircraft:
    the first move rescales the simulator's Clp, to 0.5 within 3 % (the reduction's noise in the roll rate's
    derivative moves it: 0.492 measured on this seed), and the gap is then explained."""
    import structsearch as ss
    campaign = fly_campaign("c172p", {"aero/coefficient/Clp": 0.5}, scale=0.25, seed=5, lateral=True)
    found = ss.diagnose(campaign, coefficient="Cl", simulator="jsbsim:c172p", settings=ss.Settings(jobs=2),
                        simulator_inputs=[f"{k}={v}" for k, v in GIVEN.items()])
    first = found.rounds[0].adopted
    assert first == "rescale sim:aero/coefficient/Clp", first
    factor = found.simulator["terms"]["sim:aero/coefficient/Clp"]
    assert abs(factor["factor"] - 0.5) < 0.015, factor
    assert found.explained
