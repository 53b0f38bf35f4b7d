"""Choices among values that rounding can reorder: the lowest value, ties resolved by a fixed order.

Two fits of the same optimum (two starts, a structure and one it contains at its nesting point, a model and a
flexible correction that changes nothing) have costs equal up to rounding; which of them is lower then depends
on the processor, the BLAS kernel and the thread count. A choice that follows such a difference gives another
answer on another machine. Values within :data:`TIE_RTOL` of the lowest are therefore ties, and the first of
them in a stated order wins (start order, a structure's name, a declared preference). Values further apart
than that are real differences: a fit's cost is converged to 1e-10 relative, and a kernel moves it by 1e-13.
"""
from __future__ import annotations

import math
from typing import Callable, Iterable, Sequence, TypeVar

T = TypeVar("T")

TIE_RTOL = 1e-9


def is_tie(a: float, b: float, rtol: float = TIE_RTOL) -> bool:
    """Whether ``a`` and ``b`` are equal up to rounding (within ``rtol`` of the larger magnitude)."""
    return a == b or abs(a - b) <= rtol * max(abs(a), abs(b))


def first_of_lowest(items: Iterable[T], value: Callable[[T], float], rtol: float = TIE_RTOL) -> T:
    """The first item (in the given order) whose value is within ``rtol`` of the lowest value; NaN values never
    win unless every value is NaN (then the first item). Raises ValueError when there is no item."""
    items = list(items)
    if not items:
        raise ValueError("no item to choose from")
    values = [float(value(x)) for x in items]
    finite = [v for v in values if not math.isnan(v)]
    if not finite:
        return items[0]
    low = min(finite)
    for x, v in zip(items, values):
        if not math.isnan(v) and (v == low or is_tie(v, low, rtol)):
            return x
    raise AssertionError("unreachable")


def _runs(ranked: list[T], same: Callable[[T, T], bool]):
    """Consecutive runs of ``ranked`` whose members are ``same`` as the run's first."""
    i = 0
    while i < len(ranked):
        j = i + 1
        while j < len(ranked) and same(ranked[j], ranked[i]):
            j += 1
        yield ranked[i:j]
        i = j


def sort_with_ties(items: Sequence[T], value: Callable[[T], float], order: Callable[[T], object],
                   rtol: float = TIE_RTOL) -> list[T]:
    """``items`` by ``value``, values within ``rtol`` of the group's lowest ordered by ``order`` instead:
    sorted by value, then each run of ties (chained from its first member) re-sorted by ``order``."""
    ranked = sorted(items, key=lambda x: (math.isnan(float(value(x))), float(value(x))))
    same = lambda a, b: is_tie(float(value(a)), float(value(b)), rtol)  # noqa: E731
    return [x for run in _runs(ranked, same) for x in sorted(run, key=order)]


def sort_by(items: Iterable[T], value: Callable[[T], float], order: Callable[[T], object],
            prefix: Callable[[T], tuple] = lambda _: ()) -> list[T]:
    """``items`` sorted by ``prefix`` (exact keys: a status, a parameter count), then within each prefix by
    ``value`` with ties resolved by ``order`` (:func:`sort_with_ties`)."""
    ranked = sorted(items, key=prefix)
    return [x for run in _runs(ranked, lambda a, b: prefix(a) == prefix(b))
            for x in sort_with_ties(run, value, order)]
