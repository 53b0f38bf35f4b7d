"""``structsearch bench --joint``: a joint fit of the final models against the sequential fits, in one run on the
default campaign: each coefficient's validation MSE, the shared separation parameters' standard deviations
against the lift-only fit's, and the cost (the joint fit, which starts from the sequential fits, against the
sum of the three sequential fits; the bands' cost against the fit's)."""
from __future__ import annotations

import time
from typing import Callable

from tabulate import tabulate


def run_joint_bench(scale: float = 1.0, seed: int = 0, starts: int = 4,
                    progress: Callable[[str], None] | None = None) -> dict:
    from ..fitting.bands import static_bands
    from ..fitting.candidate_fit import fit_staged
    from ..fitting.joint import fit_joint
    from ..fitting.lift_fit import LiftFit
    from ..fitting.options import FitOptions
    from ..fitting.specs import find_candidate
    from ..flight.flighttest import build_campaign
    from ..flight.reference import FINAL_MODEL_NAMES
    say = progress or (lambda m: None)
    campaign = build_campaign(seed=seed, scale=scale)
    train, val = campaign.split("train"), campaign.split("validation")
    options = FitOptions(n_starts=starts)
    names = list(FINAL_MODEL_NAMES.values())
    say("sequential fits")
    seq, seconds = {}, {}
    t0 = time.perf_counter()
    lift = fit_staged(find_candidate(names[0]), train, val, None, options)
    seconds["CL"] = time.perf_counter() - t0
    seq["CL"] = lift
    for n in names[1:]:
        c = find_candidate(n)
        t0 = time.perf_counter()
        seq[c.coefficient] = fit_staged(c, train, val, LiftFit(find_candidate(names[0]), lift), options)
        seconds[c.coefficient] = time.perf_counter() - t0
    t0 = time.perf_counter()
    bands = static_bands(find_candidate(names[0]), lift, train)
    band_seconds = time.perf_counter() - t0
    say("joint fit")
    t0 = time.perf_counter()
    joint = fit_joint([find_candidate(n) for n in names], train, val, options)
    joint_seconds = time.perf_counter() - t0
    r = joint.result
    return {
        "scale": scale, "seed": seed, "starts": starts, "samples": train.n_samples,
        "sequential_seconds": seconds, "joint_seconds": joint_seconds,
        "cost_ratio": joint_seconds / sum(seconds.values()),
        "bands_seconds": band_seconds, "bands_ratio": band_seconds / seconds["CL"],
        "weights_settled": joint.weights_settled, "iterations": joint.iterations, "converged": r.converged,
        "mse_validation": {c.coefficient: {"joint": c.validation.mse, "sequential": seq[c.coefficient].mse_validation}
                           for c in joint.coefficients},
        "shared": {n: {"joint": r.params[n], "joint_sd": r.stderr[n], "lift_only": lift.estimates.params[n],
                       "lift_only_sd": lift.estimates.stderr[n]} for n in joint.shared},
        "bands_points": len(bands.alpha),
    }


def markdown(fig: dict, command: str) -> str:
    rows = [[c, f"{v['sequential']:.5g}", f"{v['joint']:.5g}", f"{v['joint'] / v['sequential'] - 1:+.2%}"]
            for c, v in fig["mse_validation"].items()]
    shared = [[n, f"{v['lift_only']:.4g}", f"{v['lift_only_sd']:.3g}", f"{v['joint']:.4g}", f"{v['joint_sd']:.3g}",
               f"{v['joint_sd'] / v['lift_only_sd']:.2f}"] for n, v in fig["shared"].items()]
    seq = " + ".join(f"{c} {s:.1f} s" for c, s in fig["sequential_seconds"].items())
    return "\n".join([
        "# Joint fit of the final models against the sequential fits", "",
        f"Made by `{command}` ({fig['samples']} training samples, {fig['starts']} starts per nonlinear fit, one run).",
        "", f"- Cost: the joint fit {fig['joint_seconds']:.1f} s (it starts from the sequential fits, which it "
        f"includes) against the sequential fits' sum ({seq}): **{fig['cost_ratio']:.2f}x**.",
        f"- The bands of the lift model's static curve ({fig['bands_points']} points): {fig['bands_seconds']:.2f} s, "
        f"**{fig['bands_ratio']:.1%}** of its fit's time.",
        f"- Weights {'settled' if fig['weights_settled'] else 'did NOT settle'} after {fig['iterations']} "
        f"iterations; the optimizer {'converged' if fig['converged'] else 'did NOT converge'}.", "",
        "## Validation MSE per coefficient", "",
        tabulate(rows, headers=["coefficient", "sequential", "joint", "joint - sequential"], tablefmt="github"), "",
        "## The shared separation parameters", "",
        tabulate(shared, headers=["parameter", "lift-only estimate", "lift-only sd", "joint estimate", "joint sd",
                                  "joint sd / lift-only sd"], tablefmt="github"), "",
        "Standard deviations with the default covariance (hac-maneuver) of each problem: the lift-only fit's of "
        "the lift model alone, the joint fit's of the stacked problem.", ""])
