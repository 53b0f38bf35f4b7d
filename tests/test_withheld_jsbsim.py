"""The withheld-effect benchmark through JSBSim: the truth without an effect is the simulator, nothing refitted."""
from __future__ import annotations

import pytest

from structsearch.api.withheld_jsbsim import truth_without
from structsearch.diagnosis.withheld import WITHHELD
from structsearch.fitting.models import build_model
from structsearch.flight.reference import FINAL_DRAG, FINAL_LIFT, FINAL_PITCH

TRUTH = {**FINAL_LIFT, **FINAL_DRAG, **FINAL_PITCH}


@pytest.mark.parametrize("effect", sorted(WITHHELD))
def test_the_simulator_is_the_truth_without_the_effect_at_the_truths_values(effect):
    """Every exported parameter is the truth's value (no fit moved one to stand in for the effect); the effect's
    terms are gone, a lag made simpler loses its time constant, and drag and pitch come with the truth's lift."""
    coefficient, dropped, kinds = WITHHELD[effect]
    fitted = truth_without(effect)
    assert fitted[0].candidate.coefficient == "CL" and fitted[-1].candidate.coefficient == coefficient
    for f in fitted:
        assert f.params == {n: TRUTH[n] for n in f.params} and f.covariance is None
    # what the export must be given is what the model built from the structure estimates: no parameter missing,
    # none extra (read from the engine's model, not from how truth_without picks them)
    lift_model = build_model(fitted[0].candidate)
    assert set(fitted[0].params) == set(lift_model.nonlinear_names) | set(lift_model.linear_names)
    if coefficient != "CL":
        assert set(fitted[-1].params) == set(dict(fitted[-1].candidate.regressors))
        assert not set(fitted[-1].params) & set(lift_model.nonlinear_names)
    exported = fitted[-1]
    assert not set(dropped) & set(exported.params)
    if effect == "unsteady_lag":
        assert "tau1_ss" not in exported.params and dict(exported.candidate.states)["ss"] == "Q"
    if effect == "second_separation_state":
        assert not any(n.endswith("_w") for n in exported.params)
    if coefficient != "CL":   # its states are the lift model's, exported with the truth's values
        assert fitted[0].params == {n: TRUTH[n] for n in FINAL_LIFT}


@pytest.mark.slow
def test_a_withheld_pitch_rate_is_found_through_jsbsim(tmp_path):
    """The truth's lift without its pitch-rate term, exported to JSBSim and flown against (as a user's simulator):
    the diagnosis adopts the pitch-rate effect first, and it closes at least half of the gap. The campaign is a
    seed the committed benchmark did not use, at full scale: at half scale (seed 7) the move is adopted first too,
    but the baseline is within the floor's tolerance, where its share of the gap is not defined."""
    pytest.importorskip("jsbsim", reason="the benchmark drives JSBSim (the test extra has it)")
    from structsearch.api import Settings
    from structsearch.api.withheld_jsbsim import row
    from structsearch.flight.flighttest import build_campaign
    r = row(build_campaign(seed=7), "pitch_rate", tmp_path, Settings(jobs=2))
    assert r.first_adopted == "pitch_rate" and r.hit and r.closes_half, r
    assert (tmp_path / "pitch_rate" / "aerodynamics.xml").exists()


def test_the_move_that_is_the_withheld_effect_on_a_fixed_baseline():
    """The effect itself, the effect at one state, and (an effect that is the coefficient's K term on a state,
    whose states are inside the simulator) a state the gap model adds with that term count; another effect, or a
    state added for an effect that is not a K term, does not."""
    from structsearch.api.withheld_jsbsim import is_the_effect
    assert is_the_effect("pitch_rate", "pitch_rate", "pitch_rate")
    assert is_the_effect("elevator_effectiveness_loss", "elevator_effectiveness_loss: add Cm_Xde_2_ss = X_ss*de")
    assert is_the_effect("second_separation_state", "add state X_ss with CL_KL_ss = K_L(X_ss)")
    assert is_the_effect("separation_drag", "add state X_ss with CD_1mX_ss = 1 - X_ss")
    assert is_the_effect("cp_shift", "add state X_ss with Cm_1mX_ssCL = (1 - X_ss)*CL")
    assert not is_the_effect("unsteady_lag", "add state X_ss with CL_KL_ss = K_L(X_ss)")
    assert not is_the_effect("pitch_rate", "alpha_dot", "alpha_dot")
