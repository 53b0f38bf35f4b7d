"""Bad input: one clear error each, never a crash deep inside numpy."""
import numpy as np
import pytest

from structsearch import SeparableModel
from structsearch.data.flightdata import FlightData, from_segments
from structsearch.data.errors import DataError, DeclarationError, FitError
from structsearch.flight.reference import final_lift_model


def _replace(data, **cols):
    new = dict(data.columns)
    new.update(cols)
    return FlightData(new, data.starts, data.names, data.source, data.constants)


def test_nan_in_coefficient_names_maneuver_column_and_row(noise_free_lift):
    model, data = noise_free_lift
    cl = data["CL"].copy()
    cl[data.starts[2] + 17] = np.nan
    with pytest.raises(DataError, match=r"column 'CL', row 17: value is NaN.*dynamic-1"):
        model.fit(_replace(data, CL=cl))


def test_nan_in_input_column():
    seg = {"t": np.arange(5.0), "alpha": np.array([0.1, 0.2, np.nan, 0.1, 0.1])}
    with pytest.raises(DataError, match=r"file flight7.csv:m3, column 'alpha', row 2"):
        from_segments([seg], names=["m3"], source="flight7.csv")


def test_non_increasing_time():
    seg = {"t": np.array([0.0, 0.01, 0.02, 0.02, 0.04]), "alpha": np.zeros(5)}
    with pytest.raises(DataError, match=r"column 't', row 3: time is not strictly increasing"):
        from_segments([seg], names=["m1"])


def test_missing_column(small_campaign):
    model = final_lift_model()
    cols = {k: v for k, v in small_campaign.columns.items() if k != "q"}
    data = FlightData(cols, small_campaign.starts, small_campaign.names, "camp", small_campaign.constants)
    with pytest.raises(DataError, match=r"column 'q'"):
        model.fit(data)


def test_start_outside_bounds(noise_free_lift):
    model, data = noise_free_lift
    with pytest.raises(FitError, match=r"'tau1_ss'.*outside its bounds"):
        model.fit(data, start={"tau1_ss": 5.0})


def test_separable_model_bad_declarations():
    with pytest.raises(DeclarationError, match="no start value for nonlinear parameter 'b2'"):
        SeparableModel({"b1": "exp(-b2*x)"}, variables=["x"]).fit({"x": np.arange(5.0)}, np.ones(5))
    with pytest.raises(DeclarationError, match="'b7' is not a nonlinear parameter"):
        SeparableModel({"b1": "exp(-b2*x)"}, variables=["x"]).fit({"x": np.arange(5.0)}, np.ones(5),
                                                                   start={"b2": 1, "b7": 2})
    with pytest.raises(DeclarationError, match="data variable 'z' is declared but no basis function uses it"):
        SeparableModel({"b1": "exp(-b2*x)"}, variables=["x", "z"])
    with pytest.raises(DeclarationError, match="uses linear coefficient 'b1'"):
        SeparableModel({"b1": "exp(-b2*x)", "b3": "b1*x"}, variables=["x"])


def test_separable_model_bad_data():
    model = SeparableModel({"b1": "exp(-b2*x)"}, variables=["x"])
    with pytest.raises(DataError, match=r"column 'x', row 3"):
        model.fit({"x": np.array([0.0, 1, 2, np.inf])}, np.ones(4), start={"b2": 1.0})
    with pytest.raises(DataError, match=r"column 'y', row 1"):
        model.fit({"x": np.arange(3.0)}, np.array([1.0, np.nan, 2.0]), start={"b2": 1.0})
    with pytest.raises(FitError, match="outside its bounds"):
        model.fit({"x": np.arange(3.0)}, np.ones(3), start={"b2": 1.0}, bounds={"b2": (2.0, 3.0)})


def test_unknown_covariance_kind():
    model = SeparableModel({"b1": "exp(-b2*x)"}, variables=["x"])
    with pytest.raises(FitError, match="covariance must be one of"):
        model.fit({"x": np.arange(3.0)}, np.ones(3), start={"b2": 1.0}, covariance="pink")


def test_atomic_files_get_the_normal_mode(tmp_path):
    """Issue 13: written through the atomic writer, a file has 0666 less the umask, not mkstemp's 0600."""
    import os
    import stat
    from structsearch.data.atomic import write_text
    old = os.umask(0o022)
    try:
        path = write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644 and path.read_text() == "x"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]   # no temporary left behind


def test_demo_knows_how_its_campaign_was_simulated(tmp_path):
    """Issue 13: the demo reuses results/campaign only when it was simulated as the demo would (seed 0,
    the requested scale, nothing withheld, realistic errors)."""
    from structsearch.workflows import simulated_as as _simulated_as
    from structsearch.data.campaign import write_campaign
    from structsearch.flight.flighttest import build_campaign
    assert _simulated_as(tmp_path / "none") is None
    write_campaign(build_campaign(seed=0, scale=0.05), tmp_path / "c")
    assert _simulated_as(tmp_path / "c") == {"seed": 0, "scale": 0.05, "withheld": "none", "slow_errors": 1.0,
                                             "extras": False, "flights": None}
    # a campaign flown on flights with their shared errors is not the demo's
    write_campaign(build_campaign(seed=0, scale=0.05, flights=3), tmp_path / "f")
    assert _simulated_as(tmp_path / "f")["flights"] == 3


def test_csv_numbers_carry_ten_significant_digits():
    """Issue 13 (churn): 0.1 + 0.2 and its neighbour in the 16th digit are written alike."""
    from structsearch.reporting.tables import csv_value, render_table
    assert csv_value(0.1 + 0.2) == csv_value(0.3) == "0.3" and csv_value(float("nan")) == ""
    assert render_table([[1 / 3, "x", 2]], ["a", "b", "c"], "csv") == "a,b,c\n0.3333333333,x,2\n"
