"""Choices that rounding could reorder (engine/ties.py) give the same answer under rounding-size perturbations."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from structsearch.engine.ties import TIE_RTOL, first_of_lowest, is_tie, sort_with_ties

values = st.lists(st.floats(1e-6, 1e3), min_size=1, max_size=12)


def _jitter(xs, seed, size=1e-13):
    """Each value moved by rounding of the size another BLAS kernel gives (1e-13 relative)."""
    rng = np.random.default_rng(seed)
    return [x * (1 + size * rng.uniform(-1, 1)) for x in xs]


@settings(max_examples=200, deadline=None)
@given(values, st.integers(0, 2 ** 31))
def test_the_lowest_with_ties_does_not_move_under_rounding(xs, seed):
    # duplicate some values: two starts reaching one optimum
    xs = xs + xs[: len(xs) // 2]
    items = list(range(len(xs)))
    chosen = first_of_lowest(items, xs.__getitem__)
    moved = _jitter(xs, seed)
    # a value set apart from the lowest by about the tie tolerance itself may flip; exclude that band
    low = min(xs)
    if any(0.5 * TIE_RTOL < abs(x - low) / low < 2 * TIE_RTOL for x in xs):
        return
    assert first_of_lowest(items, moved.__getitem__) == chosen
    assert xs[chosen] <= low * (1 + TIE_RTOL)
    assert chosen == min(i for i in items if is_tie(xs[i], low))


@settings(max_examples=200, deadline=None)
@given(values, st.integers(0, 2 ** 31))
def test_sorting_with_ties_does_not_move_under_rounding(xs, seed):
    xs = xs + xs[::2]
    names = [f"m{i:02d}" for i in range(len(xs))]
    order = sort_with_ties(list(range(len(xs))), xs.__getitem__, names.__getitem__)
    assert sorted(order) == list(range(len(xs)))
    ys = sorted(xs)
    if any(0.5 * TIE_RTOL < abs(b - a) / a < 2 * TIE_RTOL for a, b in zip(ys, ys[1:])):
        return
    assert sort_with_ties(list(range(len(xs))), _jitter(xs, seed).__getitem__, names.__getitem__) == order
    # still sorted by value up to the tolerance
    assert all(xs[b] >= xs[a] * (1 - TIE_RTOL) for a, b in zip(order, order[1:]))


def test_nan_never_wins_and_real_differences_are_kept():
    assert first_of_lowest(["a", "b", "c"], {"a": math.nan, "b": 2.0, "c": 1.0}.__getitem__) == "c"
    assert first_of_lowest(["a", "b"], {"a": 1.0 + 1e-6, "b": 1.0}.__getitem__) == "b"
    assert first_of_lowest(["a", "b"], {"a": 1.0 + 1e-12, "b": 1.0}.__getitem__) == "a"
    assert first_of_lowest(["b", "a"], lambda _: math.nan) == "b"
    with pytest.raises(ValueError):
        first_of_lowest([], lambda _: 0.0)
