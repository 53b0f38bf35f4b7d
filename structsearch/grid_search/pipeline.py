"""Structure search: grids fitted in dependency order (lift before drag and pitch), ranked, refined."""
from __future__ import annotations

import dataclasses
import functools

import time
from dataclasses import dataclass, field
from typing import Sequence

from ..data.campaign import Campaign
from ..fitting.candidate_result import CandidateResult
from .admissibility import FIXABLE_REASONS, AdmissibilityRules, MAX_CORRELATION, Reason, reasons
from .ranking import rank
from .ranking import near_best
from .answer import answer_of
from .refinement import Refinement, refinement_key
from .refinements_together import refine_together
from ..fitting.fitter import Fitter, console_line
from ..fitting.lift_fit import LiftFit
from ..fitting.candidates import Candidate, Grid
from ..fitting.specs import load_grid


@dataclass(frozen=True)
class SearchResult:
    """Each grid's results, best first, and the wall time each grid took."""

    grids: dict[str, list[CandidateResult]]
    seconds: dict[str, float]
    refinements: dict[str, list[Refinement]] = field(default_factory=dict)
    joint: object | None = None     # the JointFit whose lift block drag and pitch read (``joint_lift``)


# ``--grid lateral``: the lateral-directional grids (``all`` is the thesis' longitudinal set)
LATERAL_GRIDS = ("side", "roll", "yaw")


def grids_for(spec: str) -> list[Grid]:
    """The grids ``--grid spec`` searches: ``all`` (separation, lift, drag, pitch), ``lateral`` (side, roll, yaw),
    or one grid by name or spec file."""
    if spec == "all":
        lift = load_grid("lift")
        return [load_grid("separation"), lift, load_grid("drag", lift), load_grid("pitch", lift)]
    if spec == "lateral":
        lift = load_grid("lift")
        return [load_grid(name, lift) for name in LATERAL_GRIDS]
    return [load_grid(spec)]


# At most this many well-fitting candidates are refined per grid (each refinement costs a few fits).
REFINE_STARTS = 3


def refinement_starts(ranked: list[CandidateResult]) -> list[CandidateResult]:
    """The candidates worth refining: within noise of the best fit (admissible or not) and not admissible
    only for reasons a refinement can remove (insignificant or correlated terms, a separation state the data do
    not place), best fit first; the rank-1 candidate when there is none."""
    starts = [s for s in near_best(ranked) if not s.placement.admissible and s.placement.reasons
              and all(_fixable(s, r) for r in s.placement.reasons)]
    starts = sorted(starts, key=lambda s: s.comparison.mse)[:REFINE_STARTS]
    if not starts and ranked and not ranked[0].failed:
        starts = [ranked[0]]
    return starts


def _fixable(s: CandidateResult, reason: str) -> bool:
    """Whether a refinement can remove ``reason`` against ``s``: a fixable kind, or parameters the data cannot
    identify that are all separation parameters (the refinement drops their state)."""
    kind = Reason.of(reason)
    if kind is Reason.NOT_IDENTIFIABLE:
        return not s.estimates.withheld and set(s.estimates.not_identifiable) <= set(s.estimates.nonlinear_names)
    return kind in FIXABLE_REASONS


def rules_for(campaign: Campaign, max_correlation: float = MAX_CORRELATION) -> AdmissibilityRules:
    """What admissibility needs from a campaign: the alpha range flown in training, the cg envelope."""
    alpha = campaign.split("train")["alpha"]
    envelope = campaign.aircraft.get("x_cg_range")
    return AdmissibilityRules(max_correlation=max_correlation, alpha_range=(float(alpha.min()), float(alpha.max())),
                              cg_range=tuple(envelope) if envelope is not None else None,
                              cbar=float(campaign.aircraft["cbar"]))


def search(fitter: Fitter, grid_spec: str, *, do_refine: bool = True, max_correlation: float = MAX_CORRELATION,
           joint_lift: Sequence[Candidate] = (), moment_reference: str | None = None) -> SearchResult:
    """Fit and rank the grids of ``grid_spec`` with ``fitter``, refining each grid's best.
    ``joint_lift``: structures (a lift one among them) fitted jointly first; drag and pitch candidates that
    name that lift structure read its joint estimate, and their two-step covariance has the joint fit as
    its first step (:func:`structsearch.fitting.joint.joint_lift`). ``moment_reference`` ("cg" or "fixed"): every
    pitch candidate takes C_m about it (None: as each declares)."""
    rules = rules_for(fitter.campaign, max_correlation)
    grids = [dataclasses.replace(g, candidates=tuple(c.with_moment_reference(moment_reference) for c in g.candidates))
             for g in grids_for(grid_spec)]
    ranked_by_grid, seconds = {}, {}
    refinements: dict[str, list[Refinement]] = {}
    joint = None
    if joint_lift:
        joint, read = _joint_lift_model(fitter, joint_lift)
        fitter = fitter.with_lifts({read.name: read})
    by_grid_results: dict[str, list[CandidateResult]] = {}
    for grid in grids:
        t0 = time.perf_counter()
        fitter = _with_lift_models(fitter, sorted({c.lift for c in grid.candidates if c.lift}))
        fitter.say(f"grid {grid.name}: {len(grid.candidates)} candidates")
        # earlier grids' candidates are warm starts too, and a candidate that is one of them under another
        # name is served its fit (the lift grid's CL-VI is the separation grid's U/S)
        earlier = [(c, r) for g in grids[:grids.index(grid)] for c, r in zip(g.candidates, by_grid_results[g.name])]
        results = fitter.fit(grid.candidates, earlier)
        by_grid_results[grid.name] = results
        if grid.name == "lift":   # a joint lift stays what drag and pitch read
            fitter = fitter.with_lifts({c.name: LiftFit(c, s) for c, s in zip(grid.candidates, results)
                                        if c.name not in fitter.lifts or not joint_lift})
        by_name = {c.name: c for c in grid.candidates}

        def judge(result, by_name=by_name):
            return reasons(result, by_name.get(result.name), rules)

        ranked = rank(results, judge)
        if do_refine:
            def rerank(extra, by_name=by_name, judge=judge, results=results):
                by_name.update({c.name: c for c, _ in extra})
                return rank(results + [s for _, s in extra], judge)

            extra, refinements[grid.name] = _refine_grid(fitter, grid, results, ranked, rules.alpha_range, rerank)
            if not refinements[grid.name]:
                del refinements[grid.name]
            if extra:
                ranked = rerank(extra)
                ranked = [s.placed(origin="refined") if s.name in {c.name for c, _ in extra} else s for s in ranked]
        ranked_by_grid[grid.name] = ranked
        seconds[grid.name] = time.perf_counter() - t0
    return SearchResult(ranked_by_grid, seconds, refinements, joint)


def _joint_lift_model(fitter: Fitter, joint_lift: Sequence[Candidate]):
    """The joint fit of ``joint_lift`` and the lift model drag and pitch read from it."""
    from ..data.errors import FitError
    from ..fitting.joint import fit_joint, joint_lift as lift_of
    say = fitter.say
    say("joint lift model: " + " + ".join(c.name for c in joint_lift))
    joint = fit_joint(list(joint_lift), *fitter.splits(), fitter.options)
    if not joint.weights_settled or not joint.result.converged:
        say(f"warning: the joint lift model {joint.name} "
            + ("did NOT settle its weights" if not joint.weights_settled else "did NOT converge")
            + "; drag and pitch read it all the same")
    read = lift_of(joint)
    if not read.influence_names:
        raise FitError(f"the joint fit {joint.name} identifies none of the lift model's parameters: drag and "
                       "pitch cannot read it")
    if read.not_identifiable:
        say(f"warning: the joint lift model cannot identify {', '.join(read.not_identifiable)}: held at their "
            "estimates in the drag and pitch candidates' two-step covariance")
    return joint, read


def _with_lift_models(fitter: Fitter, names: Sequence[str]) -> Fitter:
    """``fitter`` with the lift models ``names`` it lacks fitted (from the lift grid)."""
    missing = [n for n in names if n not in fitter.lifts]
    if not missing:
        return fitter
    lift_grid = load_grid("lift")
    candidates = [lift_grid[n] for n in missing]
    return fitter.with_lifts({c.name: LiftFit(c, s)
                              for c, s in zip(candidates, fitter.fit(candidates))})


def _refine_grid(fitter: Fitter, grid: Grid, results: list[CandidateResult], ranked: list[CandidateResult],
                 alpha_range: tuple[float, float] | None = None, rerank=None):
    """The structures the refinement of ``grid``'s candidates reached (with their fits) and the refinements
    themselves (``alpha_range``: the alpha range flown in training). The candidates within noise of the best fit
    are refined first (:func:`refinement_starts`); while no admissible structure is within the answer's tolerance
    of the best fit (:mod:`.answer`), the next candidates follow, best fit first, :data:`REFINE_STARTS` at a time,
    until one is or every candidate has been refined (``rerank(extra)``: the grid ranked with the structures
    reached so far). The refinements of one wave are walked together (:mod:`.refinements_together`): each
    round's fits are one task graph, so the wave's chains spread over the workers side by side."""
    known = {refinement_key(c): (c, r) for c, r in zip(grid.candidates, results) if not r.failed}
    # each fit of a round made as it would be alone: a refinement's steps never depend on who shares its rounds
    fit_side_by_side = functools.partial(fitter.quiet().fit, staged=False)
    extra, done_all = [], []
    wave = refinement_starts(ranked)
    queue = [s for s in down_the_ranking(ranked) if s.name not in {t.name for t in wave}]
    while wave:
        for start, done in zip(wave, refine_together([(grid[s.name], s) for s in wave], fit_side_by_side, known,
                                                     alpha_range)):
            extra += [(c, r) for c, r in done.steps if c.name not in done.reached]
            fitter.say(_refinement_line(grid, start, done))
            done_all.append(done)
        more = queue and rerank is not None and not _answered(rerank(extra) if extra else ranked)
        wave, queue = (queue[:REFINE_STARTS], queue[REFINE_STARTS:]) if more else ([], queue)
    return extra, done_all


def down_the_ranking(ranked: list[CandidateResult]) -> list[CandidateResult]:
    """Every fitted candidate that is not admissible, best fit first: where the refinement goes on when the
    candidates near the best cannot be made admissible."""
    fitted = [s for s in ranked if not s.failed and not s.placement.admissible and not s.estimates.withheld]
    return sorted(fitted, key=lambda s: (s.comparison.mse, s.name))


def _answered(ranked: list[CandidateResult]) -> bool:
    found = answer_of(ranked)
    return found is None or found.answered


def _refinement_line(grid: Grid, start: CandidateResult, done: Refinement) -> str:
    steps = " -> ".join([start.name] + [c.name for c, _ in done.steps]) or start.name
    # the first refusal and a count: every refused move would make a line of hundreds of characters
    more = len(done.refused) - 1
    stopped = (f"{done.refused[0]}; {more} more move{'s' if more > 1 else ''} refused" if more > 0
               else done.stopped)
    # cut: the refinement's whole record is in the grid's tables and refined_<grid>.toml
    return console_line(f"grid {grid.name}: refined {steps}"
                        + (f" (= {', '.join(done.reached)})" if done.reached else "") + f"; stopped: {stopped}")
