"""Candidates compared by maneuver-grouped cross-validation over the training maneuvers (issue 12 item 2)."""
import numpy as np
import pytest

from structsearch.data.flightdata import FlightData
from structsearch.engine.stallmodel import StallModel
from structsearch.flight.synthetic import campaign
from structsearch.search.candidate_result import CandidateResult, R2Summary, SplitScores
from structsearch.search.ranking import rank
from structsearch.search.runner import cross_validate, maneuver_folds


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
    return CandidateResult(name, "g", "CL", None, 0.0, names=tuple(f"p{i}" for i in range(n)),
                           train=scores(cv or validation), validation=scores(validation),
                           cv=scores(cv) if cv is not None else None, cv_folds=3 if cv is not None else 0)


def test_ranking_compares_by_cross_validation_not_by_validation():
    # "big" is better on validation, "small" on the held-out training maneuvers: the CV decides
    big = _candidate("big", 9, [1.1, 2.2, 3.3, 1.1], [1.0, 2.0, 3.0])
    small = _candidate("small", 6, [1.0, 2.0, 3.0, 1.0], [1.2, 2.4, 3.6])
    ranked = rank([big, small])
    assert [r.name for r in ranked] == ["small", "big"] and not ranked[1].within_noise
    assert ranked[1].gap == pytest.approx(0.1)


def test_too_few_maneuvers_give_no_standard_error():
    """Two validation maneuvers (no CV): the gap's standard error is n/a (NaN), not 0."""
    a = _candidate("a", 3, None, [1.0, 2.0])
    b = _candidate("b", 3, None, [1.005, 2.01])
    ranked = rank([a, b])
    assert all(np.isnan(r.gap_se) for r in ranked)
    assert ranked[1].within_noise  # 0.5 % < the 1 % practical tolerance


def test_scores_that_could_not_be_computed_survive_the_cache_as_nan():
    """A NaN held-out MSE and an n/a gap standard error are written as null and read back as NaN."""
    c = _candidate("a", 3, [1.0, float("nan")], [1.0, 2.0])
    ranked = rank([c])[0]
    back = CandidateResult.from_json(ranked.to_json())
    assert np.isnan(back.cv.mse_maneuvers[1]) and np.isnan(back.gap_se) and back.cv_folds == 3
