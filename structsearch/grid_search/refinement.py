"""Refinement (thesis chapter 10): drop what the data cannot support while the fit barely changes.

A well-fitting candidate that is not admissible for reasons a refinement can remove (insignificant or strongly
correlated terms, a separation state the data do not place) is refined step by step, one move at a time. Each
step tries, in this order, until one is taken:

1. every linear term whose t-test accepts zero: first those without a correlated partner, then those with one
   (issue 30: such a term was skipped for the pair, whose dropping then cost 4857 % and ended the refinement
   before the insignificant term was ever tried), each group least significant first; the constant last, since
   dropping it changes what every other term means (they must carry the coefficient's mean). The constant is a
   term like any other: a symmetric airfoil has no lift at zero alpha, and a constant the data put at zero
   only widens the other terms' intervals (before, it was exempt and no lift candidate of such data could ever
   become admissible);
2. the less significant member of each pair correlated above |rho| = 0.8 (the thesis' threshold), most
   correlated first. Correlations are read as admissibility reads them: with the data columns centred where
   centring keeps the model (``CandidateResult.centred_correlation``), else as estimated. A pair the ranking
   forgave (C_L with x_cg C_L, one column times another) is not chased, nor a pair with the constant (its
   correlation moves with the other column's datum);
3. every separation state of the candidate's own (not a drag or pitch candidate's, which are its lift model's)
   the data do not support: a state whose time constant the data put at zero (at its lower bound 0, or a t-test
   that accepts 0) is replaced by the simpler state it nests there (U with tau1 = 0 is Q, with tau1 = tau2 = 0
   S; Q with tau2 = 0 is S); a state the data do not place (a parameter at a bound or not identifiable, alpha*
   outside the alpha range flown) is dropped with every regressor that reads it (a second separation state two
   stalls cannot identify).

A move is taken when the held-out MSE (cross-validation, else validation) rises by less than 1 % and the refined
fit converged. A drop that removes a separation state's last regressor removes the state too (its parameters
and box): the state can no longer be identified, and keeping it would end the refinement (a drag or pitch
candidate keeps its lift model's states, whose parameters it does not estimate). Every structure a step takes
is a candidate of the ranking (the search adds them), so the best admissible one it passes through is kept. A
refined structure that equals a candidate already fitted (the thesis' declared CD-IXr, for one) reuses that
result and is reported as reached.
"""
from __future__ import annotations

import dataclasses

from dataclasses import dataclass
from typing import Callable, Generator

import numpy as np

from ..engine.regressors import symbol_names
from ..engine.separation import SeparationState, is_vortex
from ..engine.static_forms import LOCATION_PARAMETERS
from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
# a U state's lag and delay correlated beyond admissibility's limit: the data cannot tell them apart
from .admissibility import MAX_CORRELATION

# Correlated pairs above this are candidates for removal during refinement (thesis: 0.8).
REFINE_CORRELATION = 0.8
# A refinement step is kept when the held-out MSE rises by less than this fraction.
REFINE_TOLERANCE = 0.01
MAX_STEPS = 9


@dataclass(frozen=True)
class Refinement:
    """The steps taken from ``start`` and why the refinement ended."""

    start: str
    steps: tuple[tuple[Candidate, CandidateResult], ...]
    stopped: str
    reached: tuple[str, ...] = ()      # existing candidates a step turned out to be
    refused: tuple[str, ...] = ()      # why each move of the last step was refused (``stopped`` joins them)
    keys: tuple[tuple, ...] = ()       # each step's :func:`refinement_key`


@dataclass(frozen=True)
class Move:
    """One move a step tries: ``what`` in words ("dropping CL0"), the regressors it drops, the states whose kind
    it simplifies (name -> kind), the search boxes it widens, and ``why``."""

    what: str
    drop: tuple[str, ...] = ()
    kinds: tuple[tuple[str, str], ...] = ()
    why: str = ""
    boxes: tuple[tuple[str, tuple[float, float]], ...] = ()   # search boxes it widens (name -> (lo, hi))
    replace: tuple[tuple[str, str], ...] = ()                  # regressors it rewrites (name -> expression)


def _refined(c: Candidate, drop: list[str], suffix: str, kinds: dict[str, str] | None = None,
             boxes: dict[str, tuple[float, float]] | None = None, replace: dict[str, str] | None = None) -> Candidate:
    """``c`` without the regressors in ``drop`` (all drops so far, relative to ``c``), with the states of ``kinds``
    (name -> kind) simplified, the search boxes of ``boxes`` widened, and without the separation states no
    remaining regressor uses (with the boxes of the parameters that went)."""
    kinds, boxes, replace = kinds or {}, boxes or {}, replace or {}
    regs = tuple((n, replace.get(n, t)) for n, t in c.regressors if n not in drop)
    # a drag or pitch candidate reads its lift model's states (their parameters fixed): one it no longer uses
    # costs nothing, and its states must stay the lift model's
    orphans = set() if c.lift else set(_orphans(c, drop, replace))
    states = tuple((n, kinds.get(n, k)) for n, k in c.states if SeparationState(n, k).symbol not in orphans)
    kept = {p for n, k in states for p in SeparationState(n, k, c.form_of(n)).parameters}
    gone = {p for s in c.separation_states for p in s.parameters} - kept
    merged = {**dict(c.bounds), **{k: v for k, v in boxes.items() if k in kept}}
    bounds = tuple(sorted((name, box) for name, box in merged.items() if name not in gone)) if boxes else \
        tuple((name, box) for name, box in c.bounds if name not in gone)
    changes = [f"dropped {', '.join(drop)}"] if drop else []
    if replace:
        changes.append("attached flow (X = 1) in " + ", ".join(f"{n} = {t}" for n, t in sorted(replace.items())))
    if orphans and drop:
        changes[0] += f" and the state(s) {', '.join(sorted(orphans))} they left without a regressor"
    elif orphans:
        changes[-1] += f", the state(s) {', '.join(sorted(orphans))} removed"
    simpler = [f"{SeparationState(n, k).symbol} as {kinds[n]}" for n, k in c.states if n in kinds and
               SeparationState(n, k).symbol not in orphans]
    if simpler:
        changes.append(f"the state(s) {', '.join(simpler)} (a time constant at zero)")
    widened = [f"{k} in [{np.degrees(lo):.1f}, {np.degrees(hi):.1f}] deg" for k, (lo, hi) in sorted(boxes.items())
               if k in kept]
    if widened:
        changes.append(f"the box of {', '.join(widened)} (the alpha range flown)")
    note = f"refined from {c.name}: " + "; ".join(changes)
    return dataclasses.replace(c, name=f"{c.name}{suffix}", regressors=regs, states=states, note=note, bounds=bounds)


def structure_key(c: Candidate) -> tuple:
    """What makes two candidates the same model: regressor expressions, states (with their static forms), lift
    model, known terms."""
    return (c.coefficient, tuple(sorted(t.replace(" ", "") for _, t in c.regressors)), tuple(sorted(c.states)),
            c.lift) + ((tuple(sorted(c.forms)),) if c.forms else ()) + \
        ((("known",) + tuple(sorted(e.replace(" ", "") for _, e in c.known)),) if c.known else ())


def refinement_key(c: Candidate, widened: dict[str, tuple[float, float]] | None = None) -> tuple:
    """What makes two refined candidates the same fit: the structure, and the boxes a refinement widened (a
    structure fitted in a wider box is another fit of it)."""
    kept = {k: v for k, v in (widened or {}).items() if k in c.state_parameters}
    return structure_key(c) + ((tuple(sorted(kept.items())),) if kept else ())


def _orphans(c: Candidate, drop: list[str], replace: dict[str, str] | None = None) -> list[str]:
    """Separation states of ``c`` that no regressor would use once ``drop`` is dropped (and ``replace`` made)."""
    replace = replace or {}
    used = {name for n, t in c.regressors if n not in drop for name in symbol_names(replace.get(n, t))}
    symbols = [SeparationState(n, k).symbol for n, k in c.states]
    return [s for s in symbols if s not in used]


def _p(summary: CandidateResult, name: str) -> float:
    """A p-value for ordering; NaN (no standard deviation) counts as the least significant."""
    p = summary.estimates.p_values.get(name, float("nan"))
    return p if np.isfinite(p) else 2.0


def _insignificant_why(summary: CandidateResult, name: str) -> str:
    p = summary.estimates.p_values.get(name, float("nan"))
    return f"t-test accepts 0, p = {p:.2g}" if np.isfinite(p) else "no standard deviation (p-value not estimable)"


def _correlated_pairs(summary: CandidateResult, linear: list[str]) -> list[tuple[str, str, float]]:
    """Pairs of ``linear`` correlated above REFINE_CORRELATION, most correlated first, read as admissibility reads
    them (data columns centred where that keeps the model, else as estimated)."""
    centred = summary.centred_correlation
    corr = np.asarray(centred, float) if len(centred) else summary.estimates.correlation
    names = list(summary.estimates.names)
    pairs = [(a, b, float(corr[names.index(a), names.index(b)])) for i, a in enumerate(linear)
             for b in linear[i + 1:]]
    return sorted((p for p in pairs if np.isfinite(p[2]) and abs(p[2]) > REFINE_CORRELATION), key=lambda p: -abs(p[2]))


def _options(current: Candidate, summary: CandidateResult) -> list[tuple[str, str]]:
    """The terms a step tries to drop, in order (module docstring, 1 and 2): (term, why)."""
    linear = [r[0] for r in current.regressors]
    constant = next((n for n, t in current.regressors if t.strip() == "1"), None)
    pairs = [p for p in _correlated_pairs(summary, linear) if constant not in p[:2]]
    paired = {n for a, b, _ in pairs for n in (a, b)}
    weak = [n for n in summary.insignificant if n in linear]
    # the insignificant terms without a correlated partner first (their t-tests are not inflated by one: the
    # thesis' q* before C_L in CD-IX), then those with one, each least significant first; the constant last
    ordered = sorted(weak, key=lambda n: (n == constant, n in paired, -_p(summary, n)))
    out = [(n, _insignificant_why(summary, n)) for n in ordered]
    for a, b, rho in pairs:
        # the less significant member first; the other when that one was tried already (as insignificant)
        tried = {o for o, _ in out}
        for n in sorted((a, b), key=lambda x: -_p(summary, x)):
            if n not in tried:
                out.append((n, f"|rho({a}, {b})| = {abs(rho):.2f} > {REFINE_CORRELATION}"))
                break
    return out


# a time constant at zero nests a simpler state: (kind, its time constants at zero, the state it equals there),
# the simplest first (U without the alpha_dot delay is L, a lag of X0(alpha))
_NESTED = (("U", frozenset({"tau1", "tau2"}), "S"), ("U", frozenset({"tau1"}), "Q"), ("U", frozenset({"tau2"}), "L"),
           ("Q", frozenset({"tau2"}), "S"), ("L", frozenset({"tau1"}), "S"))


def _simpler_kinds(state: SeparationState, summary: CandidateResult) -> list[tuple[str, str]]:
    """The simpler states ``state`` nests where the data put its time constants at zero (at the lower bound 0 of
    their box, or a t-test that accepts 0): (kind, why), the simplest first."""
    e = summary.estimates
    lower = dict(zip(e.nonlinear_names, e.lower))
    why = {}
    for base in ("tau1", "tau2"):
        p = state.parameter_name(base)
        if p in state.parameters and lower.get(p) == 0.0:
            if e.at_bound.get(p) == "lower":
                why[base] = f"{p} at its lower bound 0"
            elif p in summary.insignificant:
                why[base] = f"{p}: t-test accepts 0"
    tangled = _tangled_time_constants(state, summary)
    if tangled:   # the data cannot tell the lag from the delay: either alone may carry what both do
        for base in ("tau1", "tau2"):
            why.setdefault(base, tangled)
    return [(simpler, "; ".join(why[b] for b in sorted(zero))) for kind, zero, simpler in _NESTED
            if kind == state.kind and zero <= set(why)]


def _tangled_time_constants(state: SeparationState, summary: CandidateResult) -> str:
    """Why the data cannot tell a U state's lag tau1 from its delay tau2 (their correlation beyond the ranking's
    limit), or "" when they can."""
    if "tau1" not in state.base_parameters or "tau2" not in state.base_parameters:
        return ""
    e = summary.estimates
    names = list(e.names)
    a, b = state.parameter_name("tau1"), state.parameter_name("tau2")
    corr = np.asarray(e.correlation, float)
    if a not in names or b not in names or corr.size == 0:
        return ""
    rho = corr[names.index(a), names.index(b)]
    return f"|rho({a}, {b})| = {abs(rho):.2f}" if np.isfinite(rho) and abs(rho) > MAX_CORRELATION else ""


def _box_moves(current: Candidate, summary: CandidateResult, alpha_range) -> list[Move]:
    """A break angle at a side of its search box that lies inside the alpha range flown: the box, not the data,
    holds it there (the Citation's default box on an airfoil that stalls elsewhere); widen the box to the range
    flown."""
    if alpha_range is None:
        return []
    e = summary.estimates
    boxes = dict(zip(e.nonlinear_names, zip(e.lower, e.upper)))
    out = []
    for state in current.separation_states:
        for base in LOCATION_PARAMETERS:
            p = state.parameter_name(base)
            side = e.at_bound.get(p)
            if base not in state.base_parameters or side is None or p not in boxes:
                continue
            lo, hi = boxes[p]
            edge = lo if side == "lower" else hi
            if not alpha_range[0] < edge < alpha_range[1]:
                continue
            wider = (float(min(lo, alpha_range[0])), float(max(hi, alpha_range[1])))
            out.append(Move(f"widening the box of {p}", boxes=((p, wider),),
                            why=f"{p} at its {side} bound {np.degrees(edge):.1f} deg, inside the alpha range flown"))
    return out


def _wrong_sign(current: Candidate, state: SeparationState, summary: CandidateResult) -> list[str]:
    """The Kirchhoff lift terms of ``state`` whose estimate is not positive (a lift model's state mimicking
    something else: a vortex's overshoot and collapse, say)."""
    if current.coefficient != "CL":
        return []
    params = summary.estimates.params
    if is_vortex(state.kind):   # its lift is the vortex's, positive while the vortex lies over the section
        return [f"vortex lift term {n} = {params[n]:.3g} not positive" for n, t in current.regressors
                if state.symbol in symbol_names(t) and n in params and not params[n] > 0]
    return [f"Kirchhoff term {n} = {params[n]:.3g} not positive" for n, t in current.regressors
            if f"K_L({state.symbol})" in t.replace(" ", "") and n in params and not params[n] > 0]


def _state_moves(current: Candidate, summary: CandidateResult,
                 alpha_range: tuple[float, float] | None) -> list[Move]:
    """The moves on separation states a step tries (module docstring, 3), in the candidate's order of states."""
    if current.lift or not current.states:   # a drag or pitch candidate's states are its lift model's
        return []
    e = summary.estimates
    unplaced = {} if e.withheld else dict(e.not_identifiable)   # withheld: the optimizer, not the data
    out = []
    for state in current.separation_states:
        name = state.name
        out += [Move(f"making {state.symbol} {simpler}", kinds=((name, simpler),), why=why)
                for simpler, why in _simpler_kinds(state, summary)]
        why = [f"{p} at its {e.at_bound[p]} bound" for p in state.parameters if p in e.at_bound]
        why += [f"{p} not identifiable" for p in state.parameters if p in unplaced]
        a_star = e.params.get(state.parameter_name("a_star"))
        if alpha_range is not None and a_star is not None and not alpha_range[0] <= a_star <= alpha_range[1]:
            why.append(f"{state.parameter_name('a_star')} outside the alpha range flown")
        why += _wrong_sign(current, state, summary)
        users = tuple(n for n, t in current.regressors if state.symbol in symbol_names(t))
        if why and users:
            out += _attach(current, state, users, why, summary)
            out.append(Move(f"dropping the state {state.symbol}", users, why="; ".join(why)))
    return out


def _attach(current: Candidate, state: SeparationState, users: tuple[str, ...], why: list[str],
            summary: CandidateResult) -> list[Move]:
    """A lift model's state the data do not place, as attached flow (X = 1): its Kirchhoff lift K_L(X) becomes
    the attached lift slope alpha (K_L(1) = alpha), its other terms go; tried before dropping the state with its
    lift (the data may need the lift and not the separation: an airfoil that never stalls in the range flown).
    Not for a Kirchhoff term of the wrong sign (a negative lift slope is no attached flow)."""
    kirchhoff = [n for n, t in current.regressors if t.replace(" ", "") == f"K_L({state.symbol})"]
    if current.coefficient != "CL" or not kirchhoff or _wrong_sign(current, state, summary):
        return []
    rest = tuple(n for n in users if n not in kirchhoff)
    return [Move(f"attaching {state.symbol} (X = 1)", rest, replace=tuple((n, "alpha") for n in kirchhoff),
                 why="; ".join(why))]


def _moves(current: Candidate, summary: CandidateResult, alpha_range) -> list[Move]:
    """Every move a step tries, in order: boxes the default made too narrow, terms, then states."""
    terms = [Move(f"dropping {n}", (n,), why=why) for n, why in _options(current, summary)]
    return _box_moves(current, summary, alpha_range) + terms + _state_moves(current, summary, alpha_range)


def _try(move: Move, c: Candidate, so_far: tuple[list[str], dict, dict, dict], suffix: str, current_mse: float,
         known: dict) -> Generator[Candidate, CandidateResult, tuple[tuple | None, str | None]]:
    """``move`` made on top of the refinement so far (drops, kinds, boxes, rewritten regressors): (candidate,
    result, the changes so far with it, was_known) when it is taken, else None and why not. Yields the candidate
    when it must be fitted (a structure in ``known`` is not) and is sent its result."""
    dropped, kinds, boxes, replaced = so_far
    drop = dropped + [n for n in move.drop if n not in dropped]
    new_kinds = {**kinds, **dict(move.kinds)}
    new_boxes = {**boxes, **dict(move.boxes)}
    new_replaced = {**replaced, **dict(move.replace)}
    what = f"{move.what} ({move.why})"
    if len(drop) >= len(c.regressors):
        return None, f"{what} would leave no term"
    candidate = _refined(c, drop, suffix, new_kinds, new_boxes, new_replaced)
    key = refinement_key(candidate, new_boxes)
    same = known.get(key)
    if same is None:
        result = yield candidate
        # a walk whose fits were made beside this one's may have taken this structure meanwhile: reached
        same = known.get(key)
    if same is not None:
        candidate, result = same
    if result.failed:
        return None, f"the refined {candidate.name} ({move.what}) failed: {result.error}"
    if result.optimizer.converged is False:
        return None, f"the refined {candidate.name} ({move.what}) did not converge: {result.optimizer.message}"
    rise = result.comparison.mse / current_mse - 1
    if not np.isfinite(rise):
        return None, f"the held-out MSE after {move.what} cannot be compared (not finite)"
    if rise > REFINE_TOLERANCE:
        return None, f"{what} raises the held-out MSE by {rise:.1%}"
    return (candidate, result, (drop, new_kinds, new_boxes, new_replaced), same is not None), None


def refine(c: Candidate, summary: CandidateResult, fit: Callable[[Candidate], CandidateResult],
           known: dict[tuple, tuple[Candidate, CandidateResult]] | None = None,
           alpha_range: tuple[float, float] | None = None) -> Refinement:
    """Refine ``c`` (fitted as ``summary``); ``fit`` fits a new structure, ``known`` maps the structures
    fitted already to their candidate and result (reused instead of refitting); ``alpha_range``: the alpha range
    flown in training (an alpha* outside it is a state the data do not place; None: not judged)."""
    walk = refinement_walk(c, summary, {} if known is None else known, alpha_range)
    try:
        request = next(walk)
        while True:
            request = walk.send(fit(request))
    except StopIteration as finished:
        return finished.value


def refinement_walk(c: Candidate, summary: CandidateResult, known: dict[tuple, tuple[Candidate, CandidateResult]],
                    alpha_range: tuple[float, float] | None = None
                    ) -> Generator[Candidate, CandidateResult, Refinement]:
    """The refinement of ``c`` as a walk that yields each structure it needs fitted and is sent its result (so
    that several walks can have their fits made together: :mod:`.refinements_together`); returns the
    :class:`Refinement`. Each step it takes that is not in ``known`` is added to it, for the walks after it."""
    steps, reached, keys = [], [], []
    current, current_summary, so_far = c, summary, ([], {}, {}, {})
    stopped, refused_all = "nothing left to drop", ()
    if summary.estimates.withheld:   # no t-test, interval or bound to judge a move by
        return Refinement(c.name, (), f"{summary.estimates.withheld}: no statistics to refine by")
    for step in range(1, MAX_STEPS + 1):
        moves = _moves(current, current_summary, alpha_range)
        if not moves:
            stopped = "nothing left to drop"
            break
        refused, taken = [], None
        suffix = "r" + ("" if step == 1 else str(step)) + "-auto"
        for move in moves:
            taken, why = yield from _try(move, c, so_far, suffix, current_summary.comparison.mse, known)
            if taken is not None:
                break
            refused.append(why)
        if taken is None:
            stopped, refused_all = "; ".join(refused) + "; not taken", tuple(refused)
            break
        current, current_summary, so_far, was_known = taken
        steps.append((current, current_summary))
        keys.append(refinement_key(current, so_far[2]))
        if was_known:
            reached.append(current.name)
        else:
            known.setdefault(keys[-1], (current, current_summary))
    else:
        stopped = f"stopped after {MAX_STEPS} steps"
    return Refinement(c.name, tuple(steps), stopped, tuple(reached), refused_all, tuple(keys))
