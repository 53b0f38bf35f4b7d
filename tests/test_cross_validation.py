"""Candidates compared by maneuver-grouped cross-validation over the training maneuvers (issue 12 item 2)."""
import numpy as np
import pytest

from structsearch.data.flightdata import FlightData
from structsearch.engine.stallmodel import StallModel
from structsearch.flight.synthetic import campaign
from structsearch.fitting.candidate_result import CandidateResult, R2Summary, SplitScores
from structsearch.grid_search.ranking import rank
from structsearch.fitting.cross_validation import cross_validate, maneuver_folds
from structsearch.flight.reference import FINAL_LIFT

from conftest import central_difference, stated_result


def test_folds_group_maneuvers_round_robin_and_refuse_tiny_folds():
    # at least 3 maneuvers per fold: 10 maneuvers give 3 folds, not 5
    assert maneuver_folds(10, 5) == [[0, 3, 6, 9], [1, 4, 7], [2, 5, 8]]
    assert maneuver_folds(40, 5)[0] == list(range(0, 40, 5))
    assert maneuver_folds(5, 5) == [] and maneuver_folds(6, 5) == [[0, 2, 4], [1, 3, 5]]
    assert maneuver_folds(40, 0) == []
    folds = maneuver_folds(23, 5)
    assert sorted(i for f in folds for i in f) == list(range(23))


def test_held_out_residuals_come_from_fits_that_did_not_see_the_maneuver():
    base = campaign({"quasi-steady": 3, "dynamic": 3}, duration=20.0, seed=4)
    rng = np.random.default_rng(9)
    y = 0.2 + 4.0 * base["alpha"] + 0.01 * rng.standard_normal(base.n_samples)
    # one maneuver carries an offset that only a fit including it can absorb
    sl = base.segment_slices()
    y[sl[4]] += 0.05
    data = FlightData({**base.columns, "CL": y}, base.starts, base.names, base.source, base.constants)
    model = StallModel.declare("lin", "CL", regressors={"c0": "1", "ca": "alpha"})
    full = model.fit(data, covariance="white")
    folds = maneuver_folds(6, 5)
    held = cross_validate(model, data, full, folds)
    for fold in folds:
        rest = [i for i in range(6) if i not in fold]
        x = np.column_stack([np.ones(base.n_samples), base["alpha"]])
        idx = np.concatenate([np.arange(sl[i].start, sl[i].stop) for i in rest])
        coef, *_ = np.linalg.lstsq(x[idx], y[idx], rcond=None)
        for i in fold:
            assert np.allclose(held[sl[i]], y[sl[i]] - x[sl[i]] @ coef, atol=1e-10)
    # the held-out error of the offset maneuver is larger than its in-sample one
    assert np.mean(held[sl[4]] ** 2) > np.mean((y - model.predict(data, full.params))[sl[4]] ** 2)


def _candidate(name, n, cv, validation):
    def scores(per):
        return SplitScores(float(np.mean(per)), tuple(per), (100,) * len(per), R2Summary(0.9, 0.8, 1.0))
    return stated_result(name, "g", "CL", None, 0.0, names=tuple(f"p{i}" for i in range(n)),
                           train=scores(cv or validation), validation=scores(validation),
                           cv=scores(cv) if cv is not None else None, cv_folds=3 if cv is not None else 0)


def test_ranking_compares_by_cross_validation_not_by_validation():
    # "big" is better on validation, "small" on the held-out training maneuvers: the CV decides
    big = _candidate("big", 9, [1.1, 2.2, 3.3, 1.1], [1.0, 2.0, 3.0])
    small = _candidate("small", 6, [1.0, 2.0, 3.0, 1.0], [1.2, 2.4, 3.6])
    ranked = rank([big, small])
    assert [r.name for r in ranked] == ["small", "big"] and not ranked[1].placement.within_noise
    assert ranked[1].placement.gap == pytest.approx(0.1)


def test_too_few_maneuvers_give_no_standard_error():
    """Two validation maneuvers (no CV): the gap's standard error is n/a (NaN), not 0."""
    a = _candidate("a", 3, None, [1.0, 2.0])
    b = _candidate("b", 3, None, [1.005, 2.01])
    ranked = rank([a, b])
    assert all(np.isnan(r.placement.gap_se) for r in ranked)
    assert ranked[1].placement.within_noise  # 0.5 % < the 1 % practical tolerance


def test_scores_that_could_not_be_computed_survive_the_cache_as_nan():
    """A NaN held-out MSE and an n/a gap standard error are written as null and read back as NaN."""
    c = _candidate("a", 3, [1.0, float("nan")], [1.0, 2.0])
    ranked = rank([c])[0]
    back = CandidateResult.from_json(ranked.to_json())
    assert np.isnan(back.cv.mse_maneuvers[1]) and np.isnan(back.placement.gap_se) and back.cv_folds == 3


@pytest.fixture(scope="module")
def lift_fit(noise_free_lift):
    """The final lift model fitted to its own output plus seeded noise on six maneuvers."""
    model, data = noise_free_lift
    rng = np.random.default_rng(21)
    y = data["CL"] + 0.01 * rng.standard_normal(data.n_samples)
    noisy = FlightData({**data.columns, "CL": y}, data.starts, data.names, data.source, data.constants)
    start = {k: v for k, v in FINAL_LIFT.items() if k in model.nonlinear_names}
    return model, noisy, model.fit(noisy, start=start, covariance="white")


def _gauss_newton_folds(model, data, params, folds, frozen=()):
    """Independent reference: the model's Jacobian in every parameter but ``frozen`` by central
    differences of its prediction, and per fold the least-squares step on the other maneuvers (numpy
    lstsq); returns the held-out residuals after the step."""
    names = model.nonlinear_names + model.linear_names
    x0 = np.array([params[n] for n in names])
    jac = central_difference(lambda x: model.predict(data, dict(zip(names, x))), x0)
    jac = jac[:, [i for i, n in enumerate(names) if n not in frozen]]
    r = data["CL"] - model.predict(data, params)
    sl = data.segment_slices()
    out = np.full_like(r, np.nan)
    for fold in folds:
        rest = np.concatenate([np.arange(sl[i].start, sl[i].stop) for i in range(len(sl)) if i not in fold])
        step, *_ = np.linalg.lstsq(jac[rest], r[rest], rcond=None)
        for i in fold:
            out[sl[i]] = r[sl[i]] - jac[sl[i]] @ step
    return out


def test_one_step_folds_are_one_gauss_newton_step_from_the_full_fit(lift_fit):
    model, data, full = lift_fit
    folds = maneuver_folds(6, 5)
    one_step = cross_validate(model, data, full, folds, "one-step")
    expected = _gauss_newton_folds(model, data, full.params, folds)
    assert np.allclose(one_step, expected, rtol=0, atol=1e-6 * np.max(np.abs(expected)))


def test_one_step_cross_validation_is_close_to_refitting_the_folds(lift_fit):
    model, data, full = lift_fit
    folds = maneuver_folds(6, 5)
    refit = cross_validate(model, data, full, folds, "refit")
    one_step = cross_validate(model, data, full, folds, "one-step")
    in_sample = data["CL"] - model.predict(data, full.params)
    sl = data.segment_slices()
    for s in sl:
        mse_refit, mse_step = np.mean(refit[s] ** 2), np.mean(one_step[s] ** 2)
        assert abs(mse_step / mse_refit - 1) < 0.02, (mse_step, mse_refit)
    # both are held-out errors: larger than the in-sample one on the whole
    assert np.mean(one_step ** 2) > np.mean(in_sample ** 2) and np.mean(refit ** 2) > np.mean(in_sample ** 2)


def test_a_gauss_newton_step_on_a_linear_model_lands_on_the_folds_exact_fits():
    """Why a linear candidate's folds are exact with either method: the one-step form (the least-squares
    step on the full fit's Jacobian and residual) equals refitting each fold (numpy lstsq)."""
    from structsearch.engine.ols import held_out_residuals
    base = campaign({"quasi-steady": 3, "dynamic": 3}, duration=20.0, seed=4)
    rng = np.random.default_rng(3)
    y = 0.2 + 4.0 * base["alpha"] + 0.01 * rng.standard_normal(base.n_samples)
    phi = np.column_stack([np.ones(base.n_samples), base["alpha"], base["alpha"] ** 2])
    coef, *_ = np.linalg.lstsq(phi, y, rcond=None)
    folds = maneuver_folds(6, 5)
    one_step = held_out_residuals(phi, y - phi @ coef, base.bounds, folds)
    sl = base.segment_slices()
    for fold in folds:
        rest = np.concatenate([np.arange(sl[i].start, sl[i].stop) for i in range(6) if i not in fold])
        fold_coef, *_ = np.linalg.lstsq(phi[rest], y[rest], rcond=None)
        for i in fold:
            assert np.allclose(one_step[sl[i]], y[sl[i]] - phi[sl[i]] @ fold_coef, rtol=0, atol=1e-10)


def test_one_step_folds_keep_a_parameter_on_its_bound_where_the_fit_left_it(lift_fit):
    """A parameter the full fit left on a bound (or could not identify) is not stepped: a refit of the
    fold could not move it past the bound either. Reference: the least-squares step without its column."""
    import dataclasses
    model, data, full = lift_fit
    name = model.nonlinear_names[0]
    pinned = dataclasses.replace(full, lower=np.where(np.arange(len(full.lower)) == 0, full.values[0],
                                                      full.lower))
    assert pinned.at_bound == {name: "lower"}
    folds = maneuver_folds(6, 5)
    one_step = cross_validate(model, data, pinned, folds, "one-step")
    expected = _gauss_newton_folds(model, data, full.params, folds, frozen=(name,))
    assert np.allclose(one_step, expected, rtol=0, atol=1e-6 * np.max(np.abs(expected)))
    # a parameter the data cannot identify is held the same way
    other = model.nonlinear_names[1]
    unidentified = dataclasses.replace(full, unidentifiable={other: "for the test"})
    expected = _gauss_newton_folds(model, data, full.params, folds, frozen=(other,))
    assert np.allclose(cross_validate(model, data, unidentified, folds, "one-step"), expected, rtol=0,
                       atol=1e-6 * np.max(np.abs(expected)))
    # and it differs from stepping every parameter
    assert not np.allclose(one_step, cross_validate(model, data, full, folds, "one-step"), rtol=0, atol=1e-9)


def test_candidates_of_different_cross_validation_methods_are_not_compared_by_it():
    import dataclasses
    nonlinear = dict(nonlinear_names=("p0",))
    a = stated_result(**{**_candidate("a", 3, [1.0, 2.0, 3.0], [1.3, 2.6, 3.9]).__dict__, **nonlinear})
    b = stated_result(**{**_candidate("b", 3, [1.2, 2.4, 3.6], [1.0, 2.0, 3.0]).__dict__, "cv_method": "one-step",
                         **nonlinear})
    assert [r.name for r in rank([a, b])] == ["b", "a"]  # by validation: b is better there
    b_refit = dataclasses.replace(b, cv_method="refit")
    assert [r.name for r in rank([a, b_refit])] == ["a", "b"]  # same method: by the CV
    back = CandidateResult.from_json(b.to_json())
    assert back.cv_method == "one-step"
    # a linear candidate's folds are exact fits whatever the method: it is compared by the CV with either
    linear = stated_result(**{**b.__dict__, "nonlinear_names": ()})
    assert [r.name for r in rank([a, linear])] == ["a", "b"]


def test_an_unknown_cross_validation_method_is_one_clear_error():
    from structsearch.data.errors import StructSearchError
    from structsearch.fitting.options import FitOptions
    with pytest.raises(StructSearchError, match="one of refit, one-step, not 'jackknife'"):
        FitOptions(cv_method="jackknife")


def test_the_bench_compares_two_rankings_candidate_by_candidate():
    import dataclasses
    from structsearch.experiments.bench import ranking_agreement
    a = rank([_candidate("a", 3, [1.0, 2.0, 3.0], [1.0, 2.0, 3.0]),
              _candidate("b", 3, [1.5, 3.0, 4.5], [1.0, 2.0, 3.0])])
    b = rank([_candidate("a", 3, [1.6, 3.2, 4.8], [1.0, 2.0, 3.0]),
              _candidate("b", 3, [1.5, 3.0, 4.5], [1.0, 2.0, 3.0])])
    a = [s.placed(admissible=True) for s in a]
    b = [s.placed(admissible=s.name == "b") for s in b]
    out = ranking_agreement({"g": a}, {"g": b})
    assert out["same_first"] == {"g": False} and out["same_admissible"] == {"g": False}
    assert out["moved"] == {"g": ["a", "b"]}
    assert out["max_rel_cv_difference"]["g"] == pytest.approx(0.6)
    same = ranking_agreement({"g": a}, {"g": a})
    assert same["same_first"]["g"] and same["moved"]["g"] == [] and same["max_rel_cv_difference"]["g"] == 0
