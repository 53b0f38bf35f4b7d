"""Symbolic regressors: every building block's derivative against finite differences; declaration checks."""
import numpy as np
import pytest

from structsearch.data.flightdata import FlightData, single_segment
from structsearch.data.errors import DataError, DeclarationError
from structsearch.engine.regressors import BUILDING_BLOCKS, block, declare
from structsearch.engine.stallmodel import StallModel

STATEFUL = sorted(n for n, text in BUILDING_BLOCKS.items() if "{X}" in text)
EXTRA = {"two_states": "K_L(X_ss)*X_w"}


@pytest.fixture(scope="module")
def columns():
    rng = np.random.default_rng(7)
    n = 50
    return single_segment({"alpha": rng.uniform(0.0, 0.35, n), "CL": rng.uniform(0.2, 1.4, n),
                           "de": rng.uniform(-0.2, 0.05, n), "q": rng.uniform(-0.1, 0.1, n),
                           "V": rng.uniform(50, 100, n)}, constants={"cbar": 2.013})


@pytest.mark.parametrize("name", STATEFUL + sorted(EXTRA))
def test_block_derivatives_match_finite_differences(name, columns):
    text = EXTRA[name] if name in EXTRA else block(name, "X_ss")
    reg = declare(name, text, states=["X_ss", "X_w"])
    assert reg.states
    rng = np.random.default_rng(8)
    n = columns.n_samples
    # stay away from the kink of max(1/2, X)
    xs = {"X_ss": rng.uniform(0.05, 0.95, n), "X_w": rng.uniform(0.05, 0.95, n)}
    xs["X_ss"][np.abs(xs["X_ss"] - 0.5) < 0.01] = 0.6
    for state in reg.states:
        h = 1e-6
        up = dict(xs, **{state: xs[state] + h})
        down = dict(xs, **{state: xs[state] - h})
        numeric = (reg.value(columns, up, n) - reg.value(columns, down, n)) / (2 * h)
        analytic = reg.derivative(state, columns, xs, n)
        assert np.allclose(analytic, numeric, rtol=1e-6, atol=1e-8), state


def test_named_expressions(columns):
    n = columns.n_samples
    qstar = declare("q", "qstar", states=[]).value(columns, {}, n)
    assert np.allclose(qstar, columns["q"] * 2.013 / columns["V"])
    spline = declare("s", "spline", states=[]).value(columns, {}, n)
    assert np.allclose(spline, np.maximum(columns["alpha"] - np.deg2rad(6), 0) ** 2)
    kl = declare("k", "K_L(X)", states=["X"]).value(columns, {"X": np.full(n, 0.25)}, n)
    assert np.allclose(kl, ((1 + 0.5) / 2) ** 2 * columns["alpha"])


def test_unknown_symbol_is_named():
    with pytest.raises(DeclarationError, match="unknown symbol 'X_foo'"):
        declare("bad", "K_L(X_foo)", states=["X_ss"])


def test_missing_constant_is_a_data_error(columns):
    data = single_segment({"q": np.ones(3), "V": np.ones(3)})
    with pytest.raises(DataError, match="cbar"):
        declare("q", "qstar", states=[]).value(data, {}, 3)


def test_model_declaration_checks():
    with pytest.raises(DeclarationError, match="X_w.*no regressor uses it"):
        StallModel.declare("m", "CL", states={"ss": "U", "w": "S"}, regressors={"c": "1", "k": "K_L(X_ss)"})
    with pytest.raises(DeclarationError, match="'tau9'"):
        StallModel.declare("m", "CL", states={"ss": "U"}, regressors={"k": "K_L(X_ss)"}, start={"tau9": 1})
    with pytest.raises(DeclarationError, match="own regressors"):
        StallModel.declare("m", "CL", regressors={"k": "CL*alpha"})
    with pytest.raises(DeclarationError, match="cannot parse"):
        StallModel.declare("m", "CL", regressors={"k": "alpha +* 2"})
    with pytest.raises(DeclarationError, match="not increasing"):
        StallModel.declare("m", "CL", states={"": "S"}, regressors={"k": "K_L(X)"}, bounds={"a1": (5, 1)})


@pytest.mark.parametrize("name", sorted(BUILDING_BLOCKS))
def test_every_block_declares_and_evaluates(name, columns):
    stateful = "{X}" in BUILDING_BLOCKS[name]
    reg = declare(name, block(name, "X_w" if stateful else None), states=["X_w"])
    n = columns.n_samples
    cols = dict(columns.columns, CT=np.full(n, 0.03), x_cg=np.full(n, 7.2))
    from structsearch.data.flightdata import FlightData
    data = FlightData(cols, columns.starts, columns.names, columns.source, columns.constants)
    value = reg.value(data, {"X_w": np.full(n, 0.3)}, n)
    assert value.shape == (n,) and np.all(np.isfinite(value))
    assert (reg.states == ("X_w",)) == stateful


def test_block_errors():
    with pytest.raises(DeclarationError, match="unknown building block"):
        block("K9", "X")
    with pytest.raises(DeclarationError, match="needs a separation state"):
        block("K_L")
    with pytest.raises(DeclarationError, match="does not depend"):
        block("qstar", "X_ss")


def test_any_campaign_column_may_appear_in_a_stall_model():
    """A free column (Mach) is a data column of the model; a missing one is named when the model meets
    the data, and X_... names stay reserved for separation states."""
    from structsearch.engine.stallmodel import StallModel
    from structsearch.flight.synthetic import campaign
    base = campaign({"quasi-steady": 2}, duration=10.0, seed=1)
    mach = base["V"] / 300.0
    rng = np.random.default_rng(0)
    y = 0.1 + 2.0 * mach * base["alpha"] + 0.001 * rng.standard_normal(base.n_samples)
    data = FlightData({**base.columns, "Mach": mach, "CL": y}, base.starts, base.names, base.source,
                      base.constants)
    model = StallModel.declare("m", "CL", {"c0": "1", "cm": "Mach*alpha"})
    assert "Mach" in model.required_columns
    fit = model.fit(data, covariance="white")
    assert abs(fit.params["cm"] - 2.0) < 0.01
    with pytest.raises(DataError, match="needs this column"):
        model.fit(base)
    with pytest.raises(DeclarationError, match="unknown symbol 'X_foo'"):
        StallModel.declare("m", "CL", {"c": "K_L(X_foo)"})
