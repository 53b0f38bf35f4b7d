"""A first-order lag as a modification of a JSBSim aircraft (``--modify`` ``[[lag]]``): read as data with one error
per bad entry, applied to the function's reads in the private copy, trimmed without it and flown with it. A lag
shorter than a frame flies the stock aircraft; a lag of 0.3 s changes the lift only while alpha moves."""
from __future__ import annotations

import numpy as np
import pytest

from structsearch.data.errors import DeclarationError
from structsearch.foreign.modify import Lag, Modification, read_modify

LAG = '[[lag]]\nfunction = "aero/coefficient/CLwbh"\ninput = "aero/alpha-rad"\ntime_constant = {tau}\n'


def test_a_lag_entry_is_read_with_its_number_and_properties(tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(LAG.format(tau=0.3) + '[[scale]]\nfunction = "aero/coefficient/CLq"\nfactor = 2\n')
    m = read_modify(path)
    assert m.lags == (Lag("aero/coefficient/CLwbh", "aero/alpha-rad", 0.3, 1),)
    assert m.scales == {"aero/coefficient/CLq": 2.0}
    assert m.functions == ("aero/coefficient/CLq", "aero/coefficient/CLwbh")
    assert m.lags[0].lagged != m.lags[0].read and m.lags[0].lagged.startswith("structsearch/")
    # a modification of scales alone keeps its digest; a lag changes it
    assert Modification(m.scales).digest() != m.digest() != Modification().digest() == "none"


@pytest.mark.parametrize("text, words", [
    (LAG.format(tau=0), "positive finite number of seconds"),
    (LAG.format(tau=-1), "positive finite number of seconds"),
    (LAG.format(tau="true"), "positive finite number of seconds"),
    (LAG.format(tau="nan"), "positive finite number of seconds"),
    ('[[lag]]\nfunction = "aero/coefficient/CLwbh"\ntime_constant = 1\n', "give exactly function"),
    ('[[lag]]\nfunction = "aero/coefficient/CLwbh"\ninput = ""\ntime_constant = 1\n', "input must be the name"),
    (LAG.format(tau=0.3) * 2, "already reads aero/alpha-rad lagged"),
    ("lag = 3\n", "must be a list"),
    ("", "no [[scale]], [[lag]], [[replace]], [[state]] or [[wing_drop]] entry"),
])
def test_a_bad_lag_entry_is_one_error_naming_file_and_entry(tmp_path, text, words):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(DeclarationError, match=words.replace("[", r"\[").replace("]", r"\]")) as err:
        read_modify(path)
    assert str(path) in str(err.value)


jsbsim = pytest.importorskip("jsbsim", reason="flying a JSBSim aircraft needs the jsbsim package (the test extra has it)")


def test_a_lag_is_applied_where_the_function_reads_its_input_and_nowhere_else():
    import xml.etree.ElementTree as ET
    from pathlib import Path
    from structsearch.foreign.aircraft_xml import read_aircraft
    from structsearch.foreign.private_copy import make_copy
    aircraft = read_aircraft("c172p")
    lag = Lag("aero/coefficient/CLwbh", "aero/alpha-rad", 0.3)
    holder = make_copy(aircraft, None, rewrite=False, lags=(lag,))
    try:
        aero = ET.parse(Path(holder.name) / "aircraft" / "c172p" / "c172p.xml").getroot().find("aerodynamics")
        functions = {f.get("name"): f for f in aero.iter("function")}
        reads = [e.text.strip() for e in functions["aero/coefficient/CLwbh"].iter("independentVar")]
        assert lag.read in reads and lag.input not in reads
        assert any(e.text.strip() == lag.input for e in functions["aero/coefficient/Cmalpha"].iter("property"))
        assert lag.read in functions
    finally:
        holder.cleanup()
    with pytest.raises(DeclarationError, match="does not read aero/beta-rad"):
        make_copy(aircraft, None, rewrite=False, lags=(Lag("aero/coefficient/CLwbh", "aero/beta-rad", 0.3),))
    with pytest.raises(DeclarationError, match="acts over time"):
        make_copy(aircraft, None, rewrite=True, lags=(lag,))


def test_a_lagged_lift_table_is_stock_for_a_tiny_lag_and_lags_by_its_time_constant():
    """The same seed flown stock, with a lag of 0.1 ms and with 0.3 s. The tiny lag keeps exp(-100) of the frame
    before, so its table reads the frame's own alpha and its C_L is the stock one (the measurement chain's noise is
    the same draws; a lag stepped a frame late would differ by C_L_alpha alpha_dot 10 ms, 0.02 in the pulls).
    Against the stock aircraft evaluated at each campaign's own recorded states (the diagnosis' baseline), the
    stock campaign's gap does not follow alpha_dot in attached flow, and the lagged one's does with the lag's sign:
    a slope between 0.3 and 1.5 times -C_L_alpha tau (its low-frequency limit; the pulls reach omega tau near 1,
    where a lag's gain falls; measured 0.58) and a correlation below -0.5 (measured -0.65)."""
    from structsearch.foreign.baseline import jsbsim_baseline
    from structsearch.foreign.fly import fly_campaign
    tau = 0.3
    stock = fly_campaign("c172p", scale=0.04, seed=3)
    tiny = fly_campaign("c172p", Modification(lags=(Lag("aero/coefficient/CLwbh", "aero/alpha-rad", 1e-4),)),
                        scale=0.04, seed=3)
    lagged = fly_campaign("c172p", Modification(lags=(Lag("aero/coefficient/CLwbh", "aero/alpha-rad", tau),)),
                          scale=0.04, seed=3)
    assert np.max(np.abs(tiny.data["CL"] - stock.data["CL"])) < 1e-9
    assert lagged.extra["source"]["modify"] != "none" and "modified" in lagged.name
    slopes, correlations = {}, {}
    for name, campaign in (("stock", stock), ("lagged", lagged)):
        baseline = jsbsim_baseline("c172p", campaign, "CL", {"fcs/flap-pos-deg": 0.0}).values
        alpha, rate = campaign.data["alpha"], campaign.data["alpha_dot"]
        attached = alpha < np.deg2rad(12.0)
        lift_slope = np.polyfit(alpha[attached], baseline[attached], 1)[0]
        gap = campaign.data["CL"] - baseline
        slopes[name] = np.polyfit(rate[attached], gap[attached], 1)[0] / (-lift_slope * tau)
        correlations[name] = np.corrcoef(rate[attached], gap[attached])[0, 1]
    assert abs(slopes["stock"]) < 0.1 and abs(correlations["stock"]) < 0.3
    assert 0.3 < slopes["lagged"] < 1.5 and correlations["lagged"] < -0.5
