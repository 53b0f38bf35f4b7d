"""The library-free floor and the signals a residual follows (issue 14 items 1 and 2)."""
import numpy as np
import pytest

from structsearch.data.flightdata import from_segments
from structsearch.diagnosis import floor as fl


def _campaign(rng, n_maneuvers, n=800):
    """Maneuvers with independent smooth signals (alpha, V, h, de) and a separation-like state."""
    segments = []
    for _ in range(n_maneuvers):
        t = np.arange(n) * 0.05
        alpha = 0.1 + 0.12 * np.sin(2 * np.pi * t / rng.uniform(15, 30) + rng.uniform(0, 6))
        V = rng.uniform(70, 110) + 5 * np.sin(2 * np.pi * t / rng.uniform(10, 40))
        h = np.full(n, rng.uniform(2000, 6000)) + 20 * t
        de = 0.02 * np.sin(2 * np.pi * t / rng.uniform(3, 9))
        segments.append({"t": t, "alpha": alpha, "V": V, "h": h, "de": de, "q": np.gradient(alpha, t),
                         "CL": np.zeros(n), "CL_true": np.zeros(n), "alpha_unlagged_true": alpha})
    return from_segments(segments)


@pytest.fixture(scope="module")
def split():
    rng = np.random.default_rng(11)
    return _campaign(rng, 12), _campaign(rng, 5), rng


def _residual(data, rng, follows=None):
    noise = 0.01 * rng.standard_normal(data.n_samples)
    if follows is None:
        return noise
    signal = data[follows]
    return noise + 0.03 * (signal - signal.mean()) / signal.std()


def test_signals_exclude_outputs_and_truth_and_add_state_and_time(split):
    train, _, _ = split
    sig = fl.signals(train, np.ones(train.n_samples))
    assert {"alpha", "V", "h", "de", "q", "X", "time_in_maneuver"} <= set(sig)
    assert not {"CL", "CL_true", "t", "alpha_unlagged_true"} & set(sig)  # outputs and what only a simulator has
    assert sig["time_in_maneuver"][0] == 0.0 and np.all(sig["time_in_maneuver"] >= 0)


@pytest.mark.parametrize("follows", ["V", "h", "de"])
def test_a_residual_that_follows_one_signal_ranks_it_first(split, follows):
    """The flexible floor removes the signal's part on unseen maneuvers; the one-signal ranking names it."""
    train, val, rng = split
    st, sv = fl.signals(train, np.ones(train.n_samples)), fl.signals(val, np.ones(val.n_samples))
    r_train, r_val = _residual(train, rng, follows), _residual(val, rng, follows)
    flex = fl.flexible_fit(r_train, train, st, r_val, sv, seed=0)
    assert flex.n_iter > 0 and flex.mse < 0.3 * np.mean(r_val ** 2)
    assert flex.mse > 0.5 * 0.01 ** 2  # it does not remove the white noise
    ranked = fl.ranked_signals(r_train, st, r_val, sv)
    assert ranked[0].name == follows, [f.name for f in ranked[:3]]


def test_pure_noise_leaves_the_floor_where_it_is(split):
    train, val, rng = split
    st, sv = fl.signals(train, np.ones(train.n_samples)), fl.signals(val, np.ones(val.n_samples))
    r_train, r_val = _residual(train, rng), _residual(val, rng)
    flex = fl.flexible_fit(r_train, train, st, r_val, sv, seed=0)
    assert flex.mse > 0.97 * np.mean(r_val ** 2)  # nothing generalises across maneuvers


def test_signal_fit_is_the_binned_mean():
    x = np.repeat(np.arange(4.0), 50)
    r = np.repeat([1.0, -1.0, 2.0, 0.5], 50)
    f = fl.signal_fit("x", r, x, r, x)
    assert np.allclose(np.interp(np.arange(4.0), f.centres, f.values), [1.0, -1.0, 2.0, 0.5])
    assert f.mse == pytest.approx(0.0, abs=1e-24)
