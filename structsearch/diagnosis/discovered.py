"""What ``discover`` returns: the path of adopted moves from a start structure to the structure the search
reaches, the final structure (with the spec file it is written to), and a comparison with the grids' rank-1
candidate and the thesis' final model. ``to_dict()`` is ``discover.json`` (docs/interfaces.md, "discover").
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from .results import Diagnosis


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
    # "look-ahead" (the first of two moves whose second passed)
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
    diagnosis: Diagnosis = field(repr=False)
    seconds: float = field(default=float("nan"), compare=False)

    def to_dict(self) -> dict:
        """``discover.json``."""
        return {"coefficient": self.coefficient, "start": dict(self.start),
                "start_mse_validation": self.start_mse_validation, "start_mse_cv": _num(self.start_mse_cv),
                "path": [p.to_dict() for p in self.path], "final": self.final.to_dict(),
                "comparison": [c.to_dict() for c in self.comparison], "steps": [s.to_dict() for s in self.steps],
                "stopped": self.stopped, "structures_fitted": self.structures_fitted,
                "noise_floor": self.noise_floor, "at_floor": self.explained,
                "terms": dict((self.diagnosis.search or {}).get("terms", {})), "seconds": self.seconds}
