"""Model sets compared coefficient by coefficient (thesis Tables 17 and 11.1, Fig. 12): pooled MSE and the
per-maneuver R^2 of C_L, C_D, C_X, C_Z and C_m on the training and the validation maneuvers.

C_X and C_Z come from a set's C_L and C_D through the stability-axis rotation at the measured alpha, against
the campaign's measured C_X, C_Z (or the same rotation of the measured C_L, C_D when it has none).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..data.coefficients import LONGITUDINAL as MODELLED
from ..data.campaign import Campaign
from ..data.flightdata import FlightData
from ..data.reduction import body_from_lift_drag

COMPARED = ("CL", "CD", "CX", "CZ", "Cm")   # the modelled coefficients and the body-axis ones they give
SPLITS = ("train", "validation")


@dataclass(frozen=True)
class CoefficientScores:
    """One model set's fit of one coefficient on one split."""

    model: str
    coefficient: str
    split: str
    mse: float
    r2: tuple[float, ...]           # per maneuver, in campaign order
    maneuvers: tuple[str, ...]

    @property
    def r2_mean(self) -> float:
        return float(np.nanmean(self.r2))

    @property
    def r2_min(self) -> float:
        return float(np.nanmin(self.r2))

    @property
    def r2_max(self) -> float:
        return float(np.nanmax(self.r2))

    def to_dict(self) -> dict:
        return {"model": self.model, "coefficient": self.coefficient, "split": self.split, "mse": self.mse,
                "r2": list(self.r2), "maneuvers": list(self.maneuvers), "r2_mean": self.r2_mean,
                "r2_min": self.r2_min, "r2_max": self.r2_max}


def measured(data: FlightData, coefficient: str) -> np.ndarray:
    if coefficient in ("CX", "CZ") and coefficient not in data:
        cx, cz = body_from_lift_drag(data["CL"], data["CD"], data["alpha"])
        return cx if coefficient == "CX" else cz
    return data[coefficient]


def per_maneuver_r2(y: np.ndarray, predicted: np.ndarray, data: FlightData) -> tuple[float, ...]:
    """1 - SSE/SST of each maneuver (NaN for a maneuver whose coefficient does not vary)."""
    out = []
    for sl in data.segment_slices():
        sst = np.sum((y[sl] - y[sl].mean()) ** 2)
        out.append(float(1.0 - np.sum((y[sl] - predicted[sl]) ** 2) / sst) if sst > 0 else float("nan"))
    return tuple(out)


def score_set(label: str, predict: Callable[[str, FlightData], np.ndarray | None], campaign: Campaign
              ) -> list[CoefficientScores]:
    """Scores of a model set given by ``predict(coefficient, data)`` (C_L, C_D or C_m; None where the set has no
    model of that coefficient, e.g. Van Ingen's published lift alone: then C_X, C_Z are not scored either)."""
    out = []
    for split in SPLITS:
        data = campaign.split(split)
        predicted: dict[str, np.ndarray | None] = {c: predict(c, data) for c in MODELLED}
        if predicted["CL"] is not None and predicted["CD"] is not None:
            predicted["CX"], predicted["CZ"] = body_from_lift_drag(predicted["CL"], predicted["CD"], data["alpha"])
        for coefficient in COMPARED:
            p = predicted.get(coefficient)
            if p is None:
                continue
            y = measured(data, coefficient)
            out.append(CoefficientScores(label, coefficient, split, float(np.mean((y - p) ** 2)),
                                         per_maneuver_r2(y, p, data), tuple(data.names)))
    return out


def percent_difference(new: float, old: float) -> float:
    """(new - old) / old in per cent (the thesis' "% difference" to Van Ingen)."""
    return 100.0 * (new - old) / old if old else float("nan")


def comparison_rows(scores: list[CoefficientScores], model: str, reference: str) -> list[dict]:
    """Per coefficient and split: both models' MSE and R^2 mean/min/max and the MSE's % difference."""
    index = {(s.model, s.coefficient, s.split): s for s in scores}
    rows = []
    for coefficient in COMPARED:
        for split in SPLITS:
            a, b = index.get((model, coefficient, split)), index.get((reference, coefficient, split))
            if a is None or b is None:
                continue
            rows.append({"coefficient": coefficient, "split": split, "mse": a.mse, "reference_mse": b.mse,
                         "difference_pct": percent_difference(a.mse, b.mse), "r2_mean": a.r2_mean,
                         "r2_min": a.r2_min, "r2_max": a.r2_max, "reference_r2_mean": b.r2_mean,
                         "reference_r2_min": b.r2_min, "reference_r2_max": b.r2_max})
    return rows

