"""Every lagged kind is flown lagged: a lagged state without the alpha_dot delay (L) flies as an unsteady one
(U) with tau2 = 0, and a vortex state (V), which the simulator does not fly, is refused by name."""
import numpy as np
import pytest

from structsearch.data.errors import DeclarationError
from structsearch.engine.separation import SeparationState
from structsearch.engine.stallmodel import StallModel
from structsearch.flight.aero import AeroModel, truth_model
from structsearch.flight.flighttest import scaled_plan, simulate_campaign, thesis_plan


def _as_kind(model: StallModel, state: str, kind: str, drop: str) -> StallModel:
    states = tuple(SeparationState(s.name, kind, s.form) if s.name == state else s for s in model.states)
    fixed = {k: v for k, v in model.fixed.items() if k != drop}
    return StallModel(model.name, model.coefficient, states, model.regressors, model.start, model.bounds, fixed)


def test_a_lagged_state_without_delay_flies_as_the_unsteady_one_with_tau2_zero():
    unsteady = truth_model(withhold=("separation_delay",))            # X_ss: U with tau2_ss = 0
    models = [_as_kind(m, "ss", "L", "tau2_ss") for m in unsteady.models.values()]
    params = {k: v for k, v in unsteady.params.items() if k != "tau2_ss"}
    lagged = AeroModel(*models, params, unsteady.constant_states, name="L truth")
    assert [s.symbol for s in lagged.unsteady] == [s.symbol for s in unsteady.unsteady] == ["X_ss"]
    plan = scaled_plan(thesis_plan(), 0.05)[:2]
    flown_u = simulate_campaign(plan, unsteady, seed=3, slow_errors=0.0)
    flown_l = simulate_campaign(plan, lagged, seed=3, slow_errors=0.0)
    assert len(flown_u) == len(flown_l) == 2
    for a, b in zip(flown_u, flown_l):
        for column in ("alpha", "CL", "Cm"):
            np.testing.assert_allclose(a[column], b[column], rtol=1e-9, atol=1e-12)


def test_a_vortex_state_is_refused_by_the_simulator_by_name():
    truth = truth_model()
    lift = truth.models["CL"]
    vortex = StallModel.declare("CL-vortex", "CL", {"CL_KL": "K_L(X_ss)", "CL_v": "X_v"},
                                states={"ss": "U", "v": "V"})
    params = dict(truth.params, tau1_v=0.1, tau_v_v=0.2, a1_v=30.0, a_star_v=0.25, CL_v=0.5, CL_KL=lift and 5.0)
    with pytest.raises(DeclarationError, match=r"X_v is a dynamic-stall vortex \(kind V\)"):
        AeroModel(vortex, truth.models["CD"], truth.models["Cm"], params, name="vortex truth")


def test_a_vortex_state_is_refused_by_the_jsbsim_export_by_name():
    from structsearch.export.card import StateModel
    from structsearch.export.jsbsim_files import _state_components
    state = StateModel("vortex", "V", {"tau1_vortex": 0.1, "tau_v_vortex": 0.2, "a1_vortex": 30.0,
                                       "a_star_vortex": 0.25})
    with pytest.raises(DeclarationError, match=r"X_vortex is a dynamic-stall vortex \(kind V\).*--format json"):
        _state_components(state)
    lagged = StateModel("ss", "L", {"tau1_ss": 0.1, "a1_ss": 30.0, "a_star_ss": 0.25})
    names = [part.get("name") for part in _state_components(lagged)]
    assert any(n.endswith("lag/X_ss/a") for n in names)   # an L state is written lagged (a lag without the delay)
