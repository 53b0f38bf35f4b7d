"""One contract for every registered static separation form (as scikit-learn runs its estimator checks over every
registered estimator): a box, a start inside it and a unit for each parameter; a curve in [0, 1], non-increasing
in alpha, at random parameters anywhere in the box; exact derivatives in alpha and in the parameters (central
differences); the equations' "where" line; an export that writes it or refuses it by name."""
from __future__ import annotations

import numpy as np
import pytest

from structsearch.data.errors import DeclarationError
from structsearch.engine.equations import write_equations
from structsearch.engine.separation import SeparationState
from structsearch.engine.static_forms import FORMS, SEPARATION_BOUNDS, SEPARATION_STARTS, parse_form, static_gradient
from structsearch.engine.units import separation_unit

DECLARED = [f.name + (":4" if f.knotted else "") for f in FORMS.values()]
ALPHA = np.linspace(-0.2, 0.8, 4001)


def _random_values(form: str, rng) -> dict[str, float]:
    entry, knots = parse_form(form)
    return {p: rng.uniform(*entry.boxes[p]) for p in entry.parameters_of(knots)}


@pytest.mark.parametrize("form", DECLARED)
def test_every_parameter_has_a_box_a_start_inside_it_and_a_unit(form):
    entry, knots = parse_form(form)
    for p in entry.parameters_of(knots):
        low, high = entry.boxes[p]
        assert low < high and low <= entry.starts[p] <= high, p
        # a parameter two forms share (a_star) keeps one box and start: the merged defaults never override one
        sharing = [f for f in FORMS.values() if p in f.boxes]
        assert all(f.boxes[p] == SEPARATION_BOUNDS[p] and f.starts[p] == SEPARATION_STARTS[p] for f in sharing), p
        assert separation_unit(f"{p}_ss") != "unknown", p
    assert set(entry.locations) <= set(entry.parameters) and set(entry.steepness) <= set(entry.parameters)


@pytest.mark.parametrize("form", DECLARED)
def test_the_curve_is_bounded_and_non_increasing_anywhere_in_its_box(form):
    rng = np.random.default_rng(11)
    for _ in range(50):
        x0 = static_gradient(form, ALPHA, _random_values(form, rng), False)[0]
        assert np.all((x0 >= 0.0) & (x0 <= 1.0))
        assert np.all(np.diff(x0) <= 1e-12)


@pytest.mark.parametrize("form", DECLARED)
def test_derivatives_match_central_differences(form):
    rng = np.random.default_rng(12)
    alpha = np.linspace(0.0, 0.5, 301)
    for _ in range(5):
        values = _random_values(form, rng)
        x0, dalpha, grads = static_gradient(form, alpha, values)
        h = 1e-7
        numeric = (static_gradient(form, alpha + h, values, False)[0] - static_gradient(form, alpha - h, values, False)[0]) / (2 * h)
        assert np.max(np.abs(numeric - dalpha)) < 1e-4 * max(1.0, np.max(np.abs(numeric)))
        for j, p in enumerate(values):
            step = 1e-7 * max(1.0, abs(values[p]))
            up, down = dict(values), dict(values)
            up[p] += step
            down[p] -= step
            numeric = (static_gradient(form, alpha, up, False)[0] - static_gradient(form, alpha, down, False)[0]) / (2 * step)
            assert np.max(np.abs(numeric - grads[:, j])) < 1e-4 * max(1.0, np.max(np.abs(numeric))), (form, p)


@pytest.mark.parametrize("form", DECLARED)
def test_the_equations_write_the_form_and_say_what_it_is(form):
    entry, _ = parse_form(form)
    text = "\n".join(write_equations("CL", [("CL_KL", "K_L(X_ss)")], [("ss", "U", form)]).text)
    if entry.meaning:
        assert f"X0_{entry.name}(" in text and entry.meaning in text
    else:
        assert "tanh" in text


@pytest.mark.parametrize("form", DECLARED)
def test_an_export_writes_the_form_or_refuses_it_by_name(form):
    from structsearch.export.card import StateModel
    entry, _ = parse_form(form)
    params = {f"{p}_ss": v for p, v in SEPARATION_STARTS.items()}
    if entry.exported:
        assert StateModel("ss", "U", params, form=form).form == form
    else:
        with pytest.raises(DeclarationError, match=f"static form '{form}' cannot be exported"):
            StateModel("ss", "U", params, form=form)


def test_a_name_outside_the_registry_is_one_error_with_the_close_match():
    with pytest.raises(DeclarationError, match="did you mean 'two_break'"):
        parse_form("two-break")
    with pytest.raises(DeclarationError, match="K of spline:K"):
        parse_form("spline:1")
    assert SeparationState("ss", "U", "spline:3").base_parameters[-3:] == ("r1", "r2", "r3")
