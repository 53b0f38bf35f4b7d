"""Issue 31: every parameter table gives each parameter's unit (tau in s, a1 per rad, a_star in rad and deg,
a linear coefficient the inverse of its regressor's unit). The expected units are written by hand from the
catalogue's definitions (q* = q cbar / V is in rad, K_L(X) in rad, the spline in rad^2), not derived by the
code under test."""
import json

import pytest

from structsearch.engine.stallmodel import StallModel
from structsearch.engine.summary import PARAMETER_HEADERS, parameter_rows, parameter_table
from structsearch.engine.units import coefficient_unit, separation_unit
from structsearch.flight.reference import FINAL_MODEL_NAMES
from structsearch.fitting.specs import find_candidate

EXPECTED = {
    "CL-VI": {"tau1_ss": "s", "tau2_ss": "s", "a1_ss": "1/rad", "a_star_ss": "rad", "a1_w": "1/rad",
              "a_star_w": "rad", "CL0": "-", "CL_KL_ss": "1/rad", "CL_KL_w": "1/rad", "CL_qstar": "1/rad",
              "CL_de": "1/rad"},
    "CD-IXr": {"CD0": "-", "CD_CT": "-", "CD_de": "1/rad", "CD_1mX_ss": "-", "CD_1mX_w": "-", "CD_CL2": "-"},
    "Cm-XXXIIIr": {"Cm0": "-", "Cm_CT": "-", "Cm_qstar": "1/rad", "Cm_de": "1/rad", "Cm_Xde_ss": "1/rad",
                   "Cm_CL": "-", "Cm_xcgCL": "-", "Cm_1mX_ssCL": "-", "Cm_1mX_wCL": "-"},
}


def _model(name):
    c = find_candidate(name)
    return StallModel.declare(c.name, c.coefficient, dict(c.regressors), states=dict(c.states))


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_the_final_models_parameters_have_their_units(name):
    units = _model(name).units
    assert {k: units[k] for k in EXPECTED[name]} == EXPECTED[name]


def test_the_units_of_declared_regressors():
    import sympy as sp
    alpha, q, cbar, V, x, xcg, CL = sp.symbols("alpha q cbar V X x_cg CL", real=True)
    assert coefficient_unit((alpha - sp.pi / 30 + sp.Abs(alpha - sp.pi / 30)) ** 2 / 4) == "1/rad^2"  # the spline
    assert coefficient_unit(q * cbar / V) == "1/rad"
    assert coefficient_unit(sp.Symbol("q", real=True)) == "s/rad"          # q itself, in rad/s
    assert coefficient_unit(xcg / cbar * CL) == "-"
    assert coefficient_unit(x * alpha, ("X",)) == "1/rad"
    assert coefficient_unit(sp.sqrt(alpha)) == "1/rad^(1/2)"
    assert coefficient_unit(sp.Symbol("mystery", real=True) * alpha) == "unknown"   # never guessed
    assert coefficient_unit(alpha + sp.Symbol("V", real=True)) == "unknown"          # mixed units
    assert separation_unit("a_star_w") == "rad" and separation_unit("a1") == "1/rad"
    assert separation_unit("tau2_ss") == "s"


def test_a_fits_table_and_dict_carry_the_units(noise_free_lift):
    """The unit column of the parameter table, a_star also in deg; fit.json's units."""
    _, data = noise_free_lift
    model = StallModel.declare("one state", "CL", states={"": "U"},
                               regressors={"CL0": "1", "CL_KL": "K_L(X)", "CL_q": "q*cbar/V"})
    fit = model.fit(data, start={"tau1": 0.2, "tau2": 0.02, "a1": 25.0, "a_star": 0.2})
    rows = {r[0]: r for r in parameter_rows(fit)}
    unit = PARAMETER_HEADERS.index("unit")
    assert rows["tau1"][unit] == "s" and rows["CL_q"][unit] == "1/rad" and rows["CL0"][unit] == "-"
    degrees = fit.params["a_star"] * 180 / 3.141592653589793
    assert rows["a_star"][unit] == f"rad ({degrees:.2f} deg)"
    assert "| unit" in parameter_table(fit, "md")
    assert json.loads(json.dumps(fit.to_dict()))["units"]["a1"] == "1/rad"


def test_the_final_models_are_the_ones_checked():
    assert set(FINAL_MODEL_NAMES.values()) == set(EXPECTED)


def test_the_pooled_r2_counts_the_differences_between_maneuvers():
    """Issue 31: the thesis' Table 11.1 gives one R^2 per data set (C_m validation 0.71), which the tables had
    compared with the mean of the per-maneuver R^2 (0.32). Pooled: 1 - SSE / SST about the mean of all samples.
    Two maneuvers of 4 samples, values written out by hand."""
    import numpy as np
    from structsearch.engine.scores import ManeuverScores
    observed = np.array([0.0, 1.0, 0.0, 1.0, 10.0, 11.0, 10.0, 11.0])
    residual = np.array([0.5, -0.5, 0.5, -0.5, 0.5, -0.5, 0.5, -0.5])
    r2 = ManeuverScores.of(observed, residual, [slice(0, 4), slice(4, 8)]).r2_summary()
    # each maneuver: SST 1.0, SSE 1.0 -> R^2 0; all samples: mean 5.5, SST 4 * 0.25 + 4 * 0.25 + 8 * 25 = 202
    assert r2.mean == pytest.approx(0.0) and r2.min == pytest.approx(0.0)
    assert r2.pooled == pytest.approx(1.0 - 2.0 / 202.0)
