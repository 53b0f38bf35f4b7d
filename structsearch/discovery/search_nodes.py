"""What a structure search records: each structure it fitted (:class:`Node`, with its verdict, a
:class:`Status`), each step (:class:`Step`) and the whole search (:class:`Exploration`)."""
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
    stopped: str                  # why the search ended
    n_fitted: int
    seconds: float

    @property
    def path(self) -> list[Node]:
        """The adopted moves, in order (the start excluded)."""
        return self.final.path()[1:]

    def tried_from(self, node: Node) -> list[Node]:
        """Every child fitted from ``node`` (look-aheads' children from their own parent)."""
        return [n for s in self.steps for n in s.tried if n.parent is node]
