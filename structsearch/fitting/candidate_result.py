"""The typed result of one candidate of a search: its fit, its scores on both splits, its rank.

The runner caches it as JSON (``to_json``/``from_json``), the ranking orders it, and the
tables, ``fit.json`` and ``ranking.csv`` read it; a failed candidate carries its reason
in ``error`` and no estimates. Its parameters' estimates and statistics are one value, the engine's
:class:`~structsearch.engine.estimates.ParameterEstimates` (``result.estimates``, covariance included); the
methods a fit result has (``summary()``, ``cov_params()``, ``conf_int()``, ``wald_test()``) are its own.
"""
from __future__ import annotations

import enum

from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ..data.atomic import json_ready
from ..engine.equations import Equations
from ..engine.estimates import ParameterEstimates, WaldTest
from ..engine.results import FitResult, starts_line
from ..engine.scores import ManeuverScores, R2Summary
from .flight_effects import FlightEffects

if TYPE_CHECKING:
    import pandas

    from ..engine.summary import FitSummary

# Version of the JSON layout below; part of the cache key, so a cache of another layout is refitted.
# 7: the parameters' estimates and covariance as one object (ParameterEstimates.to_dict); 8: the ranking's
# fields as one placement; 9: the optimizer's account as one report; 10: a fit that did not converge withholds
# its statistics (``ParameterEstimates.withheld``); 12: the flight effects and the fit's warnings; 13: scores per
# unit smaller than a maneuver on splits of few maneuvers; 14: a failure's kind
JSON_LAYOUT = 14


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
    # on a split of few maneuvers, the MSE and samples per unit smaller than a maneuver and what the units are
    # (fitting.folds.score_units: "cycles", "blocks"); empty otherwise
    mse_units: tuple[float, ...] = ()
    n_units: tuple[int, ...] = ()
    units: str = ""

    @classmethod
    def of(cls, scores: ManeuverScores, derived: tuple[float, float] | None,
           units: tuple[ManeuverScores, str] | None = None) -> "SplitScores":
        cx, cz = derived if derived else (None, None)
        per_unit = {} if units is None else {"mse_units": tuple(map(float, units[0].mse)),
                                             "n_units": tuple(map(int, units[0].counts)), "units": units[1]}
        return cls(scores.pooled_mse, tuple(map(float, scores.mse)), tuple(map(int, scores.counts)),
                   scores.r2_summary(), cx, cz, **per_unit)

    def to_json(self) -> dict:
        units = {"mse_units": list(self.mse_units), "n_units": list(self.n_units), "units": self.units} \
            if self.units else {}
        return {"mse": self.mse, "mse_maneuvers": list(self.mse_maneuvers), "n_maneuvers": list(self.n_maneuvers),
                "r2": self.r2.as_dict(),
                "mse_cx": self.mse_cx, "mse_cz": self.mse_cz, **units}

    @classmethod
    def from_json(cls, doc: dict) -> "SplitScores":
        r2 = doc["r2"]
        return cls(_nan_if_none(doc["mse"]), tuple(map(_nan_if_none, doc["mse_maneuvers"])), tuple(map(int, doc["n_maneuvers"])),
                   R2Summary(_nan_if_none(r2["mean"]), _nan_if_none(r2["min"]), _nan_if_none(r2["max"]),
                             _nan_if_none(r2.get("pooled"))),
                   doc.get("mse_cx"), doc.get("mse_cz"), tuple(map(_nan_if_none, doc.get("mse_units", ()))),
                   tuple(map(int, doc.get("n_units", ()))), str(doc.get("units", "")))


NOT_APPLICABLE = "not applicable: "


class FailureKind(enum.Enum):
    """Why a candidate has no fit, as a kind (never read from its message): whether the cache keeps it."""

    NOT_APPLICABLE = "not applicable"   # the campaign cannot fit it by its nature (a column it lacks)
    DATA = "data"                       # the data or the declaration make it fail (a DataError, a singular matrix)
    RETRIED = "retried"                 # any other failure: it may be a programming error, so it is fitted again

    @property
    def cached(self) -> bool:
        """Whether the failure follows from the question (kept in the cache) rather than maybe from the code."""
        return self is not FailureKind.RETRIED


@dataclass(frozen=True)
class OptimizerReport:
    """How the optimizer reached a candidate's estimates: its own verdict on the best start, its words, the
    residual evaluations of the best start, and how many starts reached the best cost."""

    converged: bool | None = None
    message: str = ""
    nfev: int = 0
    n_starts: int = 0
    n_reached_best: int = 0
    n_starts_asked: int | None = None   # the rest of n_starts are warm starts (engine.results.starts_line)

    def to_json(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class Placement:
    """A candidate's place in its grid's ranking (:func:`structsearch.grid_search.ranking.rank`)."""

    admissible: bool | None = None
    reasons: tuple[str, ...] = ()       # why it is not admissible
    rank: int | None = None             # None: failed, not ranked
    within_noise: bool | None = None
    gap: float | None = None            # mean per-maneuver relative held-out MSE excess over the best
    gap_se: float | None = None         # its standard error
    origin: str = "declared"            # declared in a grid, reached by refinement ("refined") or "discovered"

    def __post_init__(self):
        object.__setattr__(self, "reasons", tuple(self.reasons))

    def to_json(self) -> dict:
        return {f.name: (list(getattr(self, f.name)) if f.name == "reasons" else getattr(self, f.name))
                for f in fields(self)}

    @classmethod
    def from_json(cls, doc: dict) -> "Placement":
        values = dict(doc)
        if values.get("rank") is not None:  # a ranked result has a gap; a NaN one was written as null
            for key in ("gap", "gap_se"):
                if values.get(key) is None:
                    values[key] = float("nan")
        return cls(**values)


def _rows(matrix) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(map(float, row)) for row in np.asarray(matrix, float))


@dataclass(frozen=True)
class CandidateResult:
    """One candidate of a grid after fitting (or failing) and, once ranked, its place.

    Its parameters' statistics are one value, ``estimates`` (a
    :class:`~structsearch.engine.estimates.ParameterEstimates`; None when the fit failed), read as
    ``result.estimates.params``, ``result.estimates.stderr``, ...; the ranking's verdict is another,
    ``placement``.
    """

    name: str
    grid: str
    coefficient: str
    lift: str | None
    seconds: float
    error: str | None = None
    failure_kind: FailureKind | None = None  # the error's kind (None: it did not fail)
    # --- the fit (None when it failed) ---
    estimates: ParameterEstimates | None = None
    # the correlation with the data columns centred that can be (what admissibility judges; () when none can)
    centred_correlation: tuple[tuple[float, ...], ...] | np.ndarray = ()
    aic: float | None = None
    bic: float | None = None
    optimizer: OptimizerReport = OptimizerReport()   # how the optimizer got there (nothing: it failed)
    train: SplitScores | None = None
    validation: SplitScores | None = None
    cv: SplitScores | None = None       # held-out scores of the training maneuvers (cross-validation)
    cv_folds: int = 0
    cv_method: str = "refit"            # how the folds were fitted (runner.CV_METHODS)
    cv_scheme: str = ""                 # how they were formed: .folds.SCHEMES ("": a result that does not say)
    cv_note: str = ""                   # in words, or why there is no cross-validation (cv None)
    placement: Placement | None = None  # its place in a ranking (None: not ranked)
    equations: Equations | None = None  # the structure as equations (what summary() opens with)
    # per-flight offsets estimated with it, apart from its parameters (.flight_effects; None: none asked for)
    flight_effects: FlightEffects | None = None
    warnings: tuple[str, ...] = ()      # what the fit should have had (flight effects on a campaign with flights)

    def __post_init__(self):
        rows = _rows(self.centred_correlation) if len(self.centred_correlation) else ()
        object.__setattr__(self, "centred_correlation", rows)
        if self.error is None and self.failure_kind is not None:
            raise ValueError(f"{self.name}: a failure's kind ({self.failure_kind.value}) without its error")
        if self.error is not None and self.failure_kind is None:   # a failure nobody classified is not cached
            object.__setattr__(self, "failure_kind", FailureKind.RETRIED)

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
                   optimizer=OptimizerReport(bool(result.converged), result.message, int(result.nfev),
                                             result.n_starts, result.n_reached_best, result.n_starts_asked),
                   aic=result.aic, bic=result.bic,
                   train=train, validation=validation, cv=cv, cv_folds=cv_folds, cv_method=cv_method,
                   cv_scheme=cv_scheme, cv_note=cv_note, equations=result.equations)

    @classmethod
    def failure(cls, *, name: str, grid: str, coefficient: str, lift: str | None, error: str,
                    seconds: float, kind: FailureKind = FailureKind.RETRIED) -> "CandidateResult":
        """A candidate without a fit: ``error`` in words, ``kind`` whether it follows from the question."""
        return cls(name=name, grid=grid, coefficient=coefficient, lift=lift, seconds=seconds, error=error,
                   failure_kind=kind)

    def placed(self, **changes: Any) -> "CandidateResult":
        """A copy whose :class:`Placement` has ``changes`` (``admissible``, ``reasons``, ``rank``,
        ``within_noise``, ``gap``, ``gap_se``, ``origin``)."""
        return replace(self, placement=replace(self.placement or Placement(), **changes))

    # ----- what the estimates say of the fit (its statistics: ``estimates``) ------------------------------
    @property
    def failed(self) -> bool:
        return self.error is not None

    @property
    def not_applicable(self) -> bool:
        """A candidate the campaign cannot fit by its nature (a column or the fixed reference point it lacks), not
        one whose fit went wrong: skipped, with ``error`` saying why."""
        return self.failure_kind is FailureKind.NOT_APPLICABLE

    @property
    def n_params(self) -> int:
        """How many parameters it estimated (0: it failed)."""
        return 0 if self.estimates is None else self.estimates.n_params

    @property
    def identifiable(self) -> bool | None:
        """Whether the data identify every parameter (None: it failed)."""
        return None if self.estimates is None else not self.estimates.not_identifiable

    @property
    def insignificant(self) -> tuple[str, ...]:
        """Parameters whose t-test accepts zero (none: it failed)."""
        return () if self.estimates is None else tuple(n for n, s in self.estimates.significant.items() if not s)

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
        e, o = self._fitted(), self.optimizer
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
                 ("optimizer", f"{'converged' if o.converged else 'NOT CONVERGED'}: {o.message} "
                               f"({o.nfev} evaluations)"),
                 ("starts reaching the best cost", starts_line(o.n_reached_best, o.n_starts, o.n_starts_asked)),
                 *covariance_head(e)]
        if self.flight_effects is not None:
            f = self.flight_effects
            head.append(("flight effects", f"{', '.join(o.effect for o in f.effects) or 'none applies'} over "
                                           f"{len(f.flights)} flights, {f.coding} (offsets apart: .flight_effects)"))
        p = self.placement
        if p is not None and p.rank is not None:
            head.append(("rank", f"{p.rank}" + ("" if p.admissible else " (not admissible)")))
        return FitSummary(e, tuple(head), self.equations)

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
        doc["placement"] = None if self.placement is None else self.placement.to_json()
        doc["optimizer"] = self.optimizer.to_json()
        doc["equations"] = None if self.equations is None else {"text": list(self.equations.text),
                                                                 "latex": list(self.equations.latex)}
        doc["flight_effects"] = None if self.flight_effects is None else self.flight_effects.to_dict()
        doc["warnings"] = list(self.warnings)
        doc["failure_kind"] = None if self.failure_kind is None else self.failure_kind.value
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
        values["optimizer"] = OptimizerReport(**values.get("optimizer", {}))
        if values.get("placement") is not None:
            values["placement"] = Placement.from_json(values["placement"])
        if values.get("equations") is not None:
            values["equations"] = Equations(tuple(values["equations"]["text"]), tuple(values["equations"]["latex"]))
        if values.get("flight_effects") is not None:
            values["flight_effects"] = FlightEffects.from_dict(values["flight_effects"])
        values["warnings"] = tuple(values.get("warnings", ()))
        values["failure_kind"] = None if values.get("failure_kind") is None else FailureKind(values["failure_kind"])
        return cls(**values)
