"""Per-maneuver fit scores, computed one way for fits, searches, rankings and diagnoses.

A campaign's maneuvers differ in length and difficulty by orders of magnitude (a deep
stall against a pullup), so scores are kept per maneuver and pooled explicitly: the
pooled MSE weights each maneuver by its samples, and a mean over maneuvers comes with
the standard error that the spread between maneuvers implies.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np


@dataclass(frozen=True)
class R2Summary:
    """Mean, smallest and largest R^2 over maneuvers (NaN when no maneuver has one) and the pooled R^2 of the
    whole split, 1 - SSE / SST with SST about the split's mean (what a table of one R^2 per data set, such as
    the thesis' Table 11.1, reports: the differences between maneuvers count as signal there)."""

    mean: float
    min: float
    max: float
    pooled: float = float("nan")

    def as_dict(self) -> dict[str, float]:
        return {"mean": self.mean, "min": self.min, "max": self.max, "pooled": self.pooled}


@dataclass(frozen=True, eq=False)
class ManeuverScores:
    """Samples, residual sum of squares and total sum of squares (about the maneuver mean) per maneuver."""

    counts: np.ndarray
    sse: np.ndarray
    sst: np.ndarray
    total_sst: float = float("nan")   # about the mean of all the maneuvers' samples

    @classmethod
    def of(cls, observed: np.ndarray, residual: np.ndarray, slices: Sequence[slice]) -> "ManeuverScores":
        counts = sizes_of(slices)
        sst = np.array([float(np.sum((observed[sl] - observed[sl].mean()) ** 2)) for sl in slices])
        everything = np.concatenate([np.asarray(observed[sl], float) for sl in slices]) if slices else np.zeros(0)
        total = float(np.sum((everything - everything.mean()) ** 2)) if everything.size else float("nan")
        return cls(counts, maneuver_sse(residual, slices), sst, total)

    @property
    def mse(self) -> np.ndarray:
        """MSE of each maneuver."""
        return self.sse / self.counts

    @property
    def pooled_mse(self) -> float:
        """MSE over all samples (maneuvers weighted by their samples)."""
        return float(self.sse.sum() / self.counts.sum())

    @property
    def r2(self) -> np.ndarray:
        """R^2 of each maneuver about its own mean; NaN for a maneuver whose signal is constant."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.sst > 0, 1.0 - self.sse / np.where(self.sst > 0, self.sst, 1.0), np.nan)

    def r2_summary(self) -> R2Summary:
        r = self.r2[np.isfinite(self.r2)]
        pooled = 1.0 - float(self.sse.sum()) / self.total_sst if self.total_sst > 0 else float("nan")
        if r.size == 0:
            return R2Summary(float("nan"), float("nan"), float("nan"), pooled)
        return R2Summary(float(r.mean()), float(r.min()), float(r.max()), pooled)


def maneuver_sse(residual: np.ndarray, slices: Sequence[slice]) -> np.ndarray:
    """Residual sum of squares of each maneuver."""
    return np.array([float(residual[sl] @ residual[sl]) for sl in slices])


def maneuver_mse(residual: np.ndarray, slices: Sequence[slice]) -> np.ndarray:
    """MSE of each maneuver (when only the residual is at hand)."""
    return maneuver_sse(residual, slices) / sizes_of(slices)


def sizes_of(slices: Sequence[slice]) -> np.ndarray:
    """Samples in each maneuver."""
    return np.array([sl.stop - sl.start for sl in slices], dtype=int)


def slices_of(bounds: np.ndarray) -> list[slice]:
    """Maneuver slices from the boundary indices [start_0, start_1, ..., n]."""
    return [slice(int(bounds[i]), int(bounds[i + 1])) for i in range(len(bounds) - 1)]


def weighted_mean_se(values: np.ndarray, weights: np.ndarray) -> tuple[float, float]:
    """Weighted mean of per-maneuver values and its standard error from their spread.

    The standard error is NaN with fewer than two maneuvers: one maneuver says nothing
    about the spread between maneuvers.
    """
    values = np.asarray(values, float)
    w = np.asarray(weights, float)
    w = w / w.sum()
    mean = float(np.sum(w * values))
    if len(values) < 2:
        return mean, float("nan")
    return mean, float(np.sqrt(np.sum(w * (values - mean) ** 2) / (len(values) - 1)))
