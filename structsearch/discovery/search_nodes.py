"""What a structure search records: each structure it fitted (:class:`Node`, with its verdict, a
:class:`Status`), each step (:class:`Step`), why it stopped (:class:`Stop`), the better structures its final
choice set aside (:class:`SetAside`) and the whole search (:class:`Exploration`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
from .adoption import MoveTest
from .moves import Move


class Status(StrEnum):
    """A structure's verdict in the search (the value is the word diagnosis.json and discover.json show)."""

    START = "start"                # where the search began
    IMPROVES = "improves"          # its move passed the adoption test and lowers the validation MSE
    SIMPLIFIES = "simplifies"      # fewer parameters (or reasons) within one standard error of its parent
    REPAIRS = "repairs"            # removes a reason against admissibility (a discovery's last steps)
    LOOK_AHEAD = "look-ahead"      # the first of two moves: its own children are tested against its parent
    REJECTED = "rejected"
    FAILED = "failed"              # its fit failed



@dataclass(frozen=True, eq=False)
class Node:
    """A structure the search fitted: how it was reached (``move`` from ``parent``), its test against the
    structure it is compared with (``anchor``: its parent, or the parent's parent after a look-ahead) and its
    verdict (``status``)."""

    candidate: Candidate
    result: CandidateResult
    move: Move | None = None
    parent: "Node | None" = field(default=None, repr=False)
    anchor: "Node | None" = field(default=None, repr=False)
    test: MoveTest | None = None
    status: Status = Status.START
    reasons: tuple[str, ...] = ()
    step: int = 0
    screened: bool = False        # fitted for its scores only (no statistics: not judged for admissibility)

    @property
    def admissible(self) -> bool:
        return not self.reasons and not self.result.failed

    @property
    def mse(self) -> float:
        """The held-out MSE the search compares: cross-validation, else validation."""
        return float("inf") if self.result.failed else self.result.comparison.mse

    @property
    def n_params(self) -> int:
        return self.result.n_params

    def path(self) -> list["Node"]:
        """The nodes from the start to this one (the start first)."""
        out, node = [], self
        while node is not None:
            out.append(node)
            node = node.parent
        return out[::-1]


class Stop(StrEnum):
    """Why a search's steps ended (what the step found, not yet how the final structure compares with the floor:
    :func:`structsearch.discovery.final_choice.stopped_text` words it)."""

    START = "good enough at the start"
    GOOD_ENOUGH = "good enough"
    NO_MOVE = "no move passes the test"                  # and no look-ahead was left to take
    LOOK_AHEAD_LED_NOWHERE = "no move passes the test, alone or after a look-ahead"
    OWN_FLOOR = "no move passes the test; no look-ahead from a structure at the floor of its own residual"
    MAX_STEPS = "step budget reached"


@dataclass(frozen=True)
class SetAside:
    """A structure the search fitted with a lower held-out MSE than the final one, and why the final choice set it
    aside; ``excess`` (with ``excess_se``) is the final structure's per-maneuver relative excess of out-of-sample
    MSE over it, ``mse_cost`` the difference of the held-out MSEs: what the choice costs."""

    node: "Node"
    reason: str
    excess: float
    excess_se: float
    mse_cost: float

    def to_dict(self) -> dict:
        def num(x):
            return float(x) if x is not None and x == x and abs(x) != float("inf") else None
        n = self.node
        return {"name": n.candidate.name, "move": n.move.name if n.move is not None else None, "status": n.status,
                "screened": n.screened, "n_params": n.n_params, "mse": num(n.mse),
                "mse_validation": num(n.result.validation.mse), "admissible": None if n.screened else n.admissible,
                "reasons": list(n.reasons), "reason": self.reason, "excess": num(self.excess),
                "excess_se": num(self.excess_se), "mse_cost": num(self.mse_cost)}


@dataclass(frozen=True)
class Step:
    index: int
    expanded: tuple[str, ...]     # the structures whose moves were tried
    tried: tuple[Node, ...]       # every child fitted in this step, with its verdict
    beam: tuple[Node, ...]        # what the next step expands
    seconds: float


@dataclass(frozen=True)
class Exploration:
    start: Node
    final: Node
    steps: tuple[Step, ...]
    stopped: str                  # why the search ended (Stop's words, or stopped_text's once the floor is known)
    n_fitted: int
    seconds: float
    stop: Stop = Stop.MAX_STEPS
    # the structures the final choice set aside though their held-out MSE is lower, lowest first
    set_aside: tuple[SetAside, ...] = ()
    final_rule: str = ""          # how the final structure was chosen among the structures fitted
    stopped_at: tuple[str, ...] = ()   # the structures the last step of the search (not a repair) expanded

    def fitted(self, full: bool = True) -> list[Node]:
        """Every structure the search fitted (the start first): only those fitted in full (statistics and
        admissibility judged) with ``full``; failed fits left out."""
        nodes = [self.start] + [n for s in self.steps for n in s.tried]
        return [n for n in nodes if not n.result.failed and not (full and n.screened)]

    @property
    def path(self) -> list[Node]:
        """The adopted moves, in order (the start excluded)."""
        return self.final.path()[1:]

    def tried_from(self, node: Node) -> list[Node]:
        """Every child fitted from ``node`` (look-aheads' children from their own parent)."""
        return [n for s in self.steps for n in s.tried if n.parent is node]
