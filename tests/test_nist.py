"""NIST StRD nonlinear regression: certified values (6 digits) and standard deviations (3 digits).

Every NIST problem that can be written as sum_i c_i phi_i(x; theta) is fitted
from both certified starting points with ``covariance="white"``.
"""
import numpy as np
import pytest

from structsearch import SeparableModel
from structsearch.engine.identifiability import RANK_RTOL

from nist import SEPARABLE, load


def log_relative_error(value, certified):
    if value == certified:
        return 16.0
    return -np.log10(abs(value - certified) / abs(certified))


CASES = [(name, start) for name in SEPARABLE for start in (1, 2)]


@pytest.mark.parametrize("name,start", CASES, ids=[f"{n}-start{s}" for n, s in CASES])
def test_certified_values(name, start):
    problem = load(name)
    model = SeparableModel(SEPARABLE[name], variables=list(problem.variables))
    assert set(model.nonlinear_names) | set(model.linear_names) == set(problem.certified)
    result = model.fit(problem.variables, problem.y,
                       start={p: problem.starts[start - 1][p] for p in model.nonlinear_names},
                       covariance="white")
    # far from the rank limit: a certified problem is identifiable, nothing is named
    assert result.identifiable and result.condition_number < 1e-3 / RANK_RTOL, result.not_identifiable
    for p, certified in problem.certified.items():
        assert log_relative_error(result.params[p], certified) >= 6, (p, result.params[p], certified)
        assert log_relative_error(result.stderr[p], problem.certified_stderr[p]) >= 3, (
            p, result.stderr[p], problem.certified_stderr[p])
    assert log_relative_error(result.rss, problem.certified_rss) >= 6 if name != "Lanczos1" else True


def test_lanczos1_rss_in_extended_precision():
    # residuals of 1e-13 of the data: the RSS is only right because it is evaluated in long double
    problem = load("Lanczos1")
    model = SeparableModel(SEPARABLE["Lanczos1"], variables=["x"])
    result = model.fit(problem.variables, problem.y, start={"b2": 1.2, "b4": 2.3, "b6": 5.6},
                       covariance="white")
    assert log_relative_error(result.rss, problem.certified_rss) >= 3
