"""C_m about the fixed reference point against C_m about the recorded cg, out of sample (docs/guide/moment-reference.md).

:func:`compare_references` fits the lift model and two pitch structures on one campaign (by default the thesis'
Cm-XXXIIIr, about the cg with its cg term, and Cm-XXXIIIf, the same about ``[aircraft] reference_point`` without
it) and compares them by the ranking's rule (:mod:`structsearch.fitting.comparison`): the per-maneuver relative MSE
excess on the validation maneuvers and on the cross-validation folds, within noise when it is within one standard
error (or 1 %).

    python -m structsearch.experiments.reference_point --scale 1.0 [--cg-spread M] [--cg-moment transfer]
"""
from __future__ import annotations

import argparse
import json
from dataclasses import asdict, dataclass

from ..data.campaign import Campaign
from ..fitting.candidate_result import CandidateResult, SplitScores
from ..fitting.comparison import relative_excess, within_noise
from ..fitting.fitter import temporary_fitter
from ..fitting.lift_fit import LiftFit
from ..fitting.options import FitOptions
from ..fitting.specs import find_candidate


@dataclass(frozen=True)
class Excess:
    """The relative MSE excess of the fixed-point structure over the cg one on some held-out maneuvers."""

    mean: float
    se: float
    fixed_within_noise: bool     # the fixed-point structure is within noise of the cg one (excess <= noise bar)
    fixed_better: bool           # the cg structure is not within noise of the fixed-point one

    @classmethod
    def of(cls, fixed: SplitScores, cg: SplitScores) -> "Excess":
        mean, se = relative_excess(fixed.mse_maneuvers, cg.mse_maneuvers, fixed.n_maneuvers)
        back, back_se = relative_excess(cg.mse_maneuvers, fixed.mse_maneuvers, cg.n_maneuvers)
        return cls(mean, se, within_noise(mean, se), not within_noise(back, back_se))


@dataclass(frozen=True)
class ReferenceComparison:
    cg: str
    fixed: str
    mse_validation: dict
    mse_cv: dict
    validation: Excess
    cv: Excess | None
    estimates: dict              # [estimate, standard deviation] of the cg terms of the cg structure and Cm_CL of both

    def to_dict(self) -> dict:
        return asdict(self)


def compare_references(campaign: Campaign, cg: str = "Cm-XXXIIIr", fixed: str = "Cm-XXXIIIf",
                       options: FitOptions = FitOptions()) -> ReferenceComparison:
    """Fit ``cg`` (about the recorded cg) and ``fixed`` (about the reference point) on ``campaign`` and compare them."""
    c_cg, c_fixed = find_candidate(cg), find_candidate(fixed)
    lift_candidate = find_candidate(c_cg.lift)
    with temporary_fitter(campaign, options) as fitter:
        lift = fitter.fit_one(lift_candidate)
        r_cg, r_fixed = fitter.with_lifts({lift_candidate.name: LiftFit(lift_candidate, lift)}).fit([c_cg, c_fixed])
    for r in (r_cg, r_fixed):
        if r.failed:
            raise ValueError(f"{r.name}: {r.error}")
    return ReferenceComparison(
        cg, fixed, {cg: r_cg.mse_validation, fixed: r_fixed.mse_validation},
        {cg: _cv_mse(r_cg), fixed: _cv_mse(r_fixed)}, Excess.of(r_fixed.validation, r_cg.validation),
        Excess.of(r_fixed.cv, r_cg.cv) if r_fixed.cv is not None and r_cg.cv is not None else None,
        _estimates(r_cg, ("Cm_CL", "Cm_xcgCL")) | _estimates(r_fixed, ("Cm_CL",)))


def _estimates(r: CandidateResult, names) -> dict:
    """Estimate and standard deviation of the cg and C_L terms of ``r``."""
    e = r.estimates
    return {f"{r.name} {n}": [e.params[n], e.stderr[n]] for n in names}


def _cv_mse(r: CandidateResult) -> float | None:
    return r.cv.mse if r.cv is not None else None


def main(argv=None) -> None:
    from ..flight.flighttest import build_campaign
    p = argparse.ArgumentParser(prog="python -m structsearch.experiments.reference_point")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--cg-spread", type=float, default=None)
    p.add_argument("--cg-moment", default="thesis")
    args = p.parse_args(argv)
    campaign = build_campaign(seed=args.seed, scale=args.scale, cg_spread=args.cg_spread, cg_moment=args.cg_moment)
    print(json.dumps(compare_references(campaign).to_dict(), indent=1))


if __name__ == "__main__":
    main()
