"""Calibration of the profile intervals (issue 30) by Monte Carlo, beside the Wald intervals on the same fits.

On the first ``profile_campaigns`` campaigns of ``bench --calibration`` the final models' truth-start fits with
the default covariance (the fits whose Wald intervals the default covariance's rows calibrate) get profile
intervals at 95 % and 68 % for every nonlinear parameter (:mod:`structsearch.engine.profile`). Only the lift
model CL-VI has nonlinear parameters of its own (drag and pitch read its separation states): six per campaign.
An interval covers the truth when low <= truth <= high; a side open at the box edge covers every truth inside
the box on that side, as it says (the data do not bound the parameter there).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

PROFILE_CAMPAIGNS = 20
PROFILE_LEVELS = (0.95, 0.68)
# per parameter of one campaign: the estimate, and per level (low, high, open_low, open_high, wald_low, wald_high)
Record = Mapping[str, object]


def profile_draw(finals, train) -> tuple[dict, float]:
    """Profile intervals of every nonlinear parameter of the final models ``finals`` ({coefficient: (candidate,
    result)}, drag and pitch on the lift fit) on ``train``: (model -> parameter -> record, seconds)."""
    from ..fitting.lift_fit import LiftFit
    from ..fitting.profile import profile_candidate
    t0 = time.perf_counter()
    lift = LiftFit(*finals["CL"])
    out: dict[str, dict[str, dict]] = {}
    for cand, fit in finals.values():
        profiles = profile_candidate(cand, fit, train, lift if cand.lift else None, levels=PROFILE_LEVELS)
        for p in profiles.parameters:
            record: dict = {"estimate": p.estimate}
            for i in p.intervals:
                record[f"{i.level:g}"] = (i.low, i.high, i.open_low, i.open_high, i.wald_low, i.wald_high)
            out.setdefault(cand.name, {})[p.name] = record
    return out, time.perf_counter() - t0


@dataclass(frozen=True)
class ProfileCalibration:
    """One parameter's profile intervals against its truth over the profiled campaigns, and its Wald intervals on
    the same campaigns."""

    model: str
    parameter: str
    truth: float
    n: int                          # campaigns with a finite profile interval at every level
    coverage95: float
    coverage68: float
    wald_coverage95: float
    wald_coverage68: float
    open95: int                     # 95 % intervals with a side open at the box edge
    open68: int
    misses_low95: int               # truth below the 95 % profile interval
    misses_high95: int
    wald_misses_low95: int
    wald_misses_high95: int
    width_ratio95: float            # median (profile width / Wald width) at 95 %
    asymmetry95: float              # median (high - estimate) / (estimate - low) of the 95 % profile interval

    def to_dict(self) -> dict:
        return {"model": self.model, "parameter": self.parameter, "truth": self.truth, "n": self.n,
                "coverage_95": self.coverage95, "coverage_68": self.coverage68,
                "wald_coverage_95": self.wald_coverage95, "wald_coverage_68": self.wald_coverage68,
                "open_95": self.open95, "open_68": self.open68, "misses_low_95": self.misses_low95,
                "misses_high_95": self.misses_high95, "wald_misses_low_95": self.wald_misses_low95,
                "wald_misses_high_95": self.wald_misses_high95, "median_width_ratio_95": self.width_ratio95,
                "median_asymmetry_95": self.asymmetry95}


def _row(model: str, parameter: str, truth: float, records: Sequence[Mapping]) -> ProfileCalibration:
    def arr(level: str, k: int) -> np.ndarray:
        return np.array([r[level][k] for r in records], float)
    est = np.array([r["estimate"] for r in records], float)
    lo95, hi95, lo68, hi68 = arr("0.95", 0), arr("0.95", 1), arr("0.68", 0), arr("0.68", 1)
    ok = np.isfinite(lo95) & np.isfinite(hi95) & np.isfinite(lo68) & np.isfinite(hi68)
    wlo95, whi95, wlo68, whi68 = arr("0.95", 4), arr("0.95", 5), arr("0.68", 4), arr("0.68", 5)
    open95 = (arr("0.95", 2) > 0) | (arr("0.95", 3) > 0)
    open68 = (arr("0.68", 2) > 0) | (arr("0.68", 3) > 0)

    def share(hit: np.ndarray) -> float:
        return float(np.mean(hit[ok])) if ok.any() else float("nan")
    with np.errstate(divide="ignore", invalid="ignore"):
        width = (hi95 - lo95) / (whi95 - wlo95)
        asym = (hi95 - est) / (est - lo95)
    finite_w, finite_a = ok & np.isfinite(width), ok & np.isfinite(asym)
    return ProfileCalibration(
        model, parameter, float(truth), int(ok.sum()),
        share((lo95 <= truth) & (truth <= hi95)), share((lo68 <= truth) & (truth <= hi68)),
        share((wlo95 <= truth) & (truth <= whi95)), share((wlo68 <= truth) & (truth <= whi68)),
        int(np.sum(open95 & ok)), int(np.sum(open68 & ok)),
        int(np.sum((truth < lo95) & ok)), int(np.sum((truth > hi95) & ok)),
        int(np.sum((truth < wlo95) & ok)), int(np.sum((truth > whi95) & ok)),
        float(np.median(width[finite_w])) if finite_w.any() else float("nan"),
        float(np.median(asym[finite_a])) if finite_a.any() else float("nan"))


def profile_rows(draws, truth: Mapping[str, Mapping[str, float]], names: Mapping[str, str]) -> tuple:
    """Per profiled parameter of the final models (``names``: coefficient -> model name; ``truth``: coefficient ->
    parameter -> true value) its :class:`ProfileCalibration` over the draws that have profiles."""
    profiled = [d for d in draws if d.profiles]
    rows = []
    for coef, name in names.items():
        params = [p for p in truth[coef] if all(p in d.profiles.get(name, {}) for d in profiled)]
        if not profiled:
            break
        for p in params:
            rows.append(_row(name, p, truth[coef][p], [d.profiles[name][p] for d in profiled]))
    return tuple(rows)


def _pooled(rows, attr: str) -> float:
    n = sum(r.n for r in rows)
    return sum(getattr(r, attr) * r.n for r in rows if r.n) / n if n else float("nan")


def profile_dict(cal, truth, names) -> dict | None:
    """``calibration.json``'s ``profile`` (None when no campaign was profiled)."""
    rows = profile_rows(cal.draws, truth, names)
    profiled = [d for d in cal.draws if d.profiles]
    if not profiled:
        return None
    return {"campaigns": len(profiled), "seeds": [d.seed for d in profiled], "levels": list(PROFILE_LEVELS),
            "covariance": cal.default_kind,
            "seconds_per_campaign": float(np.mean([d.profile_seconds for d in profiled])),
            "pooled_coverage_95": _pooled(rows, "coverage95"), "pooled_coverage_68": _pooled(rows, "coverage68"),
            "pooled_wald_coverage_95": _pooled(rows, "wald_coverage95"),
            "pooled_wald_coverage_68": _pooled(rows, "wald_coverage68"),
            "parameters": [r.to_dict() for r in rows]}


def profile_lines(cal, truth, names) -> list[str]:
    """The Markdown section of ``calibration.md`` (nothing when no campaign was profiled)."""
    from tabulate import tabulate
    doc = profile_dict(cal, truth, names)
    if doc is None:
        return []
    rows = profile_rows(cal.draws, truth, names)
    n = doc["campaigns"]

    def f(x: float) -> str:
        return "NaN" if not math.isfinite(x) else f"{x:.2f}"
    body = [[r.model, r.parameter, f"{r.truth:.5g}", r.n, f(r.coverage95), f(r.wald_coverage95), f(r.coverage68),
             f(r.wald_coverage68), f"{r.open95}/{r.open68}", f"{r.misses_low95}/{r.misses_high95}",
             f"{r.wald_misses_low95}/{r.wald_misses_high95}", f(r.width_ratio95), f(r.asymmetry95)] for r in rows]
    seeds = doc["seeds"]
    return ["## Profile intervals of the nonlinear parameters", "",
            f"On the first {n} campaigns (seeds {seeds[0]}-{seeds[-1]}; `--profile-campaigns`) the truth-start fits "
            f"with the default covariance ({doc['covariance']}) get profile intervals for every nonlinear parameter "
            "(only CL-VI has its own: drag and pitch read its separation states): each parameter held on either "
            "side of its estimate, the others refitted, the interval where (S(theta_j) - S_min) / (sigma^2 c_j) "
            "reaches the square of the Wald interval's t quantile, c_j the reported over the white variance "
            "(`structsearch fit --profile`). Beside them the Wald intervals of the same fits on the same "
            "campaigns. An interval open at the box edge counts as covering a truth inside the box on that side. "
            f"Cost: {doc['seconds_per_campaign']:.1f} s per campaign (wall time in the worker that fitted it; "
            f"more on a machine shared with other work). With {n} campaigns a single "
            f"parameter's coverage has a standard error of about {(0.95 * 0.05 / max(n, 1)) ** 0.5:.3f} at 95 %.", "",
            f"Pooled 95 % coverage: profile **{doc['pooled_coverage_95']:.3f}**, Wald "
            f"{doc['pooled_wald_coverage_95']:.3f}; 68 %: profile **{doc['pooled_coverage_68']:.3f}**, Wald "
            f"{doc['pooled_wald_coverage_68']:.3f}.", "",
            tabulate(body, headers=["model", "parameter", "truth", "n", "95 % profile", "95 % Wald", "68 % profile",
                                    "68 % Wald", "open sides 95 %/68 %", "profile misses low/high 95 %",
                                    "Wald misses low/high 95 %", "median width profile / Wald 95 %",
                                    "median (high - est) / (est - low) 95 %"], tablefmt="github"), ""]
