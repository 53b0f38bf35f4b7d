"""The typed result of one candidate of a search: its fit, its scores on both splits, its rank.

The runner caches it as JSON (``to_json``/``from_json``), the ranking orders it, and the
tables, ``fit.json`` and ``ranking.csv`` read it; a failed candidate carries its reason
in ``error`` and no estimates.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import numpy as np

from ..data.atomic import json_ready
from ..engine.results import FitResult
from ..engine.scores import ManeuverScores, R2Summary

# Version of the JSON layout below; part of the cache key, so a cache of another layout is refitted.
JSON_LAYOUT = 6


def _finite_or_none(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def _nan_if_none(v) -> float:
    return float("nan") if v is None else float(v)


@dataclass(frozen=True)
class SplitScores:
    """How a fitted candidate scores on the training or the validation maneuvers."""

    mse: float                          # pooled over samples
    mse_maneuvers: tuple[float, ...]    # per maneuver
    n_maneuvers: tuple[int, ...]        # samples per maneuver
    r2: R2Summary                       # per-maneuver R^2: mean / min / max
    mse_cx: float | None = None         # derived body-axis coefficients (lift and drag candidates)
    mse_cz: float | None = None

    @classmethod
    def of(cls, scores: ManeuverScores, derived: tuple[float, float] | None) -> "SplitScores":
        cx, cz = derived if derived else (None, None)
        return cls(scores.pooled_mse, tuple(map(float, scores.mse)), tuple(map(int, scores.counts)),
                   scores.r2_summary(), cx, cz)

    def to_json(self) -> dict:
        return {"mse": self.mse, "mse_maneuvers": list(self.mse_maneuvers), "n_maneuvers": list(self.n_maneuvers),
                "r2": self.r2.as_dict(),
                "mse_cx": self.mse_cx, "mse_cz": self.mse_cz}

    @classmethod
    def from_json(cls, doc: dict) -> "SplitScores":
        r2 = doc["r2"]
        return cls(_nan_if_none(doc["mse"]), tuple(map(_nan_if_none, doc["mse_maneuvers"])), tuple(map(int, doc["n_maneuvers"])),
                   R2Summary(_nan_if_none(r2["mean"]), _nan_if_none(r2["min"]), _nan_if_none(r2["max"])),
                   doc.get("mse_cx"), doc.get("mse_cz"))


@dataclass(frozen=True)
class CandidateResult:
    """One candidate of a grid after fitting (or failing) and, once ranked, its place.

    Parameter tables read ``names``, ``nonlinear_names``, ``params``, ``stderr``,
    ``p_values``, ``significant``, ``at_bound``, ``high_correlations`` and
    ``correlation`` as they read a :class:`~structsearch.engine.results.FitResult`.
    """

    name: str
    grid: str
    coefficient: str
    lift: str | None
    seconds: float
    error: str | None = None
    # --- the fit (None when it failed) ---
    names: tuple[str, ...] = ()
    nonlinear_names: tuple[str, ...] = ()
    params: dict[str, float] | None = None
    stderr: dict[str, float] | None = None
    p_values: dict[str, float] | None = None
    at_bound: dict[str, str] | None = None
    high_correlations: tuple[tuple[str, str, float], ...] = ()
    correlation: tuple[tuple[float, ...], ...] = ()
    # the same with the data columns centred that can be (what admissibility judges; () when none can)
    centred_correlation: tuple[tuple[float, ...], ...] = ()
    significance: float = 0.05
    reference_dof: dict[str, float] | None = None  # dof of each p-value's t reference
    n_starts: int = 0
    n_reached_best: int = 0
    aic: float | None = None
    bic: float | None = None
    max_lag: int | None = None
    converged: bool | None = None      # the optimizer's own verdict on the best start
    not_identifiable: dict[str, str] | None = None  # parameter -> why its standard deviation is NaN
    condition_number: float | None = None  # of the column-scaled Jacobian at the solution
    message: str = ""                  # and its words
    nfev: int = 0                      # residual evaluations of the best start
    train: SplitScores | None = None
    validation: SplitScores | None = None
    cv: SplitScores | None = None       # held-out scores of the training maneuvers (cross-validation)
    cv_folds: int = 0
    cv_method: str = "refit"            # how the folds were fitted (runner.CV_METHODS)
    # --- set by the ranking ---
    admissible: bool | None = None
    reasons: tuple[str, ...] = ()       # why it is not admissible
    rank: int | None = None
    within_noise: bool | None = None
    gap: float | None = None            # mean per-maneuver relative held-out MSE excess over the best
    gap_se: float | None = None         # its standard error

    # ----- construction ---------------------------------------------------------------
    @classmethod
    def from_fit(cls, *, name: str, grid: str, coefficient: str, lift: str | None, result: FitResult,
                 train: SplitScores, validation: SplitScores, seconds: float,
                 centred_correlation: np.ndarray | None = None, cv: SplitScores | None = None,
                 cv_folds: int = 0, cv_method: str = "refit") -> "CandidateResult":
        return cls(name=name, grid=grid, coefficient=coefficient, lift=lift, seconds=seconds,
                   names=tuple(result.names), nonlinear_names=tuple(result.nonlinear_names),
                   params=dict(result.params), stderr=dict(result.stderr), p_values=dict(result.p_values),
                   at_bound=dict(result.at_bound),
                   high_correlations=tuple((a, b, float(c)) for a, b, c in result.high_correlations),
                   correlation=tuple(tuple(map(float, row)) for row in np.asarray(result.correlation)),
                   centred_correlation=(() if centred_correlation is None else
                                        tuple(tuple(map(float, row)) for row in centred_correlation)),
                   significance=result.significance, reference_dof=dict(result.reference_dof), n_starts=result.n_starts,
                   n_reached_best=result.n_reached_best, aic=result.aic, bic=result.bic, max_lag=result.max_lag,
                   converged=bool(result.success), message=result.message, nfev=int(result.nfev),
                   not_identifiable=dict(result.not_identifiable),
                   condition_number=float(result.condition_number),
                   train=train, validation=validation, cv=cv, cv_folds=cv_folds, cv_method=cv_method)

    @classmethod
    def failure(cls, *, name: str, grid: str, coefficient: str, lift: str | None, error: str,
                seconds: float) -> "CandidateResult":
        return cls(name=name, grid=grid, coefficient=coefficient, lift=lift, seconds=seconds, error=error)

    def ranked(self, **placing: Any) -> "CandidateResult":
        """A copy with the ranking's fields (``admissible``, ``reasons``, ``rank``, ``within_noise``, ``gap``,
        ``gap_se``) set."""
        return replace(self, **placing)

    # ----- derived ----------------------------------------------------------------------
    @property
    def failed(self) -> bool:
        return self.error is not None

    @property
    def n_params(self) -> int:
        return len(self.names)

    @property
    def identifiable(self) -> bool | None:
        return None if self.failed else not self.not_identifiable

    @property
    def linear_names(self) -> tuple[str, ...]:
        return tuple(n for n in self.names if n not in self.nonlinear_names)

    @property
    def mse_train(self) -> float:
        return self.train.mse

    @property
    def mse_validation(self) -> float:
        return self.validation.mse

    @property
    def mse_cv(self) -> float:
        return self.cv.mse if self.cv is not None else float("nan")

    @property
    def comparison(self) -> SplitScores:
        """The scores candidates are compared on: cross-validation when there is one, else validation."""
        return self.cv if self.cv is not None else self.validation

    @property
    def significant(self) -> dict[str, bool]:
        return {n: p < self.significance for n, p in self.p_values.items()}

    @property
    def insignificant(self) -> tuple[str, ...]:
        """Parameters whose t-test accepts zero."""
        return tuple(n for n, s in self.significant.items() if not s)

    @property
    def correlation_matrix(self) -> np.ndarray:
        return np.asarray(self.correlation, float)

    # ----- JSON (the cache) -------------------------------------------------------------
    def to_json(self) -> dict:
        doc = asdict(self)
        doc["layout"] = JSON_LAYOUT
        for split in ("train", "validation", "cv"):
            s = getattr(self, split)
            doc[split] = s.to_json() if s is not None else None
        doc["high_correlations"] = [list(p) for p in self.high_correlations]
        doc["correlation"] = [list(row) for row in self.correlation]
        doc["centred_correlation"] = [list(row) for row in self.centred_correlation]
        doc["reasons"] = list(self.reasons)
        doc["names"], doc["nonlinear_names"] = list(self.names), list(self.nonlinear_names)
        return json_ready(doc)

    @classmethod
    def from_json(cls, doc: dict) -> "CandidateResult":
        if doc.get("layout") != JSON_LAYOUT:
            raise ValueError(f"candidate result of layout {doc.get('layout')!r}, expected {JSON_LAYOUT}")
        known = {f.name for f in fields(cls)}
        values = {k: v for k, v in doc.items() if k in known}
        for split in ("train", "validation", "cv"):
            if values.get(split) is not None:
                values[split] = SplitScores.from_json(values[split])
        values["names"] = tuple(values.get("names", ()))
        values["nonlinear_names"] = tuple(values.get("nonlinear_names", ()))
        values["high_correlations"] = tuple((a, b, float(c)) for a, b, c in values.get("high_correlations", ()))
        values["correlation"] = tuple(tuple(map(_nan_if_none, row)) for row in values.get("correlation", ()))
        values["centred_correlation"] = tuple(tuple(map(_nan_if_none, row))
                                              for row in values.get("centred_correlation", ()))
        values["reasons"] = tuple(values.get("reasons", ()))
        if values.get("rank") is not None:  # a ranked result has a gap; a NaN one was written as null
            for key in ("gap", "gap_se"):
                if values.get(key) is None:
                    values[key] = float("nan")
        for key in ("params", "stderr", "p_values", "reference_dof"):
            if values.get(key) is not None:
                values[key] = {k: _nan_if_none(v) for k, v in values[key].items()}
        return cls(**values)
