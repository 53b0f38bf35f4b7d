"""``structsearch grids``: the shipped grids and their candidates as equations."""
import pytest

from conftest import run_cli
from structsearch.fitting.candidates import Candidate
from structsearch.fitting.specs import load_grid
from structsearch.reporting.equations import equations, model_equation, state_equation


def test_grids_lists_every_shipped_candidate_with_its_equation():
    proc = run_cli("grids")
    assert proc.returncode == 0, proc.stderr
    lift = load_grid("lift")
    for grid in (load_grid("separation"), lift, load_grid("drag", lift), load_grid("pitch", lift)):
        assert f"{grid.name}: {len(grid.candidates)} candidates" in proc.stdout
        for c in grid.candidates:
            assert f"  {c.name}: {c.coefficient} = " in proc.stdout, c.name
    assert "  X_ss/X_w U/Q: CL = CL0 + CL_KL_ss*K_L(X_ss)" in proc.stdout and "[X_ss: U, X_w: Q]" in proc.stdout


def test_one_candidate_comes_with_its_states_and_helpers():
    proc = run_cli("grids", "CL-VI")
    assert proc.returncode == 0, proc.stderr
    lines = [line.strip() for line in proc.stdout.splitlines()]
    assert "CL = CL0 + CL_KL_ss*K_L(X_ss) + CL_KL_w*K_L(X_w) + CL_qstar*qstar + CL_de*de" in lines
    assert "tau1_ss*dX_ss/dt + X_ss = 0.5*(1 - tanh(a1_ss*(alpha - tau2_ss*alpha_dot - a_star_ss)))" in lines
    assert "X_w = 0.5*(1 - tanh(a1_w*(alpha - a_star_w)))" in lines
    assert any(line.startswith("where K_L(X) = ((1 + sqrt(X))/2)^2 * alpha") for line in lines)


def test_a_pitch_grid_names_the_lift_model_its_states_come_from():
    proc = run_cli("grids", "pitch")
    assert proc.returncode == 0, proc.stderr
    assert "a state of the lift model CL-VI, its parameters fixed at that model's fit" in proc.stdout


def test_an_unknown_name_is_one_clear_error():
    proc = run_cli("grids", "CL-XCIX")
    assert proc.returncode == 2
    errors = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(errors) == 1 and "CL-XCIX" in errors[0] and "not a grid" in errors[0]


@pytest.mark.parametrize("text, written", [
    ("1", "p"), ("alpha", "p*alpha"), ("(1 - X_ss)*CL", "p*(1 - X_ss)*CL"), ("alpha - 0.1", "p*(alpha - 0.1)"),
    ("-alpha", "p*-alpha"), ("1e-3*alpha", "p*1e-3*alpha"), ("x_cg/cbar*CL", "p*x_cg/cbar*CL"),
])
def test_a_regressor_is_bracketed_only_where_a_sum_would_change_the_product(text, written):
    c = Candidate("T", "g", "CL", (("p", text),), (), None, "", ())
    assert model_equation(c) == f"CL = {written}"


def test_the_three_kinds_of_state():
    assert state_equation("", "S") == "X = 0.5*(1 - tanh(a1*(alpha - a_star)))"
    assert state_equation("w", "Q") == "X_w = 0.5*(1 - tanh(a1_w*(alpha - tau2_w*alpha_dot - a_star_w)))"
    assert state_equation("ss", "U").startswith("tau1_ss*dX_ss/dt + X_ss = ")
    c = Candidate("T", "g", "CD", (("CD0", "1"), ("k", "K_D(X)")), (("", "U"),), None, "", ())
    assert equations(c)[-1].startswith("where K_D(X) = ((1 - sqrt(X))/2)^2 * alpha^2")
