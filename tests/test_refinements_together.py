"""Refinements walked together: each round's fits in one call, the same steps as one refinement at a time, a
structure two refinements ask for in one round fitted once (and the later one reaches it)."""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from structsearch.fitting.candidates import Candidate
from structsearch.grid_search.refinement import refine
from structsearch.grid_search.refinements_together import refine_together

# the terms a fit finds insignificant, least significant first (p-values 0.5, 0.4): each refinement drops them
# one a step, then has nothing left to drop
WEAK = {"a": 0.5, "b": 0.4}


@dataclass(frozen=True)
class _Fit:
    """What refinement reads of a fitted candidate (a dataclass: a fit served twice is renamed)."""

    name: str
    grid: str
    estimates: SimpleNamespace
    optimizer: SimpleNamespace
    comparison: SimpleNamespace
    insignificant: tuple = ()
    centred_correlation: tuple = ()
    failed: bool = False
    error: str | None = None


def _fit_of(c: Candidate, mse: float = 1.0) -> _Fit:
    names = [n for n, _ in c.regressors]
    p = {n: WEAK.get(n, 1e-9) for n in names}
    estimates = SimpleNamespace(names=tuple(names), p_values=p, correlation=np.eye(len(names)),
                                params=dict.fromkeys(names, 0.1), nonlinear_names=(), lower=(), upper=(),
                                at_bound={}, not_identifiable={}, withheld=None)
    return _Fit(c.name, c.grid, estimates, SimpleNamespace(converged=True, message=""), SimpleNamespace(mse=mse),
                tuple(n for n in names if p[n] > 0.05))


def _candidate(name: str, extra: str) -> Candidate:
    return Candidate(name, "lift", "CL", (("c0", "1"), ("a", "alpha"), ("b", "de"), (extra, extra)))


def _fit_many(calls: list[list[str]]):
    def fit_many(cands):
        calls.append([c.name for c in cands])
        return [_fit_of(c, mse=1.001) for c in cands]
    return fit_many


def test_refinements_walked_together_take_the_steps_one_at_a_time_takes_in_fewer_calls():
    starts = [(_candidate(n, x), _fit_of(_candidate(n, x))) for n, x in (("P", "q"), ("Q", "alpha_dot"), ("R", "V"))]
    alone = [refine(c, s, lambda cand: _fit_of(cand, mse=1.001)) for c, s in starts]
    calls: list[list[str]] = []
    together = refine_together(starts, _fit_many(calls), {})
    assert [[c.name for c, _ in r.steps] for r in together] == [[c.name for c, _ in r.steps] for r in alone]
    assert [r.stopped for r in together] == [r.stopped for r in alone] == ["nothing left to drop"] * 3
    assert [[dict(c.regressors).keys() for c, _ in r.steps][-1] for r in together] == [
        {"c0", x} for x in ("q", "alpha_dot", "V")]
    # two steps each: two rounds of three fits, where one refinement at a time makes six calls of one
    assert calls == [["Pr-auto", "Qr-auto", "Rr-auto"], ["Pr2-auto", "Qr2-auto", "Rr2-auto"]]


def test_a_structure_two_refinements_ask_for_in_one_round_is_fitted_once_and_reached_by_the_later():
    same = _candidate("A", "q")
    twin = Candidate("B", "lift", "CL", same.regressors)
    calls: list[list[str]] = []
    known: dict = {}
    first, second = refine_together([(same, _fit_of(same)), (twin, _fit_of(twin))], _fit_many(calls), known)
    assert calls == [["Ar-auto"], ["Ar2-auto"]]
    assert [c.name for c, _ in first.steps] == ["Ar-auto", "Ar2-auto"] and first.reached == ()
    assert [c.name for c, _ in second.steps] == ["Ar-auto", "Ar2-auto"]
    assert second.reached == ("Ar-auto", "Ar2-auto")
    # what was taken is known to the walks that come after
    assert {c.name for c, _ in known.values()} == {"Ar-auto", "Ar2-auto"}


def test_a_refused_structure_asked_for_twice_is_fitted_once_for_both():
    """Both refinements refuse each move (it costs 5 %): the one fit of each round serves both, and nothing is
    reached."""
    same = _candidate("A", "q")
    twin = Candidate("B", "lift", "CL", same.regressors)
    calls: list[list[str]] = []

    def fit_many(cands):
        calls.append([c.name for c in cands])
        return [_fit_of(c, mse=1.05) for c in cands]
    first, second = refine_together([(same, _fit_of(same)), (twin, _fit_of(twin))], fit_many, {})
    assert first.steps == second.steps == () and first.reached == second.reached == ()
    assert first.stopped == second.stopped and "raises the held-out MSE by 5.0%; dropping b" in second.stopped
    # each round fits the structure both ask for once: dropping a, then dropping b
    assert calls == [["Ar-auto"], ["Ar-auto"]]


def test_requests_that_differ_only_in_what_is_not_a_term_are_two_fits():
    """One fit serves two requests only when they are one model: the same terms with another moment reference,
    box or flight effect are another question (fitted apart), while the name and note do not count."""
    import dataclasses

    from structsearch.fitting.runner import model_key
    c = Candidate("P", "pitch", "Cm", (("c0", "1"), ("a", "alpha")))
    assert model_key(c) == model_key(dataclasses.replace(c, name="Q", note="another name"))
    for other in (dataclasses.replace(c, moment_reference="fixed"), dataclasses.replace(c, flight_effects=("c0",)),
                  dataclasses.replace(c, bounds=(("a_star", (0.1, 0.3)),))):
        assert model_key(other) != model_key(c), other
