"""A structure search over moves: bidirectional stepwise with a beam.

Each step expands the beam (at most ``beam`` structures): every valid move (:mod:`.moves`) of each is fitted
once (the command's fitter: cached, in parallel on joblib or dask, each child warm started from the
structures it extends), and judged against its parent by :func:`.adoption.move_test`:

1. children that *improve* (the test rejects at alpha / moves tried and the validation MSE falls) form
   the next beam, best (lowest held-out MSE) first;
2. else children that *simplify* (fewer parameters, within one standard error of the parent, and no more
   reasons against them): the best one is the next beam (backward stepwise);
3. else the ``beam`` best children that lower the held-out MSE without passing the test are kept as a
   *look-ahead*: their own children are tested against the structure they came from, two moves together,
   so that a move that pays only with a second one is not lost. A look-ahead that leads nowhere ends the
   search.

An improving move may add reasons against admissibility (a correlation, a term the t-test accepts at zero): the
first terms of a structure grown from the intercept alone seldom make it admissible one at a time. Only the hard
reasons (not identifiable, no convergence) reject it. When the best adopted structure is not admissible, it is
*repaired* (a discovery, ``simplify``): the moves that remove or simplify (drop a term, replace one, change or
remove a state) are fitted in full, and of those that remove a reason (or a parameter within one standard error)
the one within one standard error of it, then with the fewest reasons, the fewest parameters, the lowest held-out
MSE, is adopted, until the structure is admissible or ``max_steps`` steps (the search's and the repairs'
together) are taken.

The structure the search ends with is chosen afterwards over every structure it fitted
(:func:`.final_choice.select_final`): for a discovery, the ranking's choice among every admissible structure
fitted in full (the best adopted structure repaired first when it is not admissible); for a diagnosis, among the
adopted ones. The structures with a lower held-out MSE that the choice leaves are recorded with the reason.

The search stops when no move passes, when ``stop`` says a structure is good enough (the diagnosis: at the
floor) or after ``max_steps`` steps (:class:`.search_nodes.Stop`). It does no I/O but the fitter's cache.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence


from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
from ..fitting.fitter import Fitter
from .adoption import DEFAULT_ALPHA, move_test
from .final_choice import (CONFIRMED, by_mse as _by_mse, choose,
                           hard as _hard, lower as _lower, lowest_mse as _lowest_mse, preference as _preference,
                           select_final, set_aside)
from .moves import MOVE_KINDS, NAMES_SIMULATOR_TERM, NESTED_KINDS, REPAIR_KINDS, Move, generate, structure_key
from .search_nodes import Exploration, Node, Status, Step, Stop
from .terms import TermLibrary

__all__ = ["explore", "choose", "donors", "adds_state", "Exploration", "Node", "Status", "Step", "Stop",
           "CONFIRMED", "NESTED_KINDS", "REPAIR_KINDS"]

STATUSES = tuple(Status)
DEFAULT_BEAM = 3
DEFAULT_MAX_STEPS = 20
# screened children that may simplify and are fitted in full (the simplest first)
SIMPLIFY_SHORTLIST = 4

Judge = Callable[[CandidateResult, Candidate], Sequence[str]]


def donors(nodes: Sequence[Node]) -> list[tuple[Candidate, CandidateResult]]:
    """The fitted structures of ``nodes`` as warm-start donors of a fitter."""
    return [(n.candidate, n.result) for n in nodes]


def _verdict(child: Node, anchor: Node, n_moves: int, alpha: float, judged: bool = True,
             against: CandidateResult | None = None) -> Node:
    """The child's status against its anchor; a screened child (``judged`` False: no statistics yet) passes
    every condition on the reasons against it, which its full fit then decides. ``against``: the anchor's fit
    with the child's cross-validation (refitted folds, :func:`refits_folds`), when its own differs."""
    if child.result.failed:
        return dataclasses.replace(child, status=Status.FAILED, anchor=anchor)
    # a move from the anchor itself that only adds parameters is nested: its Wald test decides (fitted in full),
    # unless it adds a separation state: with the state's K term at zero its a1 and a_star are not identified
    # (Davies' problem), the chi-square reference of the Wald test does not hold and it over-rejects (a third
    # lift state on the default campaign: Wald p 1e-14 for a held-out gain of 0.1 %, paired p 0.23); the
    # out-of-sample paired test, valid whatever the parameters, decides such a move
    nested = child.move.new_parameters if (child.parent is anchor and child.move.kind in NESTED_KINDS
                                          and not adds_state(anchor.candidate, child.candidate)) else ()
    test = move_test(against or anchor.result, child.result, alpha, n_moves, nested, statistics=judged)
    if judged and _hard(child) - _hard(anchor):
        # a structure the data cannot identify, or a fit that did not converge, is never adopted
        return dataclasses.replace(child, status=Status.REJECTED, anchor=anchor, test=test)
    fewer_reasons = not judged or len(child.reasons) <= len(anchor.reasons)
    strictly_fewer = not judged or len(child.reasons) < len(anchor.reasons)
    # screened (no statistics yet): a nested move that gains out of sample goes on to its full fit
    passes = test.improves or (not judged and nested and test.pooled_gain > 0)
    if passes and _lower(child.result.validation.mse, anchor.result.validation.mse):
        status = Status.IMPROVES
    elif child.parent is anchor and test.within_one_se and (
            (child.n_params < anchor.n_params and fewer_reasons) or
            (child.n_params <= anchor.n_params and strictly_fewer)):
        status = Status.SIMPLIFIES   # fewer parameters, or as many and fewer reasons against it: not worse
    elif child.parent is anchor and (_lower(child.mse, anchor.mse) or test.within_one_se or child.move.kind == "lift"):
        status = Status.LOOK_AHEAD   # a possible first of two moves (a lift model: the terms may need to follow)
    else:
        status = Status.REJECTED
    return dataclasses.replace(child, status=status, anchor=anchor, test=test)


def adds_state(parent: Candidate, child: Candidate) -> bool:
    """Whether ``child`` has a separation state of its own that ``parent`` lacks."""
    return bool(set(dict(child.states)) - set(dict(parent.states)))


def refits_folds(c: Candidate, move: Move | None = None) -> bool:
    """Whether ``c`` is cross-validated by refitted folds whatever the command's method: a structure with another
    static separation form than the tanh, and either side of a form move. One-step folds linearise the fit about
    the estimates of every training maneuver; a form's sharp breaks (two_break's k1 = 100/rad, a spline's knots)
    move far when a fold leaves out the maneuvers that place them, and the linearisation is then far off (on the
    two-break truth at scale 0.2 a two_break child held out 50 % worse than the tanh by one-step folds, 4.6 %
    better by refitted ones, with a lower validation MSE)."""
    return bool(c.forms) or (move is not None and move.kind == "form")


def _fits(run: "_Search", candidates: Sequence[Candidate], moves: Sequence[Move | None], donors_, **options
          ) -> list[CandidateResult]:
    """``candidates`` fitted with ``run``'s fitter (``options`` changed), those that :func:`refits_folds`
    cross-validated by refitted folds; in order."""
    out: list[CandidateResult | None] = [None] * len(candidates)
    for refit in (False, True):
        idx = [i for i, (c, m) in enumerate(zip(candidates, moves)) if refits_folds(c, m) == refit]
        if not idx:
            continue
        fitter = run.fitter.with_options(**options, **({"cv_method": "refit"} if refit else {}))
        for i, r in zip(idx, fitter.fit([candidates[i] for i in idx], donors_)):
            out[i] = r
    return out


def _refitted_anchors(run: "_Search", anchors: Sequence[Node]) -> dict[int, CandidateResult]:
    """The anchors of form moves whose folds were one-step, fitted again with refitted folds (warm started from
    their own fit: the same estimates, other folds), by ``id``: a form move is judged on refitted folds on both
    sides."""
    todo = {id(a): a for a in anchors if not a.result.failed and a.result.cv is not None
            and a.result.cv_method != "refit"}
    if not todo:
        return {}
    own = [dataclasses.replace(a, candidate=dataclasses.replace(a.candidate, name=a.candidate.name + " [one-step]"))
           for a in todo.values()]
    fitter = run.fitter.with_options(cv_method="refit")
    return dict(zip(todo, fitter.fit([a.candidate for a in todo.values()], donors(own))))


def _nested_first(improved: list[Node], tried: list[Node], alpha: float) -> list[Node]:
    """The improving moves best first, except among the moves within one standard error of the best (the ranking's
    rule: the data cannot tell them apart), where :func:`_preference` orders (the unmodelled effect is named),
    then the fewest parameters.

    The step's test has said that the best move improves; which of the moves the data cannot tell from it is
    adopted is the ranking's choice, so a library effect within one standard error of the best is adopted in its
    place even when its own test does not pass (its test then records the move it stands for), provided it lowers
    the held-out and validation MSE and adds no hard reason. The false-adoption rate is unchanged: nothing is
    adopted unless the best move passes."""
    if not improved:
        return improved
    best = improved[0]

    def near_best(n):
        return n is best or move_test(best.result, n.result, alpha, 1).within_one_se

    peers = [n for n in tried if n.parent is best.parent and n.anchor is best.anchor and n.status != Status.IMPROVES
             and (n.move.effect or n.move.kind in NAMES_SIMULATOR_TERM) and not n.screened and n.status != Status.FAILED and n.test is not None
             and n.test.pooled_gain > 0 and _lower(n.result.validation.mse, n.anchor.result.validation.mse)
             and not (_hard(n) - _hard(n.anchor))]
    near = [n for n in improved if n.parent is best.parent and near_best(n)] + [n for n in peers if near_best(n)]
    # of the moves of one preference, the fewest parameters (the one-standard-error rule, as :func:`choose`):
    # a move that adds more than the data can tell apart from a smaller one is paid for in later steps
    # (CL from the intercept adopted X*de at two states in place of de alone, then needed three moves to undo it)
    preferred = _by_mse(near, lambda n: (_preference(n), n.n_params, n is not best))[0]
    if preferred.status != Status.IMPROVES:
        preferred = dataclasses.replace(preferred, status=Status.IMPROVES,
                                        test=dataclasses.replace(preferred.test, stands_for=best.move.name))
    return [preferred] + [n for n in improved if n is not preferred]


def _shortlist(prelim: list[Node], beam: int) -> list[Node]:
    """The screened children worth a full fit: the best that improve (twice the beam), the simplest that may
    simplify, and the look-aheads the beam could keep (lift models first)."""
    def pick(status, prefix, n):
        return _by_mse((c for c in prelim if c.status == status), prefix)[:n]
    chosen = pick(Status.IMPROVES, lambda c: (), 2 * beam) + \
        pick(Status.SIMPLIFIES, lambda c: (c.n_params,), SIMPLIFY_SHORTLIST) + \
        pick(Status.LOOK_AHEAD, lambda c: (c.move.kind != "lift",), beam)
    seen, out = set(), []
    for c in chosen:
        if id(c) not in seen:
            seen.add(id(c))
            out.append(c)
    return out


@dataclass
class _Search:
    """What one exploration holds while it runs: the fitter (quiet: the exploration says what it does), the
    moves it may make, the structures it has visited and how many it fitted."""

    fitter: Fitter
    library: TermLibrary
    lift_candidates: dict[str, Candidate]
    kinds: Sequence[str]
    judge: Judge
    alpha: float
    visited: set = field(default_factory=set)
    n_fitted: int = 0

    def node(self, c: Candidate, r: CandidateResult, **kw) -> Node:
        return Node(c, r, reasons=tuple(self.judge(r, c)) if not r.failed else (f"fit failed: {r.error}",), **kw)

    def new_moves(self, parent: Node, kinds: Sequence[str]) -> tuple[list[tuple[Move, Candidate]], int]:
        """The moves from ``parent`` to structures not visited yet (now visited), and how many moves it has."""
        moves = generate(parent.candidate, self.library, self.lift_candidates, kinds)
        fresh = []
        for move, child in moves:
            key = structure_key(child)
            if key not in self.visited:
                self.visited.add(key)
                fresh.append((move, child))
        return fresh, len(moves)


def explore(start: Candidate, fitter: Fitter, library: TermLibrary, *,
            beam: int = DEFAULT_BEAM, alpha: float = DEFAULT_ALPHA, max_steps: int = DEFAULT_MAX_STEPS,
            kinds: Sequence[str] = MOVE_KINDS, judge: Judge | None = None,
            stop: Callable[[Node], bool] | None = None, simplify: bool = True,
            at_floor: Callable[[Node], bool] | None = None) -> Exploration:
    """Search structures from ``start`` (module docstring) with ``fitter``, whose lift models a drag or pitch
    structure may be fed (by name; the start's own among them). Without ``simplify`` no move is adopted for
    simplifying alone (the diagnosis asks what is missing, not what the data cannot support). ``at_floor`` says
    whether a structure's own residual holds nothing a library-free model predicts out of sample: when no move
    passes from such a structure, no look-ahead is taken (no pair of moves can pay where nothing is left), and
    the search stops there."""
    say = fitter.say
    t0 = time.perf_counter()
    run = _Search(fitter.quiet(), library, {name: lf.candidate for name, lf in fitter.lifts.items()}, kinds,
                  judge or (lambda r, c: ()), alpha)
    start_result = _fits(run, [start], [None], ())[0]
    if start_result.failed:
        from ..data.errors import StructSearchError
        raise StructSearchError(f"fitting the start structure {start.name} failed: {start_result.error}")
    root = run.node(start, start_result)
    run.visited.add(structure_key(start))
    run.n_fitted = 1
    current, confirmed, steps = [root], [root], []   # confirmed: every adopted structure
    stopped = Stop.MAX_STEPS
    if stop is not None and stop(root):
        return Exploration(root, root, (), Stop.START.value, 1, time.perf_counter() - t0, Stop.START)
    for index in range(1, max_steps + 1):
        step, n_tried, why = _search_step(run, current, index, beam, simplify, at_floor)
        steps.append(step)
        nxt = list(step.beam)
        confirmed += [n for n in nxt if n.status in CONFIRMED]
        adopted_now = [n for n in nxt if n.status in CONFIRMED]
        best = _lowest_mse(adopted_now) if adopted_now else None
        # progress only, no verdict: what a step carries on is not yet what the search adopts (the final choice
        # comes at the end; a look-ahead may lead nowhere), and a line that named it contradicted the documents
        say(f"step {index}: {n_tried} structures tried ({run.n_fitted} in all), "
            f"{f'{len(nxt)} carried to the next step' if nxt else 'none carried on: the search stops'}, "
            f"{time.perf_counter() - t0:.0f} s{_pairing(step)}")
        if not nxt:
            stopped = why
            break
        if best is not None and stop is not None and stop(best):
            stopped = Stop.GOOD_ENOUGH
            break
        current = nxt
    return _finish(run, root, confirmed, steps, stopped, max_steps, simplify, t0)


def _pairing(step: Step) -> str:
    """What the step's adoption tests paired, when not whole maneuvers (a campaign of few long records)."""
    tests = [n.test for n in step.tried if n.test is not None and "paired by" in n.test.basis]
    if not tests:
        return ""
    return f"; moves tested on {tests[0].n_maneuvers} units ({tests[0].basis.split('paired by ')[1]}: too few maneuvers)"


def _finish(run: _Search, root: Node, confirmed: list[Node], steps: list[Step], stopped: Stop, max_steps: int,
            simplify: bool, t0: float) -> Exploration:
    """The search's end: with ``simplify`` (a discovery) the best adopted structure repaired while it is not
    admissible, then the final structure chosen over every structure fitted (:mod:`.final_choice`), with the
    better ones it sets aside."""
    top = choose(confirmed, run.alpha)   # the best adopted structure, admissible or not
    stopped_at = steps[-1].expanded if steps else (root.candidate.name,)
    if simplify and not top.admissible:
        # the best structure the steps reached is repaired, not the admissible one that is left after it: a
        # structure of fewer reasons chosen before the repair may be far worse (the intercept and the elevator
        # chosen over two identified lift states whose first term was still correlated)
        confirmed = confirmed + _repair(run, top, steps, max_steps, run.fitter.say, t0)
    interim = Exploration(root, root, tuple(steps), stopped.value, run.n_fitted, 0.0, stopped)
    fitted = interim.fitted(full=True)
    final, rule = select_final(fitted, confirmed, run.alpha, admissible_first=simplify)
    aside = set_aside(final, interim.fitted(full=False), confirmed, run.alpha, simplify)
    return Exploration(root, final, tuple(steps), stopped.value, run.n_fitted, time.perf_counter() - t0, stopped,
                       aside, rule, stopped_at)


def _search_step(run: _Search, current: list[Node], index: int, beam: int, simplify: bool,
                 at_floor: Callable[[Node], bool] | None) -> tuple[Step, int, Stop | None]:
    """One step from the beam ``current``: every new child screened, the shortlist fitted in full and judged; the
    step (its beam: what the next step expands), how many children it tried and, when it keeps none, why."""
    t_step = time.perf_counter()
    pending: list[tuple[Node, Move, Candidate]] = []
    n_moves: dict[int, int] = {}
    for parent in current:
        anchor = parent if parent.status in CONFIRMED else parent.anchor
        fresh, n_all = run.new_moves(parent, run.kinds)
        n_moves[id(anchor)] = n_moves.get(id(anchor), 0) + n_all
        pending += [(parent, move, child) for move, child in fresh]
    tried = _judged_children(run, current, pending, n_moves, index, beam)
    improved = _nested_first(_by_mse(n for n in tried if n.status == Status.IMPROVES), tried, run.alpha)
    if improved:   # the preferred move may stand for the best (its status changed): the record shows it
        tried = [improved[0] if t.candidate is improved[0].candidate else t for t in tried]
    simpler = _by_mse((n for n in tried if n.status == Status.SIMPLIFIES), lambda n: (len(n.reasons), n.n_params))
    ahead = _by_mse(n for n in tried if n.status == Status.LOOK_AHEAD)
    adopted = [n for n in current if n.status in CONFIRMED]
    why = None
    if improved:
        nxt = improved[:beam]
    elif simpler and simplify:
        nxt = simpler[:1]
    elif ahead and adopted and not (at_floor is not None and all(at_floor(n) for n in adopted)):
        # a change of lift model first: it is what the other terms of a drag or pitch model build on
        nxt = _by_mse(ahead, lambda n: (n.move.kind != "lift",))[:beam]
    else:
        nxt = []
        # the gate is named only where it decided: look-aheads there were, from adopted structures it closed
        why = (Stop.OWN_FLOOR if ahead and adopted else
               Stop.LOOK_AHEAD_LED_NOWHERE if len(adopted) < len(current) else Stop.NO_MOVE)
    # only the chosen look-aheads and simplifications keep that status: the others are rejected for the record
    chosen = {id(n) for n in nxt}
    tried = [n if n.status not in (Status.LOOK_AHEAD, Status.SIMPLIFIES) or id(n) in chosen
             else dataclasses.replace(n, status=Status.REJECTED) for n in tried]
    nxt = [next(t for t in tried if t.candidate is n.candidate) for n in nxt]
    step = Step(index, tuple(n.candidate.name for n in current), tuple(tried), tuple(nxt),
                time.perf_counter() - t_step)
    return step, len(pending), why


def _judged_children(run: _Search, current: list[Node], pending, n_moves: dict[int, int], index: int,
                     beam: int) -> list[Node]:
    """Every pending child screened (estimates and out-of-sample scores: what the test needs, no statistics)
    and judged; the shortlist fitted in full (statistics, admissibility) and judged again; the others
    rejected. A form move is judged on refitted folds on both sides (:func:`refits_folds`)."""
    screens = _fits(run, [c for _, _, c in pending], [m for _, m, _ in pending], donors(current), scores_only=True)
    anchors = {id(a): a for a in (p if p.status in CONFIRMED else p.anchor for p, _, _ in pending)}
    refitted = _refitted_anchors(run, [anchors[k] for k in dict.fromkeys(
        id(p if p.status in CONFIRMED else p.anchor) for p, m, c in pending if refits_folds(c, m))])
    prelim = []
    for (parent, move, child), result in zip(pending, screens):
        anchor = parent if parent.status in CONFIRMED else parent.anchor
        raw = Node(child, result, move=move, parent=parent, step=index, screened=True)
        prelim.append(_verdict(raw, anchor, n_moves[id(anchor)], run.alpha, judged=False,
                               against=refitted.get(id(anchor)) if refits_folds(child, move) else None))
    shortlist = _shortlist(prelim, beam)
    # warm started from their own screening (renamed: a structure does not donate to itself by name)
    screened_donors = [dataclasses.replace(n, candidate=dataclasses.replace(n.candidate,
                                                                           name=n.candidate.name + " [screened]"))
                       for n in shortlist if not n.result.failed]
    fulls = _fits(run, [n.candidate for n in shortlist], [n.move for n in shortlist],
                  donors(list(current) + screened_donors))
    run.n_fitted += len(pending)
    judged = {id(n): _verdict(run.node(n.candidate, r, move=n.move, parent=n.parent, step=index), n.anchor,
                              n_moves[id(n.anchor)], run.alpha,
                              against=refitted.get(id(n.anchor)) if refits_folds(n.candidate, n.move) else None)
              for n, r in zip(shortlist, fulls)}
    return [judged.get(id(n), dataclasses.replace(n, status=Status.REJECTED if n.status != Status.FAILED else Status.FAILED))
            for n in prelim]


def _repair(run: _Search, final: Node, steps: list[Step], max_steps: int, say, t0: float) -> list[Node]:
    """``final`` repaired while it is not admissible (repairs count in the steps' budget): the repairs adopted."""
    repairs = []
    for index in range(len(steps) + 1, max_steps + 1):
        t_step = time.perf_counter()
        known = {structure_key(n.candidate): n.result for s in steps for n in s.tried if not n.screened}
        step, fitted = _repair_step(run, final, index, known)
        run.n_fitted += fitted
        steps.append(dataclasses.replace(step, seconds=time.perf_counter() - t_step))
        if not step.beam:
            break
        final = step.beam[0]
        repairs.append(final)
        say(f"repair {index}: {fitted} structures tried, kept {final.move.name} "
            f"({len(final.reasons)} reasons against it), {time.perf_counter() - t0:.0f} s")
        if final.admissible:
            break
    return repairs


def _repair_step(run: _Search, current: Node, index: int, known: dict) -> tuple[Step, int]:
    """One repair of a structure that is not admissible: every removing or simplifying move fitted in full; of the
    children with fewer reasons than ``current`` (or as many, fewer parameters and within one standard error of it)
    and no new hard reason, those within one standard error of it
    when there are any (a repair that removes a reason by undoing the structure's gain, a state dropped whole,
    leaves the search where it started), then the fewest reasons, the fewest parameters, the lowest held-out MSE.
    A child the search fitted in full (``known``) is judged on that fit; one it only screened is fitted in full now
    (its admissibility was never judged): the repairs of a structure are mostly its own step's children."""
    # a structure on the way to ``current`` is no repair of it: the search would go back where it came from
    behind = {structure_key(n.candidate) for n in current.path()}
    moves = {structure_key(c): (m, c) for m, c in generate(current.candidate, run.library, run.lift_candidates,
                                                          REPAIR_KINDS) if structure_key(c) not in behind}
    fresh = [key for key in moves if key not in known]
    run.visited.update(fresh)
    fulls = dict(zip(fresh, _fits(run, [moves[k][1] for k in fresh], [moves[k][0] for k in fresh],
                                  donors([current]))))
    tried = []
    for key, (move, child) in moves.items():
        result = fulls[key] if key in fulls else known[key]
        n = run.node(child, result, move=move, parent=current, step=index)
        status = Status.FAILED if result.failed else Status.REJECTED
        tried.append(dataclasses.replace(n, status=status, anchor=current,
                                         test=move_test(current.result, result, run.alpha, max(len(moves), 1))))
    # a reason lists every term the t-test accepts at zero: dropping one of them within one standard error leaves
    # as many reasons, and is a repair too (fewer parameters, not worse)
    fewer = [n for n in tried if n.status != Status.FAILED and not (_hard(n) - _hard(current))
             and (len(n.reasons) < len(current.reasons) or (len(n.reasons) == len(current.reasons)
                                                             and n.n_params < current.n_params
                                                             and n.test.within_one_se))]
    keeps_fit = [n for n in fewer if n.test.within_one_se]
    best = _by_mse(keeps_fit or fewer, lambda n: (len(n.reasons), n.n_params))[0] if fewer else None
    if best is not None:
        kept = dataclasses.replace(best, status=Status.REPAIRS)
        tried = [kept if n is best else n for n in tried]
        beam = (kept,)
    else:
        beam = ()
    return Step(index, (current.candidate.name,), tuple(tried), beam, 0.0), len(fresh)
