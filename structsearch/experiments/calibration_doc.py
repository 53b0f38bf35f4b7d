"""``results/calibration.md`` and ``calibration.json``: the Monte Carlo calibration of the covariances."""
from __future__ import annotations

from tabulate import tabulate

from ..engine.statistics import KINDS
from .calibration import (BAND_COVERAGE_RANGE, BINOMIAL_QUANTILE, COVERAGE_RANGE, GAP_LEVEL, REJECTION_CEILING,
                           TUNING_SEEDS, Calibration, KindCalibration, default_start_rows, held_out, joint_rows)
from .calibration_profile import profile_dict, profile_lines

# issue 30's targets for the standard deviations themselves and the two interval levels
SD_RATIO_RANGE = (0.8, 1.25)
COVERAGE68_RANGE = (0.60, 0.76)
COVERAGE95_RANGE = (0.90, 0.99)


def parameter_dict(p) -> dict:
    """One parameter's calibration; ``sd_ratio``, ``coverage_68`` and ``coverage_95`` are the names of
    docs/interfaces.md 6.4 (``ratio``, ``coverage68``, ``coverage95``: the same numbers, kept)."""
    return {"model": p.model, "parameter": p.parameter, "truth": p.truth, "mean": p.mean, "mc_sd": p.mc_sd,
            "reported_sd": p.reported_sd, "ratio": p.ratio, "sd_ratio": p.ratio, "bias_in_sd": p.bias_in_sd,
            "coverage68": p.coverage68, "coverage95": p.coverage95, "coverage_68": p.coverage68,
            "coverage_95": p.coverage95, "coverage95_of_mc_mean": p.centred95, "n": p.n,
            "covered95": p.covered95, "binomial_floor95": p.binomial_floor95,
            "coverage95_consistent": p.coverage95_consistent}


def seeds_dict(cal: Calibration) -> dict:
    return {"values": list(cal.seeds), "held_out": held_out(cal.seeds),
            "tuning_seeds": [TUNING_SEEDS[0], TUNING_SEEDS[-1]]}


def pooled(rows, attr: str) -> float:
    counted = [p for p in rows if p.n]
    n = sum(p.n for p in counted)
    return sum(getattr(p, attr) * p.n for p in counted) / n if n else float("nan")


def default_start_dict(cal: Calibration) -> dict | None:
    rows = default_start_rows(cal.draws, cal.cg_moment)
    if not rows:
        return None
    other = sorted({m for d in cal.draws for m in d.other_basin})
    return {"covariance": cal.default_kind, "pooled_coverage68": pooled(rows, "coverage68"),
            "pooled_coverage95": pooled(rows, "coverage95"),
            "other_basin": {m: sum(m in d.other_basin for d in cal.draws) for m in other},
            "parameters": [parameter_dict(p) for p in rows]}


def calibration_dict(cal: Calibration) -> dict:
    """Plain JSON-ready summary (NaN stays NaN; the writer turns it into null)."""
    return {
        "seeds": seeds_dict(cal), "scale": cal.scale, "training_samples": cal.samples, "seconds": cal.seconds,
        "best": cal.best.kind,
        # flight-level errors (bench --calibration --flight-errors): each campaign flown on `flights` flights whose
        # maneuvers share a mass, cg, engine-model and vane-calibration error; keys absent without them
        **({"flight_errors": True, "flights": cal.flights} if cal.flights else {}),
        **({"flight_effects": list(cal.flight_effects)} if cal.flight_effects else {}),
        # bench --calibration --cg-moment transfer: the truth's cg dependence and the pitch model fitted; absent for
        # the thesis' truth
        **({"cg_moment": cal.cg_moment, "models": cal.model_names} if cal.cg_moment != "thesis" else {}),
        "default_start": default_start_dict(cal),
        "joint": [parameter_dict(p) for p in joint_rows(cal.draws)],
        "profile": profile_dict(cal, cal.truth, cal.model_names),
        "bands": {coef: {"coverage95": cov, "campaign_min": cal.band_campaign_coverage[coef][0],
                         "campaign_max": cal.band_campaign_coverage[coef][1],
                         "mean_half_width": (float(sum(d.band_widths[coef] for d in cal.draws) / len(cal.draws))
                                             if cal.draws and all(coef in d.band_widths for d in cal.draws)
                                             else None)}
                  for coef, cov in cal.band_coverage.items()},
        "kinds": {k.kind: {
            "pooled_coverage68": k.pooled68, "pooled_coverage95": k.pooled95,
            "pooled_coverage95_of_mc_mean": k.pooled_centred95,
            "worst_coverage95": None if k.worst95 is None else {
                "parameter": f"{k.worst95.model}:{k.worst95.parameter}", "coverage": k.worst95.coverage95},
            "not_estimable_models": list(k.not_estimable_models),
            "gap_test_rejection_rate": k.rejection_rate, "gap_tests": k.gap_tests,
            "gap_tests_not_estimable": k.not_estimable, "meets_goals": k.meets_goals,
            "below_binomial_floor": [f"{p.model}:{p.parameter}" for p in k.below_binomial],
            "parameters": [parameter_dict(p) for p in k.parameters]}
            for k in cal.kinds},
    }


def _summary_row(k: KindCalibration) -> list:
    if k.worst95 is None:
        why = f"not estimable in any of the {k.not_estimable} fits (NaN, never 0)"
        return [k.kind, "n/a", "n/a", why, "n/a", "n/a", "no"]
    w = k.worst95
    missing = k.not_estimable_models
    worst = f"{w.coverage95:.2f} ({w.model} {w.parameter})" + (
        f"; {', '.join(missing)} not estimable (NaN, never 0)" if missing else "")
    return [k.kind, f"{k.pooled68:.3f}", f"{k.pooled95:.3f}", worst,
            f"{k.pooled_centred95:.3f}",
            f"{k.rejections}/{k.gap_tests} = {k.rejection_rate:.3f}"
            + (f" ({k.not_estimable} not estimable)" if k.not_estimable else ""),
            "yes" if k.meets_goals else "no"]


def _kind_lines(k) -> list[str]:
    """One covariance kind's table: each parameter's bias, spread, coverage and count against its binomial floor."""
    if not any(p.n for p in k.parameters):
        return [f"## {k.kind}", "", "Not estimable on these campaigns: every reported standard deviation is "
                "NaN (the estimate needs more training maneuvers than parameters).", ""]
    rows = [[p.model, p.parameter, f"{p.truth:.5g}", f"{p.bias_in_sd:+.2f}", f"{p.mc_sd:.3g}",
             f"{p.reported_sd:.3g}", f"{p.ratio:.2f}", f"{p.coverage68:.2f}", f"{p.coverage95:.2f}",
             _count(p),
             f"{p.centred95:.2f}"]
            for p in k.parameters]
    return [f"## {k.kind}", "",
            tabulate(rows, headers=["model", "parameter", "truth", "bias / MC sd", "MC sd", "mean reported sd",
                                    "reported / MC", "68 % coverage", "95 % coverage", "covered / floor",
                                    "95 % coverage of the MC mean"], tablefmt="github"), ""]


def calibration_markdown(cal: Calibration, command: str) -> str:
    lo, hi = COVERAGE_RANGE
    n = len(cal.seeds)
    lines = [
        "# Calibration of the reported uncertainty on the flight simulator", "",
        f"Produced by `{command}` in {cal.seconds:.0f} s: {n} simulated campaigns (seeds {cal.seeds[0]}-"
        f"{cal.seeds[-1]}, "
        + (f"held out: disjoint from the seeds {TUNING_SEEDS[0]}-{TUNING_SEEDS[-1]} the default covariance and the "
           "few-maneuvers flag were chosen on; " if held_out(cal.seeds) else
           f"NOT held out: they overlap the seeds {TUNING_SEEDS[0]}-{TUNING_SEEDS[-1]} the defaults were chosen on; ")
        + f"scale {cal.scale}: {cal.samples} training samples each, full measurement chain"
        + (f", flown on {cal.flights} flights whose maneuvers share a mass, cg, engine-model and vane-calibration "
           "error (`--flight-errors`)" if cal.flights else "")
        + (f"; the final models estimate per-flight offsets ({', '.join(cal.flight_effects)}; `--flight-effects`) "
           "with their parameters, and the joint fit, which takes none, is left out" if cal.flight_effects else "")
        + (f"; the truth's C_m depends on the cg by the moment transfer alone (`--cg-moment {cal.cg_moment}`), and "
           f"the pitch model fitted is its structure, {cal.model_names['Cm']}, about the fixed reference point"
           + (", whose x_cg effect has the transfer's known coefficient" if "x_cg" in cal.flight_effects else "")
           + " (the joint fit, of the thesis' models, is left out)" if cal.cg_moment != "thesis" else "")
        + "), "
        "the three final models fitted on each; intervals are estimate +- t quantile * reported standard "
        "deviation around the simulator's truth, with each fit's reference degrees of freedom (G - 1 for "
        "hac-maneuver and cluster, G the training maneuvers"
        + ("; F - 1 for hac-flight, F the effective training flights" if cal.flights else "")
        + "; m - p, i.e. the normal, for the others). Drag and pitch standard deviations include the lift model's "
        "estimation error (two-step correction).", "",
        f"Goals: pooled 95 % coverage in [{lo:.2f}, {hi:.2f}]; no parameter whose count of covered campaigns lies "
        f"below the binomial {BINOMIAL_QUANTILE:.1%} quantile of {n} campaigns at 0.95 (its Monte Carlo error: "
        f"column 'covered / floor'); gap test (Wald, {GAP_LEVEL:.0%} level) rejecting at most "
        f"{REJECTION_CEILING:.0%} of the null cases ({n} campaigns x 3 models).", "",
        tabulate([_summary_row(k) for k in cal.kinds],
                 headers=["covariance", "pooled 68 % coverage", "pooled 95 % coverage", "worst 95 % coverage",
                          "pooled 95 % coverage of the MC mean", "gap test rejections at 1 %", "meets goals"],
                 tablefmt="github"), "",
        f"Best calibrated: **{cal.best.kind}** (among the kinds that meet the goals, the one whose pooled 95 % "
        "coverage of the truth and of the Monte Carlo mean are closest to 95 %; when none meets them, that "
        "distance plus the gap-test rejections over the goal).", "",
        "Coverage of the Monte Carlo mean measures the standard deviations alone; coverage of the truth "
        "also suffers from any bias of the estimates (column 'bias / MC sd': a bias of the estimator "
        "itself, from errors in the measured regressors, that no covariance estimate can repair).", "",
        f"With {n} campaigns a single parameter's coverage has a standard error of about "
        f"{(0.95 * 0.05 / n) ** 0.5:.3f} at 95 %.", ""]
    lines += target_lines(cal)
    lines += default_start_lines(cal)
    lines += profile_lines(cal, cal.truth, cal.model_names)
    lines += band_lines(cal)
    lines += joint_lines(cal)
    for k in cal.kinds:
        lines += _kind_lines(k)
    return "\n".join(lines)


def _count(p) -> str:
    """Covered of n / the binomial floor, or why there is no count."""
    if p.covered95 is None:
        return "n/a (no standard deviation in any campaign)"
    return f"{p.covered95}/{p.n} / {p.binomial_floor95}" + ("" if p.coverage95_consistent else " (below)")


def _in(x: float, bounds) -> bool:
    return bool(bounds[0] <= x <= bounds[1])


def _target_counts(rows) -> list[str]:
    est = [p for p in rows if p.n]
    return [f"{sum(_in(p.ratio, SD_RATIO_RANGE) for p in est)}/{len(est)}",
            f"{sum(_in(p.coverage68, COVERAGE68_RANGE) for p in est)}/{len(est)}",
            f"{sum(_in(p.coverage95, COVERAGE95_RANGE) for p in est)}/{len(est)}",
            f"{min((p.ratio for p in est), default=float('nan')):.2f}-{max((p.ratio for p in est), default=float('nan')):.2f}",
            f"{pooled(est, 'coverage68'):.3f}", f"{pooled(est, 'coverage95'):.3f}"]


def target_lines(cal: Calibration) -> list[str]:
    """Issue 30's targets for the default covariance: every final-model parameter's reported / Monte Carlo
    standard deviation in 0.8-1.25, 68 % coverage in 60-76 %, 95 % coverage in 90-99 %."""
    default = next((k for k in cal.kinds if k.kind == cal.default_kind), None)
    rows = []
    if default is not None:
        rows.append([f"{default.kind}, from the truth"] + _target_counts(default.parameters))
    start = default_start_rows(cal.draws, cal.cg_moment)
    if start:
        rows.append([f"{cal.default_kind}, from the default start"] + _target_counts(start))
    # with flight-level errors, the kinds that group by flight beside it (same truth-start fits)
    rows += [[f"{k.kind}, from the truth"] + _target_counts(k.parameters) for k in cal.kinds
             if cal.flights and k.kind != cal.default_kind and KINDS[k.kind].by_flight]
    if not rows:
        return []
    lo, hi = SD_RATIO_RANGE
    return ["## The default covariance against issue 30's targets", "",
            f"Per parameter of the three final models: reported / Monte Carlo standard deviation in {lo}-{hi}, "
            f"68 % coverage in {COVERAGE68_RANGE[0]:.2f}-{COVERAGE68_RANGE[1]:.2f}, 95 % coverage in "
            f"{COVERAGE95_RANGE[0]:.2f}-{COVERAGE95_RANGE[1]:.2f} (counts of parameters inside).", "",
            tabulate(rows, headers=["fits", "sd ratio in range", "68 % in range", "95 % in range", "sd ratios",
                                    "pooled 68 %", "pooled 95 %"], tablefmt="github"), ""]


def default_start_lines(cal: Calibration) -> list[str]:
    rows = default_start_rows(cal.draws, cal.cg_moment)
    if not rows:
        return []
    other = default_start_dict(cal)["other_basin"]
    body = [[p.model, p.parameter, f"{p.truth:.5g}", f"{p.bias_in_sd:+.2f}", f"{p.mc_sd:.3g}", f"{p.reported_sd:.3g}",
             f"{p.ratio:.2f}", f"{p.coverage68:.2f}", f"{p.coverage95:.2f}"] for p in rows]
    basin = ("; ".join(f"{m} on {k} of {len(cal.draws)} campaigns" for m, k in other.items()) if other else
             "none: on every campaign each model reached the truth-start fit's training MSE")
    return ["## From the default start (what `structsearch fit` reports)", "",
            f"The final models fitted on each campaign as `structsearch fit` fits them (4 starts, declared and "
            f"quasi-random, staged; drag and pitch on that lift fit), with the default covariance "
            f"({cal.default_kind}): this coverage is not conditional on the truth's basin. Fits that ended above "
            f"the truth-start fit's training MSE (another basin): {basin}.", "",
            tabulate(body, headers=["model", "parameter", "truth", "bias / MC sd", "MC sd", "mean reported sd",
                                    "reported / MC", "68 % coverage", "95 % coverage"], tablefmt="github"), ""]


def band_lines(cal: Calibration) -> list[str]:
    """The static curves' bands against the truth (issue 29); nothing when no draw computed them."""
    coverage = cal.band_coverage
    if all(v != v for v in coverage.values()):   # all NaN: the default covariance was not among the kinds
        return []
    lo, hi = BAND_COVERAGE_RANGE
    rows = []
    for coef, cov in coverage.items():
        cmin, cmax = cal.band_campaign_coverage[coef]
        width = sum(d.band_widths[coef] for d in cal.draws) / len(cal.draws)
        rows.append([coef, f"{cov:.3f}", f"{cmin:.2f}-{cmax:.2f}", f"{width:.4g}",
                     "yes" if lo <= cov <= hi else "no"])
    n_points = len(next(iter(cal.draws[0].band_hits.values())))
    return ["## Static curves: 95 % confidence bands against the truth", "",
            f"On each campaign the default covariance's fits give each static curve (q* = 0, delta_e = 0, C_T = 0, "
            f"separation states at their steady values; {n_points} alpha points over the flown range) its 95 % "
            "confidence band (the delta method, each point's Student-t quantile with its own effective maneuvers "
            "minus one: `structsearch fit`'s `bands`); the truth's curve is the simulator's model with its true "
            "parameters on the same grid (drag and pitch on the true lift model). Coverage: the share of the "
            f"(alpha, campaign) points where the band holds the truth; goal (issue 29) {lo:.2f}-{hi:.2f}. The fits "
            "start at the truth, as the parameters' above: the coverage is conditional on the right basin.", "",
            tabulate(rows, headers=["coefficient", "pooled coverage", "per campaign (min-max)",
                                    "mean half width", "in the goal"], tablefmt="github"), ""]


def joint_lines(cal: Calibration) -> list[str]:
    """The joint fit's parameters against the truth (issue 29); nothing when no draw has a joint fit."""
    rows = joint_rows(cal.draws)
    if not rows:
        return []
    lo, hi = BAND_COVERAGE_RANGE
    estimable = [p for p in rows if p.n]
    pooled95 = sum(p.coverage95 * p.n for p in estimable) / max(sum(p.n for p in estimable), 1)
    pooled68 = sum(p.coverage68 * p.n for p in estimable) / max(sum(p.n for p in estimable), 1)
    body = [[p.parameter, f"{p.truth:.5g}", f"{p.bias_in_sd:+.2f}", f"{p.mc_sd:.3g}", f"{p.reported_sd:.3g}",
             f"{p.ratio:.2f}", f"{p.coverage68:.2f}", f"{p.coverage95:.2f}"] for p in rows]
    return ["## Joint fit of the three final models", "",
            "On each campaign `fit --joint CL-VI,CD-IXr,Cm-XXXIIIr` (default covariance on the stacked problem, "
            "from the default start: the sequential fits start it), every parameter's interval (estimate +- t "
            "quantile * reported standard deviation, each parameter's reference dof) against the truth. Goal "
            f"(issue 29): the joint parameters' 95 % intervals cover {lo:.2f}-{hi:.2f}. Pooled 95 % coverage "
            f"**{pooled95:.3f}**, 68 % {pooled68:.3f}.", "",
            tabulate(body, headers=["parameter", "truth", "bias / MC sd", "MC sd", "mean reported sd",
                                    "reported / MC", "68 % coverage", "95 % coverage"], tablefmt="github"), ""]
