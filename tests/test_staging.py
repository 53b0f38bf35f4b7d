"""Staged, warm-started fits (issue 17 item 2): waves, donors, the single fit's chain, and that staging
reaches the optimum that many quasi-random starts find."""
from dataclasses import replace as dataclasses_replace
from pathlib import Path

import numpy as np
import pytest
from conftest import stated_result

from structsearch.fitting.candidate_result import R2Summary, SplitScores
from structsearch.fitting.staging import DonorEstimate
from structsearch.fitting.candidates import Candidate
from structsearch.fitting.options import FitOptions
from structsearch.fitting.candidate_fit import fit_candidate, fit_staged
from structsearch.fitting.runner import run
from structsearch.fitting.specs import load_grid, resolve_candidate
from structsearch.fitting.staging import feeds, stages, warm_start, waves


def test_waves_fit_every_candidate_after_the_ones_that_feed_it():
    grid = load_grid("separation")
    order = waves(grid.candidates)
    wave_of = {grid.candidates[i].name: w for w, members in enumerate(order) for i in members}
    assert sorted(i for members in order for i in members) == list(range(len(grid.candidates)))
    for a in grid.candidates:
        for b in grid.candidates:
            if feeds(b, a):
                assert wave_of[b.name] < wave_of[a.name], (b.name, a.name)
    # S -> Q -> U for one state, in parallel with the two-state chain
    assert wave_of["X S"] == wave_of["X_ss/X_w S/S"] == 0
    assert wave_of["X Q"] == 1 and wave_of["X U"] == 2 and wave_of["X_ss/X_w U/S"] == 2
    assert wave_of["X_ss/X_w U/U"] == 4
    # drag and pitch candidates take the lift model's states: nothing to stage, one wave
    assert len(waves(load_grid("pitch", load_grid("lift")).candidates)) == 1


def test_regressors_order_candidates_with_the_same_parameters():
    lift = load_grid("lift")
    assert feeds(lift["CL-III"], lift["CL-IV"]) and not feeds(lift["CL-IV"], lift["CL-V"])
    assert not feeds(lift["CL-IV"], lift["CL-III"])


def _result(c: Candidate, params: dict, mse: float) -> DonorEstimate:
    """What a warm start reads of a fit (from a candidate's record, as the scheduler makes it)."""
    scores = SplitScores(mse, (mse,), (100,), R2Summary(0.9, 0.9, 0.9))
    return DonorEstimate.of(stated_result(c.name, c.grid, c.coefficient, None, 0.0, names=tuple(params),
                                   params=dict(params), train=scores, validation=scores))


def test_warm_start_comes_from_the_closest_donor_with_the_lowest_mse():
    grid = load_grid("separation")
    us = grid["X_ss/X_w U/S"]
    qs, ss, sq = grid["X_ss/X_w Q/S"], grid["X_ss/X_w S/S"], grid["X_ss/X_w S/Q"]
    fitted = [(ss, _result(ss, {"a1_ss": 1.0, "a_star_ss": 0.1, "a1_w": 2.0, "a_star_w": 0.3}, 1.0)),
              (qs, _result(qs, {"tau2_ss": 0.2, "a1_ss": 3.0, "a_star_ss": 0.15, "a1_w": 4.0, "a_star_w": 0.31},
                           2.0)),
              (sq, _result(sq, {"tau2_w": 0.2, "a1_ss": 5.0, "a_star_ss": 0.15, "a1_w": 4.0, "a_star_w": 0.31},
                           0.5))]
    # S/Q shares five parameters too but is not a subset of U/S's (tau2_w): Q/S is the donor
    assert warm_start(us, fitted) == {"tau2_ss": 0.2, "a1_ss": 3.0, "a_star_ss": 0.15, "a1_w": 4.0,
                                      "a_star_w": 0.31}
    assert warm_start(ss, fitted[1:]) is None  # nothing with a subset of its parameters
    assert warm_start(load_grid("pitch", load_grid("lift"))["Cm-I"], fitted) is None


def test_a_single_fit_starts_from_its_quasi_steady_version_too():
    cl6 = resolve_candidate("CL-VI")
    assert [dict(c.states) for c in stages(cl6)] == [{"ss": "Q", "w": "S"}]
    assert stages(load_grid("separation")["X_ss/X_w S/S"]) == []
    assert stages(load_grid("separation")["X_ss/X_w Q/Q"]) == []
    assert [dict(c.states) for c in stages(load_grid("separation")["X_ss/X_w U/U"])] == [{"ss": "Q", "w": "Q"}]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    from structsearch.data.campaign import read_campaign, write_campaign
    from structsearch.flight.flighttest import build_campaign
    path = tmp_path_factory.mktemp("campaign") / "c"
    write_campaign(build_campaign(seed=3, scale=0.05), path)
    return read_campaign(path)


def test_staged_fit_reaches_the_optimum_of_many_quasi_random_starts(tiny):
    """CL-VI from its quasi-steady stage's estimates plus the default starts, against 16 quasi-random
    starts of CL-VI itself: the same training MSE."""
    train, validation = tiny.split("train"), tiny.split("validation")
    c = resolve_candidate("CL-VI")
    options = FitOptions(cv_folds=0)
    staged = fit_staged(c, train, validation, None, options)
    many = fit_candidate(c, train, validation, None, FitOptions(n_starts=16, cv_folds=0))
    # the stage's estimates, the stage's optimum with tau1 at its nesting value 0, declared, quasi-random
    assert staged.optimizer.n_starts == 2 + FitOptions().n_starts
    assert staged.mse_train <= many.mse_train * (1 + 1e-7)


def test_a_staged_grid_is_served_from_the_cache_on_the_second_run(tiny, tmp_path):
    grid = load_grid("separation")
    cands = [grid["X S"], grid["X Q"], grid["X U"]]
    first = run(cands, tiny, tmp_path)
    messages = []
    again = run(cands, tiny, tmp_path, progress=messages.append)
    assert [r.mse_train for r in again] == [r.mse_train for r in first]
    assert messages == ["3 of 3 candidates from the cache"]
    # X U started from X Q's estimates, X Q's optimum with tau1 at 0 (the nested start) and its declared start,
    # X S from quasi-random starts
    assert first[2].optimizer.n_starts == 3 and first[0].optimizer.n_starts == FitOptions().n_starts
    assert first[2].mse_train <= first[1].mse_train    # never worse than the structure it contains
    assert np.isfinite(first[2].mse_train)


def test_rank_test_with_fewer_samples_than_parameters_names_the_null_directions():
    """Review regression: R of a 2 x 3 Jacobian has two rows; the third direction is a null one."""
    from structsearch.engine.identifiability import rank_reasons
    jac = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    assert set(rank_reasons(jac, ["a", "b", "c"])) == {"a", "b", "c"}


def test_the_state_memo_never_serves_another_theta():
    from structsearch.flight.synthetic import campaign
    data = campaign({"dynamic": 2}, duration=10.0, seed=2)
    model = resolve_candidate("CL-VI")
    from structsearch.fitting.models import build_model
    m = build_model(model)
    problem = m.bind(data)
    a, b = m.start_vector(), m.start_vector() * 1.1
    first = problem.regression_matrix(a)
    problem.evaluate(b)
    again = problem.regression_matrix(a)
    fresh = m.bind(data).regression_matrix(a)
    assert np.array_equal(first, again) and np.array_equal(again, fresh)
    assert not np.array_equal(problem.regression_matrix(b), fresh)


def test_fixed_states_are_shared_per_data_and_keyed_by_their_values():
    """A grid's drag and pitch candidates read the lift model's states with fixed parameters: computed
    once per data set, never served for other values or other data, and never pickled."""
    import dataclasses
    import pickle
    from structsearch.engine.stallmodel import FIXED_STATES_KEPT
    from structsearch.flight.synthetic import campaign
    from structsearch.fitting.models import build_model
    data = campaign({"dynamic": 2}, duration=10.0, seed=2)
    lift = build_model(resolve_candidate("CL-VI"))
    fixed = dict(zip(lift.nonlinear_names, lift.start_vector()))
    pinned = dataclasses.replace(lift, fixed=fixed)   # every separation parameter fixed
    assert not pinned.nonlinear_names
    one = pinned.bind(data).state_values(np.zeros(0))
    two = pinned.bind(data).state_values(np.zeros(0))
    assert all(one[s][1] is two[s][1] and not one[s][1].flags.writeable for s in one)
    free = lift.bind(data).state_values(lift.start_vector(), False)
    assert all(np.array_equal(one[s][1], free[s][1]) for s in one)
    moved = dataclasses.replace(lift, fixed={**fixed, "a_star_ss": fixed["a_star_ss"] + 0.01})
    other = moved.bind(data).state_values(np.zeros(0))
    assert not np.array_equal(other["X_ss"][1], one["X_ss"][1]) and other["X_w"][1] is one["X_w"][1]
    elsewhere = campaign({"dynamic": 2}, duration=10.0, seed=3)
    assert not np.array_equal(pinned.bind(elsewhere).state_values(np.zeros(0))["X_ss"][1], one["X_ss"][1])
    assert "_memo" not in pickle.loads(pickle.dumps(data)).__dict__
    # the problem's memo of its last states still serves a model with some parameters fixed (review: a
    # shadowed key made it miss)
    partly = dataclasses.replace(lift, fixed={k: v for k, v in fixed.items() if k.endswith("_w")})
    problem = partly.bind(data)
    theta = partly.start_vector()
    assert problem.state_values(theta) is problem.state_values(theta)
    for i in range(2 * FIXED_STATES_KEPT):  # a loop over fixed values keeps a bounded number
        dataclasses.replace(lift, fixed={**fixed, "a1_ss": 20.0 + i}).bind(data).state_values(np.zeros(0))
    assert len(data.memo("fixed separation states")) == FIXED_STATES_KEPT


def test_the_two_step_covariance_is_the_same_from_a_white_fit_with_its_factor(tiny):
    """The search fits a drag or pitch candidate with the white covariance and hands its Jacobian's
    inverse factor to the two-step estimator, which replaces the covariance: the same as fitting with
    the requested kind and factorising again."""
    from structsearch.fitting.lift_uncertainty import with_lift_uncertainty
    from structsearch.fitting.models import build_model
    from structsearch.fitting.lift_context import lift_context
    from structsearch.fitting.lift_fit import LiftFit
    train, validation = tiny.split("train"), tiny.split("validation")
    candidate = resolve_candidate("Cm-XXXIIIr")
    lift_candidate = resolve_candidate(candidate.lift)
    lift = LiftFit(lift_candidate, fit_staged(lift_candidate, train, validation, None, FitOptions()))
    context = lift_context(train, validation, lift)
    model = build_model(candidate, lift)
    white = model.fit(context.train, covariance="white")
    assert white.jacobian_inverse_factor is not None
    quick = with_lift_uncertainty(white, model, train, lift, context, "hac-maneuver")
    full = model.fit(context.train, covariance="hac-maneuver")
    slow = with_lift_uncertainty(dataclasses_replace(full, covariance_basis=None, jacobian_inverse_factor=None),
                                 model, train, lift, context)
    assert quick.covariance_kind == slow.covariance_kind == "hac-maneuver"
    # equal up to rounding: the two QRs of the same Jacobian may round differently (memory alignment), and
    # the sandwich amplifies that by the condition number squared
    assert np.allclose(quick.covariance, slow.covariance, rtol=1e-6, atol=1e-9 * np.nanmax(np.abs(slow.covariance)),
                       equal_nan=True)
    assert np.array_equal(np.isnan(quick.covariance), np.isnan(slow.covariance))
    assert quick.bandwidth == slow.bandwidth
    assert np.allclose(quick.effective_maneuvers, slow.effective_maneuvers, rtol=1e-6, equal_nan=True)
    # and it is the two-step covariance, not the white one it replaced
    assert not np.allclose(quick.covariance, white.covariance, equal_nan=True)


def test_a_campaign_split_is_read_only(tiny):
    train = tiny.split("train")
    assert train is tiny.split("train")
    with pytest.raises(ValueError):
        train["alpha"][0] = 0.0


def test_a_candidate_that_is_an_earlier_grids_model_is_served_its_fit(tiny, tmp_path):
    """The lift grid's CL-VI is the separation grid's X_ss/X_w U/S under another name: --grid all fits it
    once. Another search box is another question: fitted anew."""
    import dataclasses
    from structsearch.fitting.runner import same_model_fitted
    us = load_grid("separation")["X_ss/X_w U/S"]
    cl_vi = load_grid("lift")["CL-VI"]
    first = run([us], tiny, tmp_path, options=FitOptions(cv_folds=0))[0]
    said = []
    served = run([cl_vi], tiny, tmp_path, options=FitOptions(cv_folds=0), fitted_before=[(us, first)],
                 progress=said.append)[0]
    assert served.name == "CL-VI" and served.grid == "lift" and served.estimates.params == first.estimates.params
    assert served.placement is None  # the ranking judges it afresh
    assert any("the same model as separation X_ss/X_w U/S" in m for m in said)
    assert len(list((tmp_path / "cache" / "lift").glob("CL-VI-*.json"))) == 1  # cached under its own name
    # a twin fitted elsewhere (not in this run's cache) is not served: fitted anew
    said.clear()
    run([cl_vi], tiny, tmp_path / "elsewhere", options=FitOptions(cv_folds=0), fitted_before=[(us, first)],
        progress=said.append)
    assert not any("the same model" in m for m in said)
    boxed = dataclasses.replace(cl_vi, bounds=(("tau1_ss", (0.0, 1.0)),))
    assert same_model_fitted([cl_vi, boxed], [(us, first)]).keys() == {0}
    failed = dataclasses.replace(first, error="FitError: x", estimates=None)
    assert same_model_fitted([cl_vi], [(us, failed)]) == {}


def test_the_cross_validation_method_keys_only_candidates_that_may_be_nonlinear(tiny):
    """A linear candidate's folds are exact with either method: one cache entry serves both; a nonlinear
    candidate's are not; without folds the method is moot."""
    from structsearch.fitting.runner import cache_path, campaign_fingerprint
    key = campaign_fingerprint(tiny)
    refit, one_step = FitOptions(), FitOptions(cv_method="one-step")
    cl_vi, cd_i = resolve_candidate("CL-VI"), resolve_candidate("CD-I")
    lift = {"tau1": 0.3, "tau2": 0.1, "a1": 30.0, "a_star": 0.2, "CL0": 0.1}   # CD-I's lift model, CL-I
    assert cache_path(Path("o"), cl_vi, key, None, refit) != cache_path(Path("o"), cl_vi, key, None, one_step)
    assert cache_path(Path("o"), cd_i, key, lift, refit) == cache_path(Path("o"), cd_i, key, lift, one_step)
    no_folds = FitOptions(cv_folds=0)
    assert cache_path(Path("o"), cl_vi, key, None, no_folds) == \
        cache_path(Path("o"), cl_vi, key, None, FitOptions(cv_folds=0, cv_method="one-step"))
