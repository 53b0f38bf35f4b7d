"""A global model against the models fitted to each flow regime alone (``fit --by-kind``): the typed records.

Every model is validated on the same held-out maneuvers, nominal and stall apart: the pooled mean squared error of
each regime's validation maneuvers. The global model meets the issue's bar on a regime when its validation MSE
there is at most :data:`TOLERANCE` above the separate model's (a global model that does better passes).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

from ..data.campaign import REGIMES, regime
from .candidate_result import CandidateResult
from .regimes import Part

TOLERANCE = 0.05
FITTED_ON = ("all", "stall", "nominal")


def regime_mse(result: CandidateResult, validation_kinds: Sequence[str]) -> dict[str, float]:
    """Pooled validation MSE of each regime (NaN: no finite score there), from the per-maneuver scores;
    ``validation_kinds``: the kind of each validation maneuver, in the order the scores are."""
    out = {}
    scores = result.validation
    for which in REGIMES:
        pairs = [(m, n) for m, n, k in zip(scores.mse_maneuvers, scores.n_maneuvers, validation_kinds)
                 if regime(k) == which and math.isfinite(m)]
        total = sum(n for _, n in pairs)
        out[which] = sum(m * n for m, n in pairs) / total if total else math.nan
    return out


@dataclass(frozen=True)
class RegimeFit:
    """One model fitted on the training maneuvers of ``fitted_on`` ("all", "stall" or "nominal")."""

    fitted_on: str
    part: Part
    result: CandidateResult
    validation_mse: Mapping[str, float]   # by regime
    train_maneuvers: int

    def to_dict(self) -> dict:
        r = self.result
        lost = r.estimates.unidentifiable if r.estimates is not None else {}
        params = {k: (math.nan if k in lost else v) for k, v in r.estimates.params.items()} \
            if r.estimates is not None else {}
        stderr = dict(r.estimates.stderr) if r.estimates is not None else {}
        return {"model": self.part.candidate.name, "fitted_on": self.fitted_on,
                "train_maneuvers": self.train_maneuvers, "note": self.part.candidate.note,
                "lift": self.part.candidate.lift,
                "regressors": dict(self.part.candidate.regressors),
                "validation_mse": {k: _number(v) for k, v in self.validation_mse.items()},
                "mse_train": _number(r.train.mse) if r.train is not None else None,
                "params": {k: _number(v) for k, v in params.items()},
                "stderr": {k: _number(v) for k, v in stderr.items()},
                "unidentifiable": [{"parameter": p, "value": None, "reason": why}
                                   for p, why in self.part.unidentifiable],
                "not_identifiable": dict(r.estimates.not_identifiable) if r.estimates is not None else {},
                "sums": {name: list(of) for name, of in self.part.sums}}


@dataclass(frozen=True)
class KindComparison:
    """A global model and the models fitted to each regime alone, validated per regime."""

    name: str
    coefficient: str
    fits: tuple[RegimeFit, ...]    # in FITTED_ON order

    def fit(self, fitted_on: str) -> RegimeFit:
        return next(f for f in self.fits if f.fitted_on == fitted_on)

    def ratio(self, which: str) -> float:
        """Global validation MSE on regime ``which`` over that of the model fitted to ``which`` alone."""
        separate = self.fit(which).validation_mse[which]
        return self.fit("all").validation_mse[which] / separate if separate > 0 else math.nan

    def within(self, which: str, tolerance: float = TOLERANCE) -> bool:
        r = self.ratio(which)
        return math.isfinite(r) and r <= 1.0 + tolerance

    def to_dict(self) -> dict:
        return {"model": self.name, "coefficient": self.coefficient, "fits": [f.to_dict() for f in self.fits],
                "ratio": {w: _number(self.ratio(w)) for w in REGIMES},
                "within_tolerance": {w: self.within(w) for w in REGIMES}, "tolerance": TOLERANCE}


@dataclass(frozen=True)
class ByKind:
    """``fit --by-kind``'s result: one comparison per global model, and the validation maneuvers of each regime."""

    comparisons: tuple[KindComparison, ...]
    validation_maneuvers: Mapping[str, tuple[str, ...]]

    @property
    def passed(self) -> bool:
        return all(c.within(w) for c in self.comparisons for w in REGIMES)

    def to_dict(self) -> dict:
        return {"by_kind": [c.to_dict() for c in self.comparisons],
                "validation_maneuvers": {k: list(v) for k, v in self.validation_maneuvers.items()},
                "tolerance": TOLERANCE, "passed": self.passed}


def _number(x: float) -> float | None:
    """JSON's number, None for NaN (statistics that do not exist are null, never a made-up value)."""
    return float(x) if x is not None and math.isfinite(x) else None
