"""The typed result of one candidate of a search: its fit, its scores on both splits, its rank.

The runner caches it as JSON (``to_json``/``from_json``), the ranking orders it, and the
tables, ``fit.json`` and ``ranking.csv`` read it; a failed candidate carries its reason
in ``error`` and no estimates. Its parameters' estimates and statistics are the engine's
:class:`~structsearch.engine.estimates.ParameterEstimates`, the object a ``FitResult`` composes,
covariance included; the statistics are reached under the same names (``params``, ``stderr``,
``p_values``, ``cov_params()``, ``wald_test()``, ...).
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ..data.atomic import json_ready
from ..engine.estimates import ParameterEstimates, WaldTest
from ..engine.results import FitResult
from ..engine.scores import ManeuverScores, R2Summary

if TYPE_CHECKING:
    import pandas

    from ..engine.summary import FitSummary

# Version of the JSON layout below; part of the cache key, so a cache of another layout is refitted.
# 7: the parameters' estimates and covariance as one object (ParameterEstimates.to_dict)
JSON_LAYOUT = 7


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
                   R2Summary(_nan_if_none(r2["mean"]), _nan_if_none(r2["min"]), _nan_if_none(r2["max"]),
                             _nan_if_none(r2.get("pooled"))),
                   doc.get("mse_cx"), doc.get("mse_cz"))


def _delegate(name: str, failed: Any = None, convert=None):
    def get(self):
        if self.estimates is None:
            return failed
        value = getattr(self.estimates, name)
        return convert(value) if convert is not None else value
    get.__name__ = name
    get.__doc__ = f"``estimates.{name}`` ({failed!r} for a failed candidate)."
    return property(get)


def _rows(matrix) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(map(float, row)) for row in np.asarray(matrix, float))


@dataclass(frozen=True)
class CandidateResult:
    """One candidate of a grid after fitting (or failing) and, once ranked, its place.

    Parameter tables read ``names``, ``nonlinear_names``, ``params``, ``stderr``,
    ``p_values``, ``significant``, ``at_bound``, ``high_correlations`` and
    ``correlation`` as they read a :class:`~structsearch.engine.results.FitResult`: both
    delegate to the same :class:`~structsearch.engine.estimates.ParameterEstimates`.
    """

    name: str
    grid: str
    coefficient: str
    lift: str | None
    seconds: float
    error: str | None = None
    # --- the fit (None when it failed) ---
    estimates: ParameterEstimates | None = None
    # the correlation with the data columns centred that can be (what admissibility judges; () when none can)
    centred_correlation: tuple[tuple[float, ...], ...] | np.ndarray = ()
    n_starts: int = 0
    n_reached_best: int = 0
    aic: float | None = None
    bic: float | None = None
    converged: bool | None = None      # the optimizer's own verdict on the best start
    message: str = ""                  # and its words
    nfev: int = 0                      # residual evaluations of the best start
    train: SplitScores | None = None
    validation: SplitScores | None = None
    cv: SplitScores | None = None       # held-out scores of the training maneuvers (cross-validation)
    cv_folds: int = 0
    cv_method: str = "refit"            # how the folds were fitted (runner.CV_METHODS)
    cv_scheme: str = ""                 # how they were formed: .folds.SCHEMES ("": a result that does not say)
    cv_note: str = ""                   # in words, or why there is no cross-validation (cv None)
    # --- set by the ranking ---
    admissible: bool | None = None
    reasons: tuple[str, ...] = ()       # why it is not admissible
    rank: int | None = None
    within_noise: bool | None = None
    gap: float | None = None            # mean per-maneuver relative held-out MSE excess over the best
    gap_se: float | None = None         # its standard error

    def __post_init__(self):
        rows = _rows(self.centred_correlation) if len(self.centred_correlation) else ()
        object.__setattr__(self, "centred_correlation", rows)
        object.__setattr__(self, "reasons", tuple(self.reasons))

    # ----- construction ---------------------------------------------------------------
    @classmethod
    def from_fit(cls, *, name: str, grid: str, coefficient: str, lift: str | None, result: FitResult,
                 train: SplitScores, validation: SplitScores, seconds: float,
                 centred_correlation: np.ndarray | None = None, cv: SplitScores | None = None,
                 cv_folds: int = 0, cv_method: str = "refit", cv_scheme: str = "",
                 cv_note: str = "") -> "CandidateResult":
        return cls(name=name, grid=grid, coefficient=coefficient, lift=lift, seconds=seconds,
                   estimates=result.estimates,
                   centred_correlation=() if centred_correlation is None else centred_correlation,
                   n_starts=result.n_starts, n_reached_best=result.n_reached_best, aic=result.aic, bic=result.bic,
                   converged=bool(result.converged), message=result.message, nfev=int(result.nfev),
                   train=train, validation=validation, cv=cv, cv_folds=cv_folds, cv_method=cv_method,
                   cv_scheme=cv_scheme, cv_note=cv_note)

    @classmethod
    def failure(cls, *, name: str, grid: str, coefficient: str, lift: str | None, error: str,
                seconds: float) -> "CandidateResult":
        return cls(name=name, grid=grid, coefficient=coefficient, lift=lift, seconds=seconds, error=error)

    def ranked(self, **placing: Any) -> "CandidateResult":
        """A copy with the ranking's fields (``admissible``, ``reasons``, ``rank``, ``within_noise``, ``gap``,
        ``gap_se``) set."""
        return replace(self, **placing)

    # ----- the estimates --------------------------------------------------------------
    names = _delegate("names", ())
    nonlinear_names = _delegate("nonlinear_names", ())
    linear_names = _delegate("linear_names", ())
    params = _delegate("params")
    stderr = _delegate("stderr")
    p_values = _delegate("p_values")
    t_values = _delegate("t_values")
    at_bound = _delegate("at_bound")
    reference_dof = _delegate("reference_dof")
    units = _delegate("units", {})
    not_identifiable = _delegate("not_identifiable")
    significant = _delegate("significant")
    significance = _delegate("significance", 0.05)
    max_lag = _delegate("max_lag")
    condition_number = _delegate("condition_number")
    covariance_kind = _delegate("covariance_kind")
    high_correlations = _delegate("high_correlations", (), lambda pairs: tuple((a, b, float(c)) for a, b, c in pairs))
    correlation = _delegate("correlation", (), _rows)

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
    def insignificant(self) -> tuple[str, ...]:
        """Parameters whose t-test accepts zero."""
        return tuple(n for n, s in self.significant.items() if not s)

    @property
    def correlation_matrix(self) -> np.ndarray:
        return np.asarray(self.correlation, float)

    def _fitted(self) -> ParameterEstimates:
        if self.estimates is None:
            raise ValueError(f"candidate {self.name} has no estimates: {self.error or 'not fitted'}")
        return self.estimates

    def cov_params(self) -> "pandas.DataFrame":
        return self._fitted().cov_params()

    def conf_int(self, level: float = 0.95) -> "pandas.DataFrame":
        return self._fitted().conf_int(level)

    def wald_test(self, names: Sequence[str]) -> WaldTest:
        return self._fitted().wald_test(names)

    def summary(self) -> "FitSummary":
        """Scores, optimizer and parameters with tests and flags (text, Markdown, HTML, LaTeX)."""
        from ..engine.summary import FitSummary, covariance_head, covariance_line
        e = self._fitted()
        head = [("model", self.name), ("coefficient", self.coefficient), ("lift model", self.lift or "-"),
                ("parameters (nonlinear + linear)", f"{len(e.nonlinear_names)} + {len(e.linear_names)}")]
        for label, split in (("train", self.train), ("cross-validation", self.cv), ("validation", self.validation)):
            if split is not None:
                head.append((f"MSE {label}", f"{split.mse:.6g}"))
        if self.cv_note:
            head.append(("cross-validation folds", self.cv_note))
        if self.validation is not None:
            r2 = self.validation.r2
            head.append(("R^2 validation per maneuver mean / min / max",
                         f"{r2.mean:.4f} / {r2.min:.4f} / {r2.max:.4f}"))
        head += [("covariance", covariance_line(e.covariance_kind, e.max_lag, e.bandwidth)),
                 ("optimizer", f"{'converged' if self.converged else 'NOT CONVERGED'}: {self.message} "
                               f"({self.nfev} evaluations)"),
                 ("starts reaching the best cost", f"{self.n_reached_best} of {self.n_starts}"),
                 *covariance_head(e)]
        if self.rank is not None:
            head.append(("rank", f"{self.rank}" + ("" if self.admissible else " (not admissible)")))
        return FitSummary(e, tuple(head))

    # ----- scores ------------------------------------------------------------------------
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

    # ----- JSON (the cache) -------------------------------------------------------------
    def to_json(self) -> dict:
        doc = {f.name: getattr(self, f.name) for f in fields(self)}
        doc["layout"] = JSON_LAYOUT
        doc["estimates"] = None if self.estimates is None else self.estimates.to_dict()
        for split in ("train", "validation", "cv"):
            s = getattr(self, split)
            doc[split] = s.to_json() if s is not None else None
        doc["centred_correlation"] = [list(row) for row in self.centred_correlation]
        doc["reasons"] = list(self.reasons)
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
        if values.get("estimates") is not None:
            values["estimates"] = ParameterEstimates.from_dict(values["estimates"])
        values["centred_correlation"] = tuple(tuple(map(_nan_if_none, row))
                                              for row in values.get("centred_correlation", ()))
        values["reasons"] = tuple(values.get("reasons", ()))
        if values.get("rank") is not None:  # a ranked result has a gap; a NaN one was written as null
            for key in ("gap", "gap_se"):
                if values.get(key) is None:
                    values[key] = float("nan")
        return cls(**values)
