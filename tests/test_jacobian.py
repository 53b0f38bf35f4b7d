"""The Golub-Pereyra residual Jacobian and the model Jacobian against central finite differences."""
import numpy as np
import pytest

from structsearch import SeparableModel
from structsearch.flight.reference import FINAL_LIFT, final_lift_model, van_ingen_lift_model
from structsearch.engine.snls import model_jacobian, project, residual_jacobian
from structsearch.engine.stallmodel import StallModel

from conftest import central_difference


def projected_residual(problem, y):
    return lambda th: project(problem.evaluate(th).phi, y).residual


MODELS = {
    "CL-VI": final_lift_model,
    "CL-I": van_ingen_lift_model,
    "Q-and-U": lambda: StallModel.declare(
        "QU", "CL", states={"a": "Q", "b": "U"},
        regressors={"c0": "1", "ka": "K_L(X_a)", "kb": "K_L(X_b)*X_a", "de": "X_b*de"}),
}


@pytest.mark.parametrize("name", sorted(MODELS))
def test_golub_pereyra_jacobian(name, small_campaign):
    model = MODELS[name]()
    rng = np.random.default_rng(9)
    data = small_campaign.select([0, 3])
    cols = dict(data.columns)
    cols["CL"] = 0.2 + 5 * data["alpha"] + 0.02 * rng.standard_normal(data.n_samples)
    from structsearch.data.flightdata import FlightData
    data = FlightData(cols, data.starts, data.names, data.source, data.constants)
    problem = model.bind(data)
    lower, upper = model.bound_vectors()
    theta = lower + rng.uniform(0.2, 0.8, len(lower)) * (upper - lower)
    theta[[i for i, n in enumerate(model.nonlinear_names) if n.startswith("a1")]] = 25.0
    ev = problem.evaluate(theta)
    proj = project(ev.phi, data["CL"])
    analytic = residual_jacobian(ev, proj, len(theta))
    numeric = central_difference(projected_residual(problem, data["CL"]), theta)
    scale = np.max(np.abs(numeric), axis=0)
    assert np.all(np.max(np.abs(analytic - numeric), axis=0) <= 1e-5 * scale)


def test_model_jacobian(noise_free_lift):
    model, data = noise_free_lift
    problem = model.bind(data.select([0, 2]))
    theta = np.array([FINAL_LIFT[p] for p in model.nonlinear_names])
    coef = np.array([FINAL_LIFT[p] for p in model.linear_names])
    k = len(theta)
    analytic = model_jacobian(problem.evaluate(theta), coef, k)

    def output(x):
        return problem.evaluate(x[:k]).phi @ x[k:]

    numeric = central_difference(output, np.concatenate([theta, coef]))
    scale = np.max(np.abs(numeric), axis=0)
    assert np.all(np.max(np.abs(analytic - numeric), axis=0) <= 1e-6 * scale)


def test_separable_model_jacobian():
    x = np.linspace(0.05, 3, 80)
    model = SeparableModel({"b1": "exp(-b2*x)", "b3": "x**b4/(1 + b2*x)", "b5": "1"}, variables=["x"])
    problem = model.bind({"x": x})
    y = 2 * np.exp(-1.3 * x) + 0.5 * x ** 1.7 / (1 + 1.3 * x) + np.sin(5 * x) * 0.01
    theta = np.array([1.1, 1.5])
    ev = problem.evaluate(theta)
    analytic = residual_jacobian(ev, project(ev.phi, y), 2)
    numeric = central_difference(projected_residual(problem, y), theta)
    assert np.allclose(analytic, numeric, rtol=1e-6, atol=1e-9)
    # bookkeeping: only (basis, parameter) pairs that really depend on each other
    assert sorted(zip(ev.rows.tolist(), ev.params.tolist())) == [(0, 0), (1, 0), (1, 1)]


def test_the_finite_difference_check_fails_a_wrong_derivative():
    """The tolerance of :func:`assert_matches_finite_difference` comes from the differences themselves: it
    passes the exact derivative of a steep sigmoid and fails one off by 1e-5 of its size."""
    from conftest import assert_matches_finite_difference
    x_grid = np.linspace(0.0, 0.4, 200)

    def curve(p):
        return 0.5 * (1 - np.tanh(p[0] * (x_grid - p[1])))

    p = np.array([35.0, 0.25])
    sech2 = 1 - np.tanh(p[0] * (x_grid - p[1])) ** 2
    exact = np.column_stack([-0.5 * sech2 * (x_grid - p[1]), 0.5 * sech2 * p[0]])
    assert_matches_finite_difference(exact, curve, p)
    wrong = exact.copy()
    wrong[:, 0] *= 1 + 1e-5
    with pytest.raises(AssertionError, match="elements off"):
        assert_matches_finite_difference(wrong, curve, p)
