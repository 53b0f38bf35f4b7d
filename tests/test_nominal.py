"""Stall with non-stall data: ``simulate --nominal`` (nominal maneuvers, kind = "nominal") and ``fit --by-kind`` (a
global model against its stall and attached-flow parts, validated on each kind apart)."""
import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from structsearch.data.campaign import regime
from structsearch.data.errors import DataError
from structsearch.flight.envelope import MACH_ONSET, QBAR_ONSET_PA
from structsearch.flight.nominal import INPUTS, nominal_plan, pulses
from structsearch.fitting.by_kind import regime_mse
from structsearch.fitting.regimes import NOT_PLACED, VANISHES, ZERO_ON_STALL, attached_part, stall_part
from structsearch.fitting.specs import find_candidate, lift_candidate

SCALE = 0.05


def test_simulate_nominal_writes_nominal_maneuvers_that_read_back(campaign_on_disk):
    c = campaign_on_disk(0, SCALE, nominal=True)
    nominal = [m for m in c.maneuvers if m.kind == "nominal"]
    assert {m.id.split("-", 1)[1] for m in nominal} == set(INPUTS)
    assert {m.split for m in nominal} == {"train", "validation"}
    assert [regime(m.kind) for m in c.maneuvers] == ["nominal" if m in nominal else "stall" for m in c.maneuvers]
    toml = (c.directory / "campaign.toml").read_text()
    assert toml.count('kind = "nominal"') == len(nominal)
    assert "Mach" in c.data.columns and "qbar" in c.data.columns


def test_a_campaign_without_nominal_maneuvers_reads_as_stall_and_is_unchanged(campaign_on_disk):
    c = campaign_on_disk(0, SCALE)
    assert {regime(m.kind) for m in c.maneuvers} == {"stall"}
    assert "Mach" not in c.data.columns and "nominal" not in (c.directory / "campaign.toml").read_text()


def test_the_stall_maneuvers_fly_the_same_with_nominal_ones(simulated_campaign):
    plain, both = simulated_campaign(0, SCALE), simulated_campaign(0, SCALE, nominal=True)
    stall = [i for i, m in enumerate(both.maneuvers) if m.kind != "nominal"]
    assert [m.id for m in plain.maneuvers] == [both.maneuvers[i].id for i in stall]
    same = both.data.select(stall)
    for name, values in plain.data.columns.items():   # the envelope terms are zero there, up to rounding
        np.testing.assert_allclose(same.columns[name], values, rtol=1e-9, atol=1e-9, err_msg=name)
    # ... because every stall maneuver flies below the envelope terms' onsets
    assert same.columns["Mach"].max() < MACH_ONSET and same.columns["qbar"].max() < QBAR_ONSET_PA


def test_the_nominal_maneuvers_span_the_envelope_in_attached_flow():
    from structsearch.flight.aero import truth_model
    from structsearch.flight.flighttest import PROCEDURES
    from structsearch.flight.nominal import simulate_nominal, with_air_data
    plan = [p for p in nominal_plan() if p.input == "doublet"]   # the six conditions
    citation = PROCEDURES["citation"]
    flown = [with_air_data(c) for c in simulate_nominal(plan, truth_model(envelope=True), 3, 1.0, citation.aircraft,
                                                        citation.fuel, citation.flown_cg_range)]
    mach, qbar = np.concatenate([c["Mach"] for c in flown]), np.concatenate([c["qbar"] for c in flown])
    assert mach.min() < 0.3 and mach.max() > 0.5
    assert qbar.min() < 4000 and qbar.max() > 8000
    for c in flown:   # attached flow, the doublet visible in the elevator
        assert c["X_ss_true"].min() > 0.99 and c["X_w_true"].min() > 0.99
        assert np.ptp(c["de"]) > 0.01


def test_the_plan_flies_every_input_at_every_condition():
    plan = nominal_plan()
    assert len(plan) == 24 and sum(p.split == "validation" for p in plan) == 8
    for name in INPUTS:
        mine = [p for p in plan if p.input == name]
        assert sorted(p.condition for p in mine) == list(range(6))
        assert {p.flight_level for p in mine if p.split == "validation"} != set()
    small = nominal_plan(0.05)
    assert {(p.input, p.split) for p in small} == {(n, s) for n in INPUTS for s in ("train", "validation")}


@pytest.mark.parametrize("widths", [(1, 1), (3, 2, 1, 1)])
def test_elevator_inputs_are_the_declared_pulses(widths):
    dt, unit = 0.01, 0.5
    t = np.arange(0, 10, dt)
    de = pulses(t, 2.0, unit, widths, 0.02)
    assert np.all(de[t < 2.0] == 0) and np.all(de[t >= 2.0 + sum(widths) * unit + 1e-9] == 0)
    edges = 2.0 + unit * np.cumsum((0,) + widths)
    for i, (a, b) in enumerate(zip(edges, edges[1:])):
        inside = de[(t >= a + dt / 2) & (t < b - dt / 2)]
        assert np.all(inside == 0.02 * (-1) ** i)


def test_the_attached_part_holds_the_states_at_one_and_names_what_it_cannot_place():
    part = attached_part(find_candidate("CL-G"))
    regs = dict(part.candidate.regressors)
    assert regs["CL_KL_ss_plus_CL_KL_w"] == "alpha" and "CL_Ma" in regs and not part.candidate.states
    lost = dict(part.unidentifiable)
    assert lost["a_star_ss"] == NOT_PLACED and lost["tau1_ss"] == NOT_PLACED
    assert dict(part.sums) == {"CL_KL_ss_plus_CL_KL_w": ("CL_KL_ss", "CL_KL_w")}
    pitch = find_candidate("Cm-G")
    part = attached_part(pitch, lift_candidate(pitch.lift))
    lost = dict(part.unidentifiable)
    assert lost["Cm_1mX_ssCL"] == VANISHES and lost["Cm_1mX_wCL"] == VANISHES and lost["a1_w"] == NOT_PLACED
    assert dict(part.sums) == {"Cm_de_plus_Cm_Xde_ss": ("Cm_de", "Cm_Xde_ss")}
    assert part.candidate.lift == "CL-G.nominal"   # the lift model's own attached-flow part
    assert attached_part(find_candidate("CL-G")).candidate.lift is None


def test_the_attached_drag_part_reads_the_lift_parts_cl_not_the_measured_one(simulated_campaign):
    """The measured C_L carries each maneuver's own noise, correlated with C_D's (both rotate the measured C_X,
    C_Z): a nominal-only drag model reading it would validate on the validation maneuvers' own noise while the
    global model reads its lift model's C_L. The attached part reads the C_L of the lift's attached part."""
    from structsearch.data.errors import StructSearchError
    from structsearch.fitting.lift_fit import LiftAt
    from structsearch.fitting.models import predict_candidate
    data = simulated_campaign(0, SCALE, nominal=True).of_kind("nominal")
    lift = find_candidate("CL-G")
    lift_part = attached_part(lift).candidate
    drag = attached_part(find_candidate("CD-G"), lift).candidate
    assert drag.lift == lift_part.name
    lift_params = {"CL0": 0.23, "CL_KL_ss_plus_CL_KL_w": 3.98, "CL_qstar": 8.07, "CL_de": -0.34, "CL_Ma": 3.0}
    cl = predict_candidate(lift_part, lift_params, data)
    assert np.std(cl - data["CL"]) > 1e-3   # the lift model's C_L is not the measured one
    drag_params = {"CD0": 0.0165, "CD_CT": 0.39, "CD_de": -0.19, "CD_CL2": 0.026, "CD_M2": 0.15}
    got = predict_candidate(drag, drag_params, data, LiftAt(lift_part, lift_params))
    by_hand = (0.0165 + 0.39 * data["CT"] - 0.19 * data["de"] + 0.026 * cl ** 2
               + 0.15 * np.maximum(data["Mach"] - MACH_ONSET, 0) ** 2)
    np.testing.assert_allclose(got, by_hand, rtol=1e-12, atol=1e-15)
    with pytest.raises(StructSearchError, match="needs the fitted lift model CL-G.nominal"):
        predict_candidate(drag, drag_params, data)   # never the measured C_L by default


def test_the_stall_part_drops_only_the_terms_the_data_never_excite(simulated_campaign):
    c = simulated_campaign(0, SCALE, nominal=True)
    lift = find_candidate("CL-G")
    stall = c.keeping(lambda m: m.kind != "nominal").data
    part = stall_part(lift, stall)
    assert dict(part.unidentifiable) == {"CL_Ma": ZERO_ON_STALL}
    assert [n for n, _ in part.candidate.regressors] == [n for n, _ in lift.regressors if n != "CL_Ma"]
    assert stall_part(lift, c.data).unidentifiable == ()   # where the envelope is flown, nothing is dropped


def test_validation_mse_is_pooled_per_kind():
    scores = SimpleNamespace(mse_maneuvers=(1.0, 3.0, 10.0, math.nan), n_maneuvers=(1, 3, 5, 7))
    out = regime_mse(SimpleNamespace(validation=scores), ["quasi-steady", "dynamic", "nominal", "nominal"])
    assert out["stall"] == pytest.approx((1 + 9) / 4) and out["nominal"] == 10.0


def test_by_kind_refuses_a_campaign_without_nominal_maneuvers(campaign_on_disk):
    from structsearch.api.by_kind import fit_by_kind
    with pytest.raises(DataError, match="nominal maneuvers among the train") as info:
        fit_by_kind(campaign_on_disk(0, SCALE), "CL-G")
    assert "campaign.toml" in str(info.value) and "kind" in str(info.value)


@pytest.mark.slow
def test_the_global_models_are_within_five_percent_of_the_separate_ones(simulated_campaign, tmp_path):
    """On a laboratory-clean campaign (no slow reconstruction errors: what is left of a validation MSE is the
    model's), each global model validates within 5 % of the model fitted to each kind alone, on each kind. With
    the slow errors the comparison is of models within noise of one another at this scale (README: the
    full-scale figure)."""
    from structsearch.api import Settings
    from structsearch.api.by_kind import fit_by_kind
    campaign = simulated_campaign(0, 0.1, nominal=True, slow_errors=0.0)
    res = fit_by_kind(campaign, "CL-G,CD-G,Cm-G", settings=Settings(starts=2, jobs=1), out=tmp_path)
    for c in res.comparisons:
        assert c.within("nominal") and c.within("stall"), (c.name, c.ratio("nominal"), c.ratio("stall"))
        # the attached-flow part knows no stall: the global model is needed there
        assert c.fit("nominal").validation_mse["stall"] > 5 * c.fit("all").validation_mse["stall"], c.name
        # each fit's drag and pitch read the C_L of the lift model fitted on the same maneuvers
        expected = {"all": "CL-G", "stall": "CL-G.stall", "nominal": "CL-G.nominal"}
        assert all(f.result.lift == (expected[f.fitted_on] if c.name != "CL-G" else None) for f in c.fits)
    assert res.passed


@pytest.mark.slow
def test_the_command_line_fits_by_kind_end_to_end(run_cli, tmp_path):
    data, out = tmp_path / "c", tmp_path / "out"
    done = run_cli("simulate", "--out", data, "--scale", SCALE, "--nominal")
    assert done.returncode == 0, done.stderr
    assert "nominal" in done.stdout
    done = run_cli("fit", "--data", data, "--model", "CL-G", "--by-kind", "--starts", 1, "--out", out)
    assert done.returncode == 0, done.stderr
    assert "CL-G.nominal" in done.stdout and "global / separate validation MSE" in done.stdout
    doc = json.loads((out / "by_kind.json").read_text())
    (cl,) = doc["by_kind"]
    assert [f["fitted_on"] for f in cl["fits"]] == ["all", "stall", "nominal"]
    nominal = cl["fits"][2]
    assert {u["parameter"] for u in nominal["unidentifiable"]} >= {"a_star_ss", "tau1_ss"}
    assert all(u["value"] is None for u in nominal["unidentifiable"])
    assert set(doc["validation_maneuvers"]) == {"nominal", "stall"}
    assert "attached-flow part" in (out / "by_kind.md").read_text()
    done = run_cli("fit", "--data", data, "--model", "CL-G", "--by-kind", "--joint", "CL-VI", "--out", out)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
