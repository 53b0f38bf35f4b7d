"""The typed :class:`Discovery` of a structure search: its path read from the diagnosis' rounds and the search's
nodes, and the comparison with the grid's rank-1 candidate and the thesis' final model."""
from __future__ import annotations

from pathlib import Path

from ..diagnosis.discovered import ComparisonRow, Discovery, FinalStructure, PathStep, StepLine


# The grid each coefficient's rank-1 candidate comes from.
GRIDS = {"CL": "lift", "CD": "drag", "Cm": "pitch"}


def _cv(result) -> float | None:
    return result.cv.mse if result.cv is not None else None


def _row(role, candidate, result, found, judge) -> ComparisonRow:
    from ..discovery.adoption import move_test
    if result.failed:
        return ComparisonRow(role, candidate.name, 0, float("nan"), None, False, None, None, None)
    reasons = tuple(judge(result, candidate))
    if result is found:
        excess = se = None
        within = True
    else:
        test = move_test(result, found, 1.0, 1)   # the discovered structure against this one
        excess, se, within = -test.gain, test.gain_se, test.within_one_se
    return ComparisonRow(role, candidate.name, len(result.params), result.validation.mse, _cv(result), not reasons,
                         excess, se, within, tuple(e for _, e in candidate.regressors))


def build_discovery(campaign, diagnosis, exploration, lifts, options, n_jobs, backend, out: Path, say,
                    seconds: float) -> Discovery:
    from ..discovery.explore import fit_structures
    from ..discovery.judge import judge_for
    from ..fitting.specs import find_candidate
    from ..flight.reference import FINAL_MODEL_NAMES
    from ..grid_search.pipeline import search
    judge = judge_for(campaign)
    nodes = exploration.final.path()
    path = []
    for i, node in enumerate(nodes[1:]):
        r = diagnosis.rounds[i]
        row = r.effect(node.move.name)
        path.append(PathStep(node.move.name, node.move.kind, node.move.effect, node.candidate.to_dict(),
                             node.result.validation.mse, _cv(node.result),
                             node.test.to_dict() if node.test is not None else None,
                             row.shrink if row is not None else None,
                             dict(row.acts_in) if row is not None and row.acts_in else None, node.status))
    final_node = exploration.final
    final = FinalStructure(final_node.candidate.name, None, final_node.candidate.to_dict(),
                           final_node.result.validation.mse, _cv(final_node.result), final_node.admissible,
                           final_node.reasons)
    coef = final_node.candidate.coefficient
    say(f"the {GRIDS[coef]} grid's rank-1 candidate and the thesis' final model, for comparison")
    rows = [_row("discovered", final_node.candidate, final_node.result, final_node.result, judge)]
    grid = search(campaign, GRIDS[coef], out, n_jobs=n_jobs, options=options, backend=backend, do_refine=False)
    ranked = grid.grids[GRIDS[coef]]
    if ranked and not ranked[0].failed:
        from ..fitting.specs import load_grid
        rank1 = load_grid(GRIDS[coef])[ranked[0].name]
        rows.append(_row(f"{GRIDS[coef]} grid rank 1", rank1, ranked[0], final_node.result, judge))
    thesis = find_candidate(FINAL_MODEL_NAMES[coef])
    (thesis_result,) = fit_structures([thesis], campaign, out, lifts, options, n_jobs, backend)
    rows.append(_row("thesis final", thesis, thesis_result, final_node.result, judge))
    steps = tuple(StepLine(s.index, len(s.tried), (s.beam[0].status + " " + s.beam[0].move.name) if s.beam else "-",
                           min((n for n in s.beam), key=lambda n: n.mse).candidate.name if s.beam else "-",
                           min((n.mse for n in s.beam), default=float("nan")), s.seconds)
                  for s in exploration.steps)
    start = exploration.start
    return Discovery(coef, start.candidate.to_dict(), start.result.validation.mse, _cv(start.result), tuple(path),
                     final, tuple(rows), steps, exploration.stopped, exploration.n_fitted, diagnosis.noise_floor,
                     diagnosis.explained, diagnosis, seconds)
