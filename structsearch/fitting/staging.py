"""Staged, warm-started fits: a candidate starts where a simpler candidate ended.

Candidate B *feeds* A when both model the same coefficient without a lift model and B's separation
parameters are a subset of A's (a steady state's a1, a_star are in the quasi-steady one's, which adds
tau2, and in the unsteady one's, which adds tau1), strictly, or with the same parameters and a strict
subset of A's regressors (CL-III feeds CL-IV). A grid is fitted in *waves*: a candidate's wave is one
more than the latest wave of the candidates feeding it, so they are fitted before it. It starts from
the estimates of the fitted candidate (of this grid or an earlier one) that shares most of its
separation parameters, the lowest training MSE among equals; the parameters that candidate lacks
start at their declared or default value; it is fitted from that warm start and from its declared
start. Which donor a candidate gets depends on the grids searched together (``--grid lift`` alone
or after the separation grid in ``--grid all``); the cache key does not hold the warm start (it
chooses where the solver begins, not the question), so a cached fit serves either. A candidate no fitted candidate feeds keeps the usual starts (declared and
quasi-random) and, when it has unsteady states, adds the estimates of its quasi-steady version
(``structsearch fit`` does the same), so it never starts from less than the default multistart.

Drag and pitch candidates take their states from the lift model (nothing to stage): one wave.
"""
from __future__ import annotations

import dataclasses

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..engine.separation import SeparationState, nests
from ..engine.ties import first_of_lowest
from .candidate_result import CandidateResult
from .candidates import Candidate

# A candidate with a donor is fitted from the donor's estimates and from its declared start (then from
# quasi-random points if WARM_STARTS is raised above 1); a single fit's quasi-steady stage from its
# declared start and STAGE_STARTS - 1 quasi-random points. `structsearch bench --staged` measures the
# single fit against the best admissible solution of 64 random starts on 50 small campaigns, beside fits
# with fewer runs (experiments/bench_staged.py, results/bench.md).
WARM_STARTS = 1
STAGE_STARTS = 2
# Kinds in order of nesting: each adds one parameter to the previous one.
KIND_ORDER = {"S": 0, "Q": 1, "L": 1, "U": 2}   # L (a lag without the delay) nests S as Q does


@dataclass(frozen=True)
class DonorEstimate:
    """What a warm start reads of a fitted candidate: its estimates and training MSE (a fit whose statistics are
    still being computed has both already: the optimum of its best start)."""

    params: Mapping[str, float]
    mse_train: float
    failed: bool = False

    @classmethod
    def of(cls, result: CandidateResult) -> "DonorEstimate":
        if result.failed:
            return cls({}, float("nan"), True)
        return cls(dict(result.estimates.params), result.mse_train)


def _stageable(c: Candidate) -> bool:
    return bool(c.state_parameters) and not c.lift


def _regressors(c: Candidate) -> set[str]:
    return {text.replace(" ", "") for _, text in c.regressors}


def feeds(inner: Candidate, outer: Candidate) -> bool:
    """Whether ``inner`` is fitted before ``outer`` in a grid (see the module's docstring)."""
    if not may_donate(inner, outer):
        return False
    return set(inner.state_parameters) != set(outer.state_parameters) or _regressors(inner) < _regressors(outer)


def waves(candidates: Sequence[Candidate]) -> list[list[int]]:
    """Indices of ``candidates`` in waves: everything feeding a candidate lies in an earlier wave.
    Candidates with a lift model or without separation parameters form the first wave."""
    depth: dict[int, int] = {}

    def depth_of(i: int) -> int:
        if i not in depth:
            inner = [j for j in range(len(candidates)) if feeds(candidates[j], candidates[i])]
            depth[i] = 1 + max((depth_of(j) for j in inner), default=-1)
        return depth[i]

    levels = [depth_of(i) for i in range(len(candidates))]
    return [[i for i, d in enumerate(levels) if d == level] for level in sorted(set(levels))]


def may_donate(d: Candidate, c: Candidate) -> bool:
    """Whether ``d``, once fitted, may give ``c`` its warm start (see :func:`warm_start`)."""
    return d.name != c.name and d.coefficient == c.coefficient and _stageable(d) and _stageable(c) \
        and set(d.state_parameters) <= set(c.state_parameters)


def warm_start(c: Candidate, fitted: Sequence[tuple[Candidate, DonorEstimate]]) -> dict[str, float] | None:
    """Estimates of ``c``'s separation parameters from the fitted candidate that shares most of them (of
    the same coefficient, without a lift model; the lowest training MSE among equals), for those it has;
    None when no fitted candidate shares all of its own separation parameters with ``c``."""
    if not _stageable(c):
        return None
    donors = [(d, r) for d, r in fitted if may_donate(d, c) and not r.failed and np.isfinite(r.mse_train)]
    if not donors:
        return None
    most = max(len(d.state_parameters) for d, _ in donors)
    # equal fits (a structure and one it contains) tie up to rounding: the name decides, not the processor
    donor, result = first_of_lowest(sorted(((d, r) for d, r in donors if len(d.state_parameters) == most),
                                           key=lambda dr: dr[0].name), lambda dr: dr[1].mse_train)
    return {k: result.params[k] for k in c.state_parameters if k in result.params}


# The value of a separation parameter at which a state of a higher kind is the lower kind's (tau1 -> 0: U is Q;
# tau2 -> 0: Q is S); clipped into the box.
NESTING_VALUES = {"tau1": 0.0, "tau2": 0.0}


def contains(outer: Candidate, inner: Candidate) -> bool:
    """Whether ``inner`` is ``outer`` with some terms at zero and some states' kinds lowered (each of its states is
    one of ``outer``'s, of the same or a lower kind): its optimum, with ``outer``'s extra time constants at their
    nesting values, is a point of ``outer``'s parameter space as good as ``inner``'s fit."""
    if inner.name == outer.name or inner.coefficient != outer.coefficient or inner.lift != outer.lift:
        return False
    if not _regressors(inner) <= _regressors(outer):
        return False
    kinds = dict(outer.states)
    return all(n in kinds and nests(k, kinds[n]) and inner.form_of(n) == outer.form_of(n)
               for n, k in inner.states)


def nested_start(c: Candidate, inner_params: Mapping[str, float]) -> dict[str, float]:
    """``c``'s separation parameters at a contained structure's optimum: the ones it shares take the inner
    estimates, a time constant it adds its nesting value (:data:`NESTING_VALUES`); the rest are left to the
    declared start."""
    out = {}
    for n, k in c.states:
        state = SeparationState(n, k, c.form_of(n))
        for base in state.base_parameters:
            name = state.parameter_name(base)
            if name in inner_params:
                out[name] = float(inner_params[name])
            elif base in NESTING_VALUES:
                out[name] = NESTING_VALUES[base]
    return out


def best_contained(c: Candidate, fitted: Sequence[tuple[Candidate, DonorEstimate]]) -> dict[str, float] | None:
    """The nested start (:func:`nested_start`) from the fitted structure contained in ``c`` with the lowest training
    MSE: a fit that also starts there never ends above it (issue 30: U/Q ended above the Q/Q it contains)."""
    if not _stageable(c):
        return None
    inner = [(d, r) for d, r in fitted if contains(c, d) and not r.failed and np.isfinite(r.mse_train)]
    if not inner:
        return None
    d, r = first_of_lowest(sorted(inner, key=lambda dr: dr[0].name), lambda dr: dr[1].mse_train)
    return nested_start(c, r.params)


def demoted(c: Candidate, highest: str) -> Candidate:
    """``c`` with every state's kind lowered to at most ``highest`` (S or Q); a vortex state stays one (it lowers
    to no other kind: a steady one would be the static curve, not a vortex)."""
    states = tuple((n, k if k not in KIND_ORDER else min(k, highest, key=KIND_ORDER.get)) for n, k in c.states)
    own = {p for n, k in states for p in SeparationState(n, k, c.form_of(n)).parameters}
    return dataclasses.replace(c, name=f"{c.name} [{highest}]", states=states, note=f"stage of {c.name}",
                               bounds=tuple(b for b in c.bounds if b[0] in own))


def stages(c: Candidate) -> list[Candidate]:
    """The chain a single fit of ``c`` climbs before ``c`` itself: ``c`` with every unsteady state made
    quasi-steady (none when ``c`` has no unsteady state or feeds on a lift model). A steady stage
    before it was measured and dropped: it cost time and reached the best no more often."""
    if c.lift or not any(kind == "U" for _, kind in c.states):
        return []
    return [demoted(c, "Q")]
