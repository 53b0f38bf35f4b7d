"""What the campaign report plots, as plain arrays (no matplotlib, no files).

A :class:`ModelSet` is one simulator: a lift, a drag and a pitch structure fitted
on the training maneuvers (fitted by the study layer, :mod:`structsearch.thesis_study.model_set`;
this module fits nothing). From it come the static
curves of the thesis' figures 6-11 (separation states at equilibrium, q = 0,
delta_e = 0, C_T = 0, mean centre of gravity and airspeed), the measured points
corrected for everything the static curve leaves out (partial residuals: static
model at the sample's alpha plus the sample's residual), time traces, a
hysteresis loop, and the gap breakdown of a diagnosis.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..data.campaign import Campaign
from ..data.flightdata import FlightData
from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
from ..engine.scores import ManeuverScores

from ..data.coefficients import LONGITUDINAL
from ..thesis_study.model_set import ModelSet

# Stall stages on the static separation curve (thesis Fig. 6)
STAGES = (("flow starts to separate", 0.9), ("half separated (alpha*)", 0.5), ("fully stalled", 0.1))
ALPHA_BAND = 0.04  # rad, as in the diagnosis


@dataclass(frozen=True)
class Reference:
    """The flight condition of the static curves."""

    V: float
    x_cg: float | None                # None: the campaign has no x_cg column
    constants: Mapping[str, float]


def reference(data: FlightData) -> Reference:
    return Reference(float(np.mean(data["V"])), float(np.mean(data["x_cg"])) if "x_cg" in data else None,
                     dict(data.constants))


def static_values(ms: ModelSet, alpha: np.ndarray, ref: Reference) -> dict[str, np.ndarray]:
    """Inputs of the aerodynamic model in the static condition at each alpha."""
    alpha = np.asarray(alpha, float)
    zero = np.zeros_like(alpha)
    values = {"alpha": alpha, "alpha_dot": zero, "q": zero, "de": zero, "CT": zero,
              "V": np.full_like(alpha, ref.V)}
    if ref.x_cg is not None:
        values["x_cg"] = np.full_like(alpha, ref.x_cg)
    values.update({k: np.full_like(alpha, v) for k, v in ref.constants.items()})
    values.update(ms.aero.separation_targets(alpha, zero))
    return values


def static_coefficients(ms: ModelSet, alpha: np.ndarray, ref: Reference) -> dict[str, np.ndarray]:
    values = ms.aero.coefficients(static_values(ms, alpha, ref))
    # a coefficient without alpha-dependent terms comes back as a scalar
    return {coef: np.broadcast_to(v, np.shape(alpha)).astype(float) for coef, v in zip(LONGITUDINAL, values)}


def separation_curves(ms: ModelSet, alpha: np.ndarray) -> dict[str, dict]:
    """X_0(alpha) of every state and the alpha of each stall stage."""
    out = {}
    for s in ms.aero.states:
        x0 = s.static(alpha)
        if s.form == "tanh":
            # X_0 = 1/2 - 1/2 tanh(a1 (alpha - a*)) inverted at each stage's level
            stages = {label: float(s.a_star + np.arctanh(1 - 2 * level) / s.a1) for label, level in STAGES}
        else:   # another form (non-increasing) inverted on a fine grid; NaN for a level it never reaches
            fine = np.linspace(-0.5, 1.5, 20001)
            curve = s.static(fine)
            stages = {label: float(fine[np.argmax(curve <= level)]) if np.any(curve <= level) else float("nan")
                      for label, level in STAGES}
        a_star = s.a_star if np.isfinite(s.a_star) else stages["half separated (alpha*)"]
        out[s.symbol] = {"x0": x0, "a1": s.a1, "a_star": a_star, "kind": s.kind, "stages": stages,
                         "form": s.form}
    return out


def partial_points(ms: ModelSet, data: FlightData, ref: Reference, max_points: int = 5000,
                   seed: int = 0) -> dict[str, np.ndarray]:
    """Measured coefficients corrected to the static condition, on a seeded subsample."""
    rng = np.random.default_rng(seed)
    idx = np.sort(rng.choice(data.n_samples, size=min(max_points, data.n_samples), replace=False))
    alpha = data["alpha"][idx]
    static = static_coefficients(ms, alpha, ref)
    out = {"alpha": alpha}
    for coef in LONGITUDINAL:
        residual = data[coef][idx] - ms.predict(coef, data)[idx]
        out[coef] = static[coef] + residual
    return out


def derived_pitch(ms: ModelSet, alpha: np.ndarray, ref: Reference) -> dict[str, np.ndarray]:
    """Centre-of-pressure arm l_cp = -dC_m/dC_L and elevator effectiveness dC_m/d delta_e (Eqs. 31-33).

    Both are partial derivatives of the fitted pitch model in the static condition, so they
    follow whatever structure won the search. ``x_cp`` is measured from the campaign's x_cg datum.
    """
    values = static_values(ms, alpha, ref)
    values["CL"] = static_coefficients(ms, alpha, ref)["CL"]
    l_cp = -ms.aero.partial("Cm", "CL", values)
    cbar = ref.constants.get("cbar", 1.0)
    return {"l_cp": l_cp, "x_cp": (ref.x_cg + l_cp * cbar) if ref.x_cg is not None else None, "Cm_de": ms.aero.partial("Cm", "de", values),
            "depends_on_CL": bool(np.any(l_cp != 0))}


# thesis Table 11.1, validation data, this work: pooled R^2 and the smallest maneuver's
THESIS_R2_VALIDATION = {"CL": (0.91, 0.81), "CD": (0.86, 0.75), "Cm": (0.71, 0.18)}


def r2_sentence(ms: ModelSet, data: FlightData) -> str:
    """Each coefficient's validation R^2, pooled (one per data set, as Table 11.1 reports it) and per maneuver, and
    why the per-maneuver R^2 of C_m is low: within one maneuver C_m varies little against the error the model
    cannot follow (the validation MSE), so R^2 = 1 - MSE / variance drops where the variance is small."""
    parts, worst = [], None
    for coef in LONGITUDINAL:
        pred = ms.predict(coef, data)
        scores = ManeuverScores.of(data[coef], data[coef] - pred, data.segment_slices())
        r2 = scores.r2_summary()
        thesis = THESIS_R2_VALIDATION.get(coef)
        parts.append(f"{coef} {r2.pooled:.2f} pooled, per maneuver mean {r2.mean:.2f} and min {r2.min:.2f}"
                     + (f" (thesis Table 11.1: {thesis[0]:.2f}, min {thesis[1]:.2f})" if thesis else ""))
        if coef == "Cm" and np.isfinite(scores.r2).any():
            i = int(np.nanargmin(scores.r2))
            worst = (data.names[i], scores.sst[i] / scores.counts[i], scores.mse[i], scores.r2[i])
    text = "Validation R^2: " + "; ".join(parts) + "."
    if worst is not None:
        name, var, mse, r2 = worst
        text += (" What limits the pitch fit within a maneuver: where a maneuver's own C_m varies little, the error "
                 "no structure follows (the slow reconstruction error of C_m) is a large share of that variation: "
                 f"the worst maneuver, {name}, varies by {var:.3g} (variance about its mean) against an MSE of "
                 f"{mse:.3g} (R^2 {r2:.2f}). Across maneuvers C_m varies far more, which the pooled R^2 counts.")
    return text


def trace_selection(ms: ModelSet, data: FlightData, train: FlightData | None = None) -> dict[str, list[dict]]:
    """Per coefficient, the best, median and worst maneuver of ``data`` by R^2, with their traces (and, given the
    training maneuvers, the model's 95 % confidence and prediction bands along them)."""
    from ..fitting.bands import trace_bands
    out = {}
    for coef in LONGITUDINAL:
        pred = ms.predict(coef, data)
        slices = data.segment_slices()
        per_maneuver = ManeuverScores.of(data[coef], data[coef] - pred, slices).r2
        scored = [(float(score), name, sl) for score, name, sl in zip(per_maneuver, data.names, slices)]
        scored.sort(key=lambda s: -s[0] if np.isfinite(s[0]) else np.inf)
        picks = [("best", scored[0]), ("median", scored[len(scored) // 2]), ("worst", scored[-1])]
        out[coef] = [{"which": which, "maneuver": name, "r2": score, "t": data["t"][sl] - data["t"][sl][0],
                      "measured": data[coef][sl], "model": pred[sl],
                      "band": None if train is None else trace_bands(
                          ms.candidates[coef], ms.summaries[coef], train, data.select([data.names.index(name)]),
                          ms.lift if coef != "CL" else None)}
                     for which, (score, name, sl) in picks]
    return out


def hysteresis_maneuver(campaign: Campaign) -> int:
    """Index of the maneuver for the hysteresis loop: a validation dynamic stall if there is one."""
    ranked = []
    for i, m in enumerate(campaign.maneuvers):
        sl = campaign.data.segment_slices()[i]
        span = float(np.ptp(campaign.data["alpha"][sl]))
        ranked.append(((m.kind == "dynamic") + (m.kind in ("dynamic", "deep-dynamic")) + (m.split == "validation"),
                       span, i))
    return max(ranked)[2]


def hysteresis(ms: ModelSet, campaign: Campaign, ref: Reference) -> dict:
    i = hysteresis_maneuver(campaign)
    data = campaign.data.select([i])
    m = campaign.maneuvers[i]
    grid = np.linspace(data["alpha"].min(), data["alpha"].max(), 200)
    return {"maneuver": m.id, "kind": m.kind, "split": m.split, "alpha": data["alpha"],
            "measured": data["CL"], "model": ms.predict("CL", data), "static_alpha": grid,
            "static": static_coefficients(ms, grid, ref)["CL"], "index": i}


def gap_cells(residual: np.ndarray, data: FlightData, bands: np.ndarray) -> np.ndarray:
    """Mean squared residual per (maneuver, alpha band); NaN where a maneuver never visits a band."""
    band = np.clip(np.searchsorted(bands, data["alpha"], side="right") - 1, 0, len(bands) - 2)
    cells = np.full((data.n_segments, len(bands) - 1), np.nan)
    for row, sl in enumerate(data.segment_slices()):
        sums = np.bincount(band[sl], weights=residual[sl] ** 2, minlength=len(bands) - 1)
        counts = np.bincount(band[sl], minlength=len(bands) - 1)
        with np.errstate(invalid="ignore", divide="ignore"):
            cells[row] = np.where(counts > 0, sums / counts, np.nan)
    return cells


def alpha_bands(alpha: np.ndarray) -> np.ndarray:
    lo = np.floor(alpha.min() / ALPHA_BAND) * ALPHA_BAND
    hi = np.ceil(alpha.max() / ALPHA_BAND) * ALPHA_BAND
    return np.arange(lo, hi + ALPHA_BAND / 2, ALPHA_BAND)


def with_effect(ms: ModelSet, coef: str, changed: Candidate, fitted: CandidateResult, campaign: Campaign) -> dict:
    """Validation residuals of the set's ``coef`` model before and after adding a library effect: ``changed``
    is the model with the effect, ``fitted`` its fit (:func:`structsearch.thesis_study.model_set.fit_with_effect`)."""
    baseline = ms.candidates[coef]
    val = campaign.split("validation")
    after = ms.predict(coef, val, changed, fitted.estimates.params)
    bands = alpha_bands(val["alpha"])
    before_residual, after_residual = val[coef] - ms.predict(coef, val), val[coef] - after
    return {"baseline": baseline.name, "model": changed.name, "bands": bands,
            "maneuvers": list(val.names), "before": gap_cells(before_residual, val, bands),
            "after": gap_cells(after_residual, val, bands),
            "mse_before": float(np.mean(before_residual ** 2)), "mse_after": float(np.mean(after_residual ** 2))}
