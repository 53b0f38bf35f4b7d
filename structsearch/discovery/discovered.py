"""What ``discover`` returns: the path of moves from a start structure to the final structure (with the spec
file it is written to), the better structures the final choice set aside and why, and a comparison with the
grids' rank-1 candidate and the thesis' final model. ``to_dict()`` is ``discover.json`` (docs/interfaces.md,
"discover").
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from ..data.coefficients import GRID_OF
from ..fitting.fitter import Fitter
from .adoption import move_test
from .explore import CONFIRMED, Exploration
from .judge import judge_for



def _num(x) -> float | None:
    return float(x) if x is not None and np.isfinite(x) else None


@dataclass(frozen=True)
class PathStep:
    """One adopted move: what it did, the structure it made, its scores, its test, its shrink of the gap to the
    floor and where it acts (the phase and alpha band where it improves the fit most)."""

    move: str
    kind: str
    effect: str | None
    structure: Mapping[str, Any]
    mse_validation: float
    mse_cv: float | None
    test: Mapping[str, Any] | None
    shrink: float | None
    where: Mapping[str, str] | None
    # why it was adopted: "improves" (its test passed, or it stands for a move within one SE whose test did),
    # "simplifies" (fewer parameters within one SE), "repairs" (removes a reason against admissibility),
    # "look-ahead" (the first of two moves whose second passed), "selected" (the final structure, not adopted by
    # the steps: the final choice over every structure fitted took it)
    verdict: str = "improves"

    @property
    def p_value(self) -> float | None:
        return None if self.test is None else self.test.get("p_value")

    def to_dict(self) -> dict:
        return {"move": self.move, "kind": self.kind, "effect": self.effect, "structure": dict(self.structure),
                "mse_validation": self.mse_validation, "mse_cv": _num(self.mse_cv),
                "test": dict(self.test) if self.test else None, "p_value": self.p_value, "shrink": self.shrink,
                "where": dict(self.where) if self.where else None, "verdict": self.verdict}


@dataclass(frozen=True)
class FinalStructure:
    name: str
    spec: str | None              # the spec file written (None: not written)
    structure: Mapping[str, Any]
    mse_validation: float
    mse_cv: float | None
    admissible: bool
    reasons: tuple[str, ...]

    def to_dict(self) -> dict:
        return {"name": self.name, "spec": self.spec, "structure": dict(self.structure),
                "mse_validation": self.mse_validation, "mse_cv": _num(self.mse_cv), "admissible": self.admissible,
                "reasons": list(self.reasons)}


@dataclass(frozen=True)
class ComparisonRow:
    """A reference structure against the discovered one: the per-maneuver relative excess of its held-out MSE
    over the discovered structure's, with its standard error, and whether the two are within noise of each
    other by the ranking's one-standard-error rule (either way)."""

    role: str                     # "discovered", "grid rank 1", "thesis final"
    name: str
    n_params: int
    mse_validation: float
    mse_cv: float | None
    admissible: bool
    excess: float | None
    excess_se: float | None
    within_noise: bool | None
    terms: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        return {"role": self.role, "name": self.name, "n_params": self.n_params,
                "mse_validation": self.mse_validation, "mse_cv": _num(self.mse_cv), "admissible": self.admissible,
                "excess": _num(self.excess), "excess_se": _num(self.excess_se), "within_noise": self.within_noise,
                "terms": list(self.terms)}


@dataclass(frozen=True)
class SetAsideRow:
    """A structure the search fitted with a lower held-out MSE than the final one, set aside by the final choice:
    why (``reason``) and what it costs (the final structure's relative ``excess`` over it, with ``excess_se``, and
    ``mse_cost``, the difference of the held-out MSEs). ``admissible`` is None for a structure only screened."""

    name: str
    move: str | None
    status: str
    screened: bool
    n_params: int
    mse: float | None
    mse_validation: float | None
    admissible: bool | None
    reasons: tuple[str, ...]
    reason: str
    excess: float | None
    excess_se: float | None
    mse_cost: float | None

    @classmethod
    def of(cls, aside) -> "SetAsideRow":
        """The row of a :class:`~.search_nodes.SetAside`."""
        d = aside.to_dict()
        return cls(**{**d, "status": str(d["status"]), "reasons": tuple(d["reasons"])})

    def to_dict(self) -> dict:
        return {**dataclasses.asdict(self), "reasons": list(self.reasons)}


@dataclass(frozen=True)
class StepLine:
    index: int
    tried: int
    kept: str
    best: str
    best_mse: float
    seconds: float

    def to_dict(self) -> dict:
        return {"index": self.index, "tried": self.tried, "kept": self.kept, "best": self.best,
                "best_mse": self.best_mse, "seconds": self.seconds}


@dataclass(frozen=True)
class Discovery:
    coefficient: str
    start: Mapping[str, Any]
    start_mse_validation: float
    start_mse_cv: float | None
    path: tuple[PathStep, ...]
    final: FinalStructure
    comparison: tuple[ComparisonRow, ...]
    steps: tuple[StepLine, ...]
    stopped: str
    structures_fitted: int
    noise_floor: float
    explained: bool
    # the diagnosis of the search (structsearch.diagnosis.results.Diagnosis: diagnosis.json), which the
    # diagnosis layer made for it (discovery does not import the layer above it)
    diagnosis: Any = field(repr=False)
    seconds: float = field(default=float("nan"), compare=False)
    # the better structures the final choice set aside (lowest held-out MSE first), and its rule
    set_aside: tuple[SetAsideRow, ...] = ()
    final_rule: str = ""
    # the search itself, every structure it fitted (not written: what a caller checks the final choice against)
    exploration: Exploration | None = field(default=None, repr=False, compare=False)
    # the final structure as the answer, by the ranking's rule (docs/interfaces.md 8.1; None: nothing to judge)
    answer: Any = None

    def to_dict(self) -> dict:
        """``discover.json``."""
        return {"coefficient": self.coefficient, "start": dict(self.start),
                "start_mse_validation": self.start_mse_validation, "start_mse_cv": _num(self.start_mse_cv),
                "path": [p.to_dict() for p in self.path], "final": self.final.to_dict(),
                "comparison": [c.to_dict() for c in self.comparison], "steps": [s.to_dict() for s in self.steps],
                "stopped": self.stopped, "structures_fitted": self.structures_fitted,
                "noise_floor": self.noise_floor, "at_floor": self.explained,
                "terms": dict((self.diagnosis.search or {}).get("terms", {})), "seconds": self.seconds,
                "final_rule": self.final_rule, "set_aside": [a.to_dict() for a in self.set_aside],
                "answer": self.answer.to_dict() if self.answer is not None else None}


def _cv(result) -> float | None:
    return result.cv.mse if result.cv is not None else None


def _row(role, candidate, result, found, judge) -> ComparisonRow:
    if result.failed:
        return ComparisonRow(role, candidate.name, 0, float("nan"), None, False, None, None, None)
    reasons = tuple(judge(result, candidate))
    if result is found:
        excess = se = None
        within = True
    else:
        test = move_test(result, found, 1.0, 1)   # the discovered structure against this one
        excess, se, within = -test.gain, test.gain_se, test.within_one_se
    return ComparisonRow(role, candidate.name, result.n_params, result.validation.mse, _cv(result), not reasons,
                         excess, se, within, tuple(e for _, e in candidate.regressors))


def build_discovery(fitter: Fitter, diagnosis, exploration: Exploration, seconds: float) -> Discovery:
    """The :class:`Discovery` of ``exploration`` (its ``diagnosis`` says how far each adopted move closed the
    gap), compared with the grid's rank-1 candidate and the thesis' final model (fitted with ``fitter``)."""
    from ..fitting.specs import find_candidate, load_grid
    from ..flight.reference import FINAL_MODEL_NAMES
    from ..grid_search.pipeline import search
    judge = judge_for(fitter.campaign)
    say = fitter.say
    nodes = exploration.final.path()
    path = []
    for i, node in enumerate(nodes[1:]):
        r = diagnosis.rounds[i]
        row = r.effect(node.move.name)
        path.append(PathStep(node.move.name, node.move.kind, node.move.effect, node.candidate.to_dict(),
                             node.result.validation.mse, _cv(node.result),
                             node.test.to_dict() if node.test is not None else None,
                             row.shrink if row is not None else None,
                             dict(row.acts_in) if row is not None and row.acts_in else None,
                             node.status if node.status in CONFIRMED or node is not exploration.final else "selected"))
    final_node = exploration.final
    final = FinalStructure(final_node.candidate.name, None, final_node.candidate.to_dict(),
                           final_node.result.validation.mse, _cv(final_node.result), final_node.admissible,
                           final_node.reasons)
    coef = final_node.candidate.coefficient
    # the thesis' final model, where the thesis has one (it models C_L, C_D and C_m)
    thesis_name = FINAL_MODEL_NAMES.get(coef)
    say(f"the {GRID_OF[coef]} grid's rank-1 candidate" + (" and the thesis' final model" if thesis_name else "")
        + ", for comparison")
    rows = [_row("discovered", final_node.candidate, final_node.result, final_node.result, judge)]
    grid = search(dataclasses.replace(fitter.quiet(), lifts={}), GRID_OF[coef], do_refine=False)
    ranked = grid.grids[GRID_OF[coef]]
    if ranked and not ranked[0].failed:
        rank1 = load_grid(GRID_OF[coef])[ranked[0].name]
        rows.append(_row(f"{GRID_OF[coef]} grid rank 1", rank1, ranked[0], final_node.result, judge))
    if thesis_name:
        thesis = find_candidate(thesis_name)
        rows.append(_row("thesis final", thesis, fitter.quiet().fit_one(thesis), final_node.result, judge))
    steps = tuple(StepLine(s.index, len(s.tried), (s.beam[0].status + " " + s.beam[0].move.name) if s.beam else "-",
                           min((n for n in s.beam), key=lambda n: n.mse).candidate.name if s.beam else "-",
                           min((n.mse for n in s.beam), default=float("nan")), s.seconds)
                  for s in exploration.steps)
    start = exploration.start
    return Discovery(coef, start.candidate.to_dict(), start.result.validation.mse, _cv(start.result), tuple(path),
                     final, tuple(rows), steps, exploration.stopped, exploration.n_fitted, diagnosis.noise_floor,
                     diagnosis.explained, diagnosis, seconds, tuple(map(SetAsideRow.of, exploration.set_aside)),
                     exploration.final_rule, exploration, discovery_answer(exploration))


def discovery_answer(exploration: Exploration):
    """The final structure as the answer (:mod:`structsearch.grid_search.answer`): admissible and within the
    answer's tolerance of the best fit among every structure fitted in full, else "no admissible structure near"
    (a repair that fell back to an admissible structure far worse than the best fit is no answer)."""
    from ..grid_search.answer import answer_of
    final = exploration.final
    others = sorted((n for n in exploration.fitted() if n is not final), key=lambda n: (n.mse, n.candidate.name))
    placed = [n.result.placed(admissible=n.admissible, reasons=n.reasons) for n in [final] + others]
    if not final.admissible:   # the answer is the final structure or none: no other admissible one stands in
        placed = [r.placed(admissible=False, reasons=r.placement.reasons or ("not the final structure",))
                  for r in placed]
    return answer_of(placed)
