"""Periodic maneuvers in a campaign (docs/interfaces.md 7.5): ``periodic = true``, a phase-averaged cycle without a
time column read with the ``frequency`` of its [[maneuver]] entry, the period carried through selections, and a fit
whose states start at their periodic solution."""
import numpy as np
import pandas as pd
import pytest

from structsearch.data.campaign import read_campaign, write_campaign
from structsearch.data.errors import DataError
from structsearch.data.flightdata import from_segments
from structsearch.fitting.models import build_model
from structsearch.fitting.specs import load_grid
from structsearch.flight.synthetic import ar1_noise, pitching_airfoil

# a pitching airfoil (as tests/test_short_records.py): cbar 0.5 m at 38.5 m/s, a 0.83 s cycle
CBAR, V, PERIOD, N = 0.5, 38.5, 0.83, 415
TRUTH = {"tau1": 0.12, "tau2": 0.02, "a1": 25.0, "a_star": 0.30, "CL0": 0.05, "CL_KL": 5.5}


def _cycle(seed=1, noise=0.005, phase=np.pi / 2):
    """One phase-averaged cycle of N samples (no time column), starting at alpha's maximum by default, where the
    lagged state is farthest from its equilibrium, with C_L of CL-II flown periodically plus AR(1) noise."""
    cols = pitching_airfoil(cycles=1.0, period=PERIOD, dt=PERIOD / N, airspeed=V, phase=phase, seed=seed)
    data = from_segments([cols], names=["c"], constants={"cbar": CBAR}, periods=[PERIOD])
    cl = build_model(load_grid("lift")["CL-II"]).predict(data, TRUTH)
    cols["CL"] = cl + (ar1_noise(np.random.default_rng(seed + 100), len(cl), 0.9, noise) if noise else 0.0)
    return {k: v for k, v in cols.items() if k not in ("t", "alpha_dot")}


def _campaign(path, entry='frequency = 1.2048192771084338\n', cycles=None, time=False):
    path.mkdir(parents=True, exist_ok=True)
    text = f'name = "wind tunnel"\n[aircraft]\nS = 0.5\ncbar = {CBAR}\nb = 1.0\n'
    for i, cols in enumerate(cycles or [_cycle()]):
        if time:
            cols = {"t": np.arange(len(cols["alpha"])) * PERIOD / len(cols["alpha"]), **cols}
        pd.DataFrame(cols).to_csv(path / f"c{i}.csv", index=False, float_format="%.17g")
        text += (f'[[maneuver]]\nid = "c{i}"\nfile = "c{i}.csv"\nkind = "dynamic"\n'
                 f'split = "{"train" if i == 0 else "validation"}"\n{entry}')
    (path / "campaign.toml").write_text(text)
    return path


def test_a_cycle_without_time_reads_with_its_frequency(tmp_path):
    campaign = read_campaign(_campaign(tmp_path / "c"))
    data = campaign.data
    assert data.periods == pytest.approx((PERIOD,)) and campaign.maneuvers[0].periodic
    np.testing.assert_allclose(data["t"], np.arange(N) * PERIOD / N, rtol=0, atol=1e-15)
    # alpha_dot is derived across the cycle's ends as the periodic signal it is: within 1e-3 of the exact rate
    exact = pitching_airfoil(cycles=1.0, period=PERIOD, dt=PERIOD / N, airspeed=V, phase=np.pi / 2)["alpha_dot"]
    assert np.max(np.abs(data["alpha_dot"] - exact)) < 1e-3 * np.max(np.abs(exact))


def test_the_period_survives_selection_writing_and_reading(tmp_path):
    campaign = read_campaign(_campaign(tmp_path / "c", cycles=[_cycle(1), _cycle(2)], entry="periodic = true\n",
                                       time=True))
    assert campaign.data.periods == pytest.approx((PERIOD, PERIOD))   # one cycle: duration and one step
    assert campaign.split("validation").periods == pytest.approx((PERIOD,))
    assert campaign.data.with_columns(dict(campaign.data.columns)).periods == campaign.data.periods
    again = read_campaign(write_campaign(campaign, tmp_path / "written"))
    assert again.data.periods == pytest.approx(campaign.data.periods, rel=1e-12)
    assert [m.periodic for m in again.maneuvers] == [True, True]


def test_a_fit_of_a_periodic_cycle_recovers_the_truth_and_its_states_are_periodic(tmp_path):
    """The issue's target: the states of a periodic record start within 1e-6 of their value one cycle later. The
    cycle starts at alpha's maximum, where the lag is farthest behind: read as periodic the fit recovers CL-II's
    parameters; read as a record whose states start in equilibrium it fits worse."""
    model = build_model(load_grid("lift")["CL-II"])
    periodic = read_campaign(_campaign(tmp_path / "c")).split("train")
    fit = model.fit(periodic)
    values = fit.estimates.params
    for name, truth in TRUTH.items():
        assert values[name] == pytest.approx(truth, rel=0.1), name
    problem = model.bind(periodic)
    theta = np.array([values[n] for n in model.nonlinear_names])
    x = problem.state_values(theta, False)["X"][1]
    t = periodic["t"]
    tau1 = values["tau1"]
    # one more step of the lag, from the last sample to one period after the first, with the input wrapped
    alpha_eff = periodic["alpha"] - values["tau2"] * periodic["alpha_dot"]
    u = 1 / (1 + np.exp(2 * values["a1"] * (alpha_eff - values["a_star"])))
    h = t[0] + PERIOD - t[-1]
    a = np.exp(-h / tau1)
    g = tau1 * (1 - a) / h
    one_cycle_later = a * x[-1] + (g - a) * u[-1] + (1 - g) * u[0]
    assert abs(one_cycle_later - x[0]) < 1e-6
    equilibrium = read_campaign(_campaign(tmp_path / "e", entry="", time=True)).split("train")
    assert equilibrium.periods is None
    assert model.fit(equilibrium).mse > 10 * fit.mse   # measured: 125 times


@pytest.mark.parametrize("entry, column, message", [
    ("", "t", "required column is missing .a phase-averaged cycle without time stamps: give its frequency"),
    ("frequency = 0\n", "frequency", "frequency must be a positive finite number"),
    ("frequency = -1.2\n", "frequency", "frequency must be a positive finite number"),
    ("frequency = nan\n", "frequency", "frequency must be a positive finite number"),
    ("frequency = inf\n", "frequency", "frequency must be a positive finite number"),
    ('frequency = "1.2"\n', "frequency", "frequency must be a positive finite number"),
    ("frequency = 1.2\nperiodic = false\n", "frequency", "a frequency makes the maneuver periodic"),
    ('periodic = "yes"\nfrequency = 1.2\n', "periodic", "periodic must be true or false"),
    ("periodc = true\n", "periodc", "did you mean 'periodic'"),
])
def test_bad_periodic_keys_are_one_error_naming_file_maneuver_and_key(tmp_path, entry, column, message):
    with pytest.raises(DataError, match=message) as info:
        read_campaign(_campaign(tmp_path / "c", entry=entry))
    text = str(info.value)
    assert f"column '{column}'" in text, text
    assert ("c0.csv" if column == "t" else "campaign.toml [[maneuver]] #1") in text, text


def test_a_periodic_record_that_does_not_cover_its_period_is_an_error(tmp_path):
    """Half a cycle marked with the cycle's frequency: the samples leave half the period uncovered."""
    half = {"t": np.arange(N // 2) * PERIOD / N, **{k: v[: N // 2] for k, v in _cycle().items()}}
    path = _campaign(tmp_path / "c", cycles=[half], entry="frequency = 1.2048192771084338\n")
    with pytest.raises(DataError, match=r"c0.csv \(maneuver 'c0'\), column 'frequency': a periodic maneuver must "
                                        r"cover its period: its samples span 0.412 s of the 0.83 s period"):
        read_campaign(path)


def test_a_record_of_several_cycles_with_its_frequency_starts_one_period_on(tmp_path):
    """Three cycles with a time column and the frequency: the states start at their value one period later."""
    cols = pitching_airfoil(cycles=3.0, period=PERIOD, dt=PERIOD / 100, airspeed=V, phase=0.4)
    cols["CL"] = 0.5 + 0 * cols["t"]
    del cols["alpha_dot"]
    path = _campaign(tmp_path / "c", cycles=[cols], entry="frequency = 1.2048192771084338\n")
    data = read_campaign(path).data
    x = build_model(load_grid("lift")["CL-II"]).bind(data).state_values(
        np.array([TRUTH[n] for n in ("tau1", "tau2", "a1", "a_star")]), False)["X"][1]
    assert abs(x[100] - x[0]) < 1e-6


def test_cycles_cut_from_a_periodic_record_are_each_periodic(tmp_path):
    cols = pitching_airfoil(cycles=3.0, period=PERIOD, dt=PERIOD / 400, airspeed=V, phase=-np.pi / 2)
    cols["CL"] = 0.5 + 0 * cols["t"]
    del cols["alpha_dot"]
    path = _campaign(tmp_path / "c", cycles=[cols], entry='frequency = 1.2048192771084338\nsegment = "cycles"\n')
    campaign = read_campaign(path)
    assert len(campaign.maneuvers) == 3 and all(m.periodic and m.frequency is None for m in campaign.maneuvers)
    for sl, period in zip(campaign.data.segment_slices(), campaign.data.periods):
        t = campaign.data["t"][sl]
        assert period == pytest.approx(t[-1] - t[0] + PERIOD / 400)


def test_marking_a_record_periodic_changes_its_cache_key(tmp_path):
    """A fit cached for a record read as not periodic is not the fit of the same samples read as periodic."""
    from structsearch.fitting.runner import fingerprint
    import dataclasses
    periodic = read_campaign(_campaign(tmp_path / "p", time=True, entry="periodic = true\n")).data
    plain = dataclasses.replace(periodic, periods=None)   # the same columns, not periodic
    assert fingerprint(periodic) != fingerprint(plain)
    assert fingerprint(plain) == fingerprint(dataclasses.replace(plain))
