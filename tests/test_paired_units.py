"""Records of few long maneuvers: their out-of-sample scores are also kept per smaller unit (the cycles of a
periodic record, contiguous blocks of another), and the adoption test pairs those units, saying so."""
import numpy as np
import pytest

from structsearch.data.flightdata import from_segments
from structsearch.discovery.adoption import move_test
from structsearch.engine.scores import R2Summary
from structsearch.fitting.candidate_result import SplitScores
from structsearch.fitting.folds import UNITS_BELOW_MANEUVERS, score_units

RATE = 100.0


def _record(seconds: float, hz: float = 1.0):
    t = np.arange(0.0, seconds, 1.0 / RATE)
    return {"t": t, "alpha": 0.1 + 0.1 * np.sin(2 * np.pi * hz * t), "V": np.full_like(t, 30.0),
            "CL": np.zeros_like(t)}


def test_a_periodic_record_is_cut_into_its_cycles_and_another_into_blocks():
    data = from_segments([_record(3.0), _record(4.0), _record(0.5)], periods=[1.0, None, None],
                         constants={"cbar": 0.5})
    rows, label = score_units(data)
    assert label == "blocks and cycles"
    lengths = [b - a for a, b in rows]
    assert lengths[:3] == [100, 100, 100]                       # three cycles of 1 s at 100 Hz
    assert sum(lengths[3:-1]) == 400 and len(lengths[3:-1]) == 5  # 4 s of blocks: five (the most folds)
    assert lengths[-1] == 50                                     # too short to cut: the maneuver itself
    assert rows[0][0] == 0 and all(a == b for (_, a), (b, _) in zip(rows[:-1], rows[1:])) and rows[-1][1] == 750


def test_maneuvers_too_short_to_cut_give_no_units():
    data = from_segments([_record(0.3), _record(0.3)], constants={"cbar": 0.5})
    assert score_units(data) == ((), "")


def _scores(mse_maneuvers, mse_units):
    r2 = R2Summary(np.nan, np.nan, np.nan)
    units = {} if mse_units is None else {"mse_units": tuple(mse_units), "n_units": (100,) * len(mse_units),
                                          "units": "cycles"}
    return SplitScores(float(np.mean(mse_maneuvers)), tuple(mse_maneuvers), (100,) * len(mse_maneuvers), r2, **units)


class _Result:
    """What the adoption test reads of a fit: its held-out scores."""

    def __init__(self, validation, cv=None):
        self.validation, self.cv, self.failed, self.estimates, self.cv_method = validation, cv, False, None, "refit"


def test_two_maneuvers_give_no_test_and_their_cycles_give_one_that_says_so():
    rng = np.random.default_rng(3)
    parent_units = 1.0 + 0.1 * rng.random(12)
    child_units = 0.5 * parent_units * (1 + 0.05 * rng.standard_normal(12))
    parent = _Result(_scores([1.0, 1.1], None))
    child = _Result(_scores([0.5, 0.55], None))
    test = move_test(parent, child, alpha=0.1, n_moves=5)
    assert not np.isfinite(test.p_value) and "2 maneuvers" in test.reason and not test.improves
    parent = _Result(_scores([1.0, 1.1], parent_units))
    child = _Result(_scores([0.5, 0.55], child_units))
    test = move_test(parent, child, alpha=0.1, n_moves=5)
    assert test.n_maneuvers == 12 and test.basis == "validation, paired by cycles"
    assert test.p_value < 1e-6 and test.improves
    assert test.gain == pytest.approx(np.mean(1 - child_units / parent_units), rel=1e-12)


def test_the_units_are_kept_only_below_the_threshold_and_survive_the_cache():
    scores = _scores([1.0, 1.1], [0.5, 0.6, 0.4])
    assert SplitScores.from_json(scores.to_json()) == scores
    plain = _scores([1.0] * UNITS_BELOW_MANEUVERS, None)
    assert "units" not in plain.to_json() and SplitScores.from_json(plain.to_json()) == plain
    from structsearch.fitting.candidate_fit import _unit_scores
    from structsearch.fitting.options import FitOptions
    data = from_segments([_record(3.0)], periods=[1.0], constants={"cbar": 0.5})
    residual = np.repeat([1.0, 2.0, 3.0], 100)
    scores, label = _unit_scores(data, data["CL"], residual, FitOptions(), 1)
    assert label == "cycles" and np.allclose(scores.mse, [1.0, 4.0, 9.0], rtol=1e-12)
    assert _unit_scores(data, data["CL"], residual, FitOptions(), UNITS_BELOW_MANEUVERS) is None
