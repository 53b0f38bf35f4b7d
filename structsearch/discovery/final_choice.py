"""The structure a search ends with, chosen over every structure it fitted, and why it stopped, in words that
agree with its numbers.

The steps adopt moves one test at a time, and a beam of adopted structures is what they remember; the final
choice is made afterwards over *every* structure fitted in full, by the ranking's rule: admissible structures
first (``discover``), then the fewest parameters within one standard error of the lowest held-out MSE. A
structure adopted early and left behind by later moves (a state whose terms the data could not identify yet)
is then still a candidate, and a final answer cannot be worse than a structure the search's own log showed
beyond noise. A diagnosis names effects, so its final structure is an adopted one (a move whose test passed:
its false-adoption rate); every structure with a lower held-out MSE that a choice leaves is recorded with the
reason and the MSE it costs (:class:`~.search_nodes.SetAside`), so that nothing better goes unsaid.
"""
from __future__ import annotations

from typing import Sequence

from ..engine.ties import is_tie, sort_by
from ..fitting.comparison import ANSWER_TOLERANCE
from ..grid_search.admissibility import HARD_REASONS, Reason
from .adoption import DEFAULT_ALPHA, move_test
from .moves import NAMES_SIMULATOR_TERM, NESTED_KINDS, structure_key
from .search_nodes import Node, SetAside, Status, Stop

CONFIRMED = (Status.START, Status.IMPROVES, Status.SIMPLIFIES, Status.REPAIRS)


def hard(n: Node) -> set[Reason]:
    """The kinds of hard reasons against ``n`` (:data:`~structsearch.grid_search.admissibility.HARD_REASONS`)."""
    return {kind for kind in map(Reason.of, n.reasons) if kind in HARD_REASONS}


def preference(n: Node) -> int:
    """How a move explains a gap, simplest first: a simulator's own term rescaled (it names the simulator's function
    that misses: a library term of the same signal fits alike), the library's whole effect, its share at one state,
    a move that only adds to its parent (it keeps what the parent explained), any other move; the start last but
    one."""
    if n.move is None:
        return 5
    if n.move.kind in NAMES_SIMULATOR_TERM:
        return 0
    if n.move.effect:
        return 1 if not n.move.at_one_state else 2
    return 3 if n.move.kind in NESTED_KINDS else 4


def by_mse(nodes, prefix=lambda n: ()) -> list[Node]:
    """Nodes by ``prefix``, then held-out MSE; MSEs equal up to rounding (two moves that reach one structure:
    drop a term, or replace it by one the structure has) ordered by fewer parameters, then structure name, on
    every machine."""
    return sort_by(nodes, lambda n: n.mse, lambda n: (n.n_params, n.candidate.name), prefix)


def lower(a: float, b: float) -> bool:
    """``a`` below ``b`` by more than rounding (equal fits are equal on every machine)."""
    return a < b and not is_tie(a, b)


def lowest_mse(nodes: Sequence[Node]) -> Node:
    """The node of lowest held-out MSE, ties as :func:`by_mse` orders them."""
    return by_mse(nodes)[0]


def choose(confirmed: Sequence[Node], alpha: float = DEFAULT_ALPHA, admissible_first: bool = False) -> Node:
    """Of ``confirmed``, the fewest parameters within one standard error of the lowest held-out MSE (the ranking's
    one-standard-error rule), then the move that names the effect (:func:`preference`), then the lower MSE. With
    ``admissible_first``, among the admissible structures when there are any, as the ranking ranks admissible
    candidates first; when none is, among those with the fewest reasons against them of those that fit within the
    answer's tolerance of the best (:data:`~structsearch.fitting.comparison.ANSWER_TOLERANCE`): a structure with fewer
    flaws that fits far worse (the start, say) is no answer to present."""
    pool = [n for n in confirmed if not n.result.failed]
    if admissible_first:
        if not any(n.admissible for n in pool):
            best_fit = lowest_mse(pool)
            pool = [n for n in pool if n is best_fit or n.mse <= best_fit.mse * (1.0 + ANSWER_TOLERANCE)]
        fewest = min(len(n.reasons) for n in pool)
        pool = [n for n in pool if len(n.reasons) == fewest]
    best = lowest_mse(pool)
    near = [n for n in pool if n is best or move_test(best.result, n.result, alpha, 1).within_one_se]
    return by_mse(near, lambda n: (n.n_params, preference(n)))[0]


def select_final(fitted: Sequence[Node], confirmed: Sequence[Node], alpha: float = DEFAULT_ALPHA,
                 admissible_first: bool = False) -> tuple[Node, str]:
    """The final structure and the rule that chose it. With ``admissible_first`` (``discover``): the ranking's
    choice among every admissible structure fitted in full, whatever its verdict in the steps (a verdict judged
    one move against its parent; the final choice compares them all); when none is admissible, among the adopted
    ones with the fewest reasons against them. Without (a diagnosis): among the adopted structures."""
    admissible = [n for n in fitted if n.admissible and not n.screened]
    if admissible_first and admissible:
        return choose(admissible, alpha), ("the fewest parameters within one standard error of the lowest held-out "
                                           "MSE among every admissible structure fitted in full")
    if admissible_first:
        return choose(confirmed, alpha, True), ("no structure fitted is admissible: the fewest parameters within "
                                                "one standard error of the lowest held-out MSE among the adopted "
                                                "structures with the fewest reasons against them, of those within "
                                                f"{ANSWER_TOLERANCE:.0%} of the best adopted fit")
    return choose(confirmed, alpha), ("the fewest parameters within one standard error of the lowest held-out MSE "
                                      "among the adopted structures (a move is adopted when its test passes)")


def set_aside(final: Node, fitted: Sequence[Node], confirmed: Sequence[Node], alpha: float,
              admissible_first: bool) -> tuple[SetAside, ...]:
    """Every structure of ``fitted`` (screened ones too) whose held-out MSE is lower than the final one's beyond
    rounding, lowest first, with the reason the final choice left it and what that costs. A structure reached
    twice (screened in one step, fitted in full by a repair) is listed once, as fitted in full."""
    adopted = {id(n) for n in confirmed}
    seen = {structure_key(final.candidate)}
    out = []
    for n in by_mse((n for n in fitted if lower(n.mse, final.mse)), lambda n: (n.screened,)):
        key = structure_key(n.candidate)
        if key in seen:
            continue
        seen.add(key)
        test = move_test(n.result, final.result, alpha, 1)   # the final structure against this one
        out.append(SetAside(n, _why(n, final, adopted, admissible_first), -test.gain, test.gain_se,
                            final.mse - n.mse))
    return tuple(sorted(out, key=lambda a: a.node.mse))


def _why(n: Node, final: Node, adopted: set, admissible_first: bool) -> str:
    if n.screened:
        return ("screened only: fitted for its scores, not in full (the step's shortlist left it), so its "
                + ("admissibility was not judged" if admissible_first else "test was not taken: not adopted"))
    if admissible_first and not n.admissible:
        return "not admissible: " + "; ".join(n.reasons)
    if admissible_first or id(n) in adopted:
        return ("the one-standard-error rule: the final structure is within one standard error of it with fewer "
                "parameters (or as many, naming an effect)")
    return _not_adopted(n)


def _not_adopted(n: Node) -> str:
    """Why a diagnosis did not adopt ``n`` (its final structure is an adopted one)."""
    new_hard = hard(n) - (hard(n.anchor) if n.anchor is not None else set())
    if new_hard:
        return "not adopted: " + "; ".join(r for r in n.reasons if Reason.of(r) in new_hard)
    if n.status == Status.LOOK_AHEAD:
        return "a look-ahead: its move did not pass its test, and no second move from it did"
    t = n.test
    if t is None:
        return "not adopted"
    if not t.improves:
        return (f"not adopted: its test did not pass (p {t.decisive_p_value:.2g} against the threshold "
                f"{t.threshold:.2g})")
    return "not adopted: its test passed, but the step kept other moves (its beam, or a simpler move within noise)"


def stopped_text(stop: Stop, at_floor: bool, stopped_at: str, max_steps: int) -> str:
    """Why the search ended, in words that agree with the document's floor: "at the floor" only when the final
    structure is (``at_floor``, the diagnosis' verdict against its noise floor)."""
    if stop == Stop.OWN_FLOOR:
        if at_floor:
            return "no move passes the test; at the floor of its own residual, so no look-ahead"
        return (f"no move passes the test from {stopped_at}; no look-ahead was taken (a library-free model of its "
                "residual predicts nothing more out of sample within noise), though the final structure is above "
                "the floor")
    if stop == Stop.MAX_STEPS:
        return f"step budget reached ({max_steps} steps, the repairs' included)"
    return str(stop.value)
