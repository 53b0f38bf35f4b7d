"""The withheld-effect benchmark through JSBSim: a simulator that lacks one effect, diagnosed as a user's simulator.

For each effect of the withheld benchmark (:data:`structsearch.diagnosis.withheld.WITHHELD`), the truth of the
default campaign without that effect (the simulator's own parameter values, nothing refitted: a dropped term is
gone, a lag made simpler keeps every other value) is exported to JSBSim, and the flight data are diagnosed against
that aircraft as ``diagnose --simulator jsbsim:DIR`` diagnoses any simulator: a fixed baseline, evaluated at the
recorded states. Scored against the truth: is the withheld effect (or a move that carries its name at one state)
the first move adopted, and does it close at least half of the baseline's gap?

A baseline refitted to the data would not do: the fit moves its other parameters to stand in for the missing effect
(the lag-free lift model fitted to the default campaign is within 1 % of the noise floor), so the benchmark would
ask whether a diagnosis finds an effect that the baseline already half carries.
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Sequence

from ..data.campaign import Campaign
from ..fitting.candidates import Candidate
from .exporting import Fitted
from .settings import Settings

# A library effect "explains" the gap when it closes at least this share of it (the withheld benchmark's rule).
HALF = 0.5
# The move that is a withheld effect when the baseline is a fixed simulator. The simulator's separation states
# are inside it, out of the gap model's reach: an effect that is the coefficient's K term on a state (the K term
# a new state brings: K_L(X) in lift, the second state; 1 - X in drag, separation drag; (1 - X) C_L in pitch, the
# centre-of-pressure shift; data/coefficients.py) enters as a state the gap model adds with that term
SAME_ON_A_FIXED_BASELINE = {"second_separation_state": "add state ", "separation_drag": "add state ",
                            "cp_shift": "add state "}


@dataclass(frozen=True)
class ThroughJsbsimRow:
    """One withheld effect diagnosed through JSBSim: what was adopted first, and how much of the gap it closed."""

    effect: str
    coefficient: str
    baseline: str                 # the structure exported (the truth's structure without the effect)
    first_adopted: str | None     # the first round's adopted move (None: nothing adopted)
    hit: bool                     # it is the withheld effect (or that effect at one state)
    shrink: float | None          # the share of the baseline's gap it closes
    closes_half: bool
    gap_over_floor: float | None  # the baseline's validation MSE over the noise floor, minus 1
    explained: bool
    seconds: float


def truth_without(effect: str) -> list[Fitted]:
    """The default campaign's truth without ``effect`` as export reads fitted models: the lift model and, for a
    drag or pitch effect, that coefficient's model; the truth's values, no covariance."""
    from ..data.coefficients import LIFT, coefficient
    from ..diagnosis.withheld import baseline_without
    from ..fitting.specs import find_candidate
    from ..flight.reference import FINAL_DRAG, FINAL_LIFT, FINAL_MODEL_NAMES, FINAL_PITCH
    truth = {**FINAL_LIFT, **FINAL_DRAG, **FINAL_PITCH}
    reduced = baseline_without(effect)
    lift = reduced if coefficient(reduced.coefficient).owns_states else find_candidate(FINAL_MODEL_NAMES[LIFT.name])
    models = [lift] + ([reduced] if reduced is not lift else [])
    return [_truth_of(c, truth) for c in models]


def _truth_of(c: Candidate, truth: dict[str, float]) -> Fitted:
    own = [n for n, _ in c.regressors] + (list(c.state_parameters) if not c.lift else [])
    missing = [n for n in own if n not in truth]
    if missing:   # the truth table and the final models are declared apart: say which one drifted
        raise KeyError(f"{c.name}: the truth has no value for {', '.join(missing)}")
    return Fitted(c, {n: float(truth[n]) for n in own}, dict.fromkeys(own), note="the simulator's truth, not fitted")


def row(campaign: Campaign, effect: str, work: Path, settings: Settings = Settings()) -> ThroughJsbsimRow:
    """Export the truth without ``effect`` under ``work/effect`` and diagnose ``campaign`` against it."""
    from ..diagnosis.withheld import baseline_without
    from ..export.write import write_export
    from .diagnosing import diagnose_simulator
    from .exporting import exported_model
    from .results import campaign_record
    t0 = time.perf_counter()
    fitted = truth_without(effect)
    aircraft = work / effect
    write_export(exported_model(fitted, campaign, campaign_record(campaign)), "jsbsim", aircraft)
    coefficient = baseline_without(effect).coefficient
    doc = diagnose_simulator(campaign, coefficient=coefficient, simulator=f"jsbsim:{aircraft}", settings=settings)
    first = doc.first
    adopted = next((e for e in first.effects if e.name == first.adopted), None) if first.adopted else None
    shrink = adopted.shrink if adopted is not None else None
    floor = doc.noise_floor
    gap = doc.mse.validation / floor - 1 if floor and math.isfinite(floor) and floor > 0 else None
    return ThroughJsbsimRow(effect, coefficient, fitted[-1].candidate.name, first.adopted,
                            adopted is not None and is_the_effect(effect, adopted.name, adopted.effect), shrink,
                            shrink is not None and shrink >= HALF, gap, bool(doc.explained),
                            time.perf_counter() - t0)


def effects() -> list[str]:
    """The withheld benchmark's effects, in its order (JSBSim needed: one error naming the extra when absent)."""
    from ..diagnosis.withheld import WITHHELD
    from ..export.check import need_jsbsim
    need_jsbsim("the withheld benchmark through JSBSim drives JSBSim")
    return list(WITHHELD)


def is_the_effect(effect: str, move: str, move_effect: str | None = None) -> bool:
    """Whether the adopted ``move`` (its name, and the library effect it carries) is the withheld ``effect``: the
    effect itself, the effect at one state, or its form on a fixed baseline (:data:`SAME_ON_A_FIXED_BASELINE`)."""
    same = SAME_ON_A_FIXED_BASELINE.get(effect)
    return effect in (move, move_effect) or move.startswith(f"{effect}:") or bool(same and move.startswith(same))


def markdown(rows: Sequence[ThroughJsbsimRow], command: str, seconds: float) -> str:
    """The benchmark's page: a row per effect and the counts the target reads."""
    from tabulate import tabulate
    table = [[r.effect, r.coefficient, r.first_adopted or "nothing adopted", "yes" if r.hit else "no",
              "-" if r.shrink is None else f"{r.shrink:.2f}", "yes" if r.closes_half else "no",
              "-" if r.gap_over_floor is None else f"{100 * r.gap_over_floor:.0f} %", "yes" if r.explained else "no",
              f"{r.seconds:.0f}"] for r in rows]
    hits = sum(r.hit for r in rows)
    both = sum(r.hit and r.closes_half for r in rows)
    return "\n".join([
        "# Withheld effects through JSBSim", "",
        f"Every figure on this page was made by `{command}` ({seconds:.0f} s).", "",
        "For each effect of the withheld benchmark, the default campaign's truth without it (the simulator's own "
        "parameter values, nothing refitted) is exported to JSBSim, and the default campaign is diagnosed against "
        "that aircraft as `diagnose --simulator jsbsim:DIR` diagnoses any simulator: a fixed baseline, evaluated at "
        "the recorded states, with the diagnose command's own settings (`diagnose --simulator`). `shrink` is the "
        "share of the first round's gap the move adopted first closes. On a fixed baseline the simulator's "
        "separation states are out of the gap model's reach, so an effect that is the coefficient's K term on a "
        "state enters as a state the gap model adds with that term: `add state X with ...` counts as "
        "`second_separation_state` (K_L(X) in lift), `separation_drag` (1 - X in drag) and `cp_shift` "
        "((1 - X) C_L in pitch).", "",
        tabulate(table, headers=["withheld effect", "coef.", "adopted first", "is the effect", "shrink", ">= 0.5",
                                 "baseline gap over floor", "explained", "s"], tablefmt="github"), "",
        f"Adopted first: **{hits}/{len(rows)}**; adopted first and closing at least half of the gap: "
        f"**{both}/{len(rows)}**.", ""])


def to_json(rows: Sequence[ThroughJsbsimRow], command: str, seconds: float) -> dict:
    return {"command": command, "seconds": seconds, "rows": [asdict(r) for r in rows],
            "adopted_first": sum(r.hit for r in rows),
            "adopted_first_closing_half": sum(r.hit and r.closes_half for r in rows)}
