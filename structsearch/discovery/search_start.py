"""Where a structure search starts: the baseline fitted, the term library it draws moves from, the lift models
its drag or pitch structures may be fed, and the judge of admissibility. The diagnosis and ``discover`` start
their searches here, so both check their inputs alike and in the same order (a bad term file is an error
before anything is fitted)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..data.errors import DataError, DeclarationError
from ..fitting.candidate_fit import fit_lift_model
from ..fitting.candidate_result import CandidateResult
from ..fitting.candidates import Candidate
from ..fitting.fitter import Fitter
from ..flight.reference import FINAL_MODEL_NAMES
from .explore import Judge
from .judge import judge_for
from .moves import MOVE_KINDS, generate
from .terms import SimulatorTerm, TermLibrary, library_for


@dataclass(frozen=True)
class SearchStart:
    """A structure search ready to run: ``fitter`` holds every lift model a drag or pitch structure may be fed,
    ``result`` is the baseline's fit and ``reasons`` why it is not admissible (none: it is)."""

    fitter: Fitter
    baseline: Candidate
    library: TermLibrary
    judge: Judge
    result: CandidateResult
    reasons: tuple[str, ...]


def start_search(fitter: Fitter, baseline: Candidate, terms: str | None = None,
                 kinds=MOVE_KINDS, simulator_terms: tuple[SimulatorTerm, ...] = ()) -> SearchStart:
    """The search from ``baseline``: ``fitter``'s lift models are the ones given (the story's lift structure found
    for C_L, discover's ``--lifts``); ``terms`` is a user's term file; ``simulator_terms`` the terms of a simulator
    baseline the moves may rescale, drop or replace."""
    train, val = fitter.splits()
    if baseline.coefficient not in val:
        raise DataError("the campaign has no column for the diagnosed coefficient",
                        source=str(fitter.campaign.directory), column=baseline.coefficient)
    # the term library first: a bad term file is an error before anything is fitted
    library = library_for(baseline.coefficient, train, terms)
    if simulator_terms:
        missing = [t.column for t in simulator_terms if t.column not in train]
        if missing:
            raise DataError("the campaign has no column for the simulator's term", source=str(fitter.campaign.directory),
                            column=missing[0])
        library = dataclasses.replace(library, simulator=tuple(simulator_terms))
    fitter = with_lift_models(fitter, baseline)
    if not generate(baseline, library, {n: lf.candidate for n, lf in fitter.lifts.items()}, kinds):
        raise DeclarationError(f"no move of the structure search applies to {baseline.name}")
    result = fitter.quiet().fit_one(baseline)
    if result.failed:
        raise DeclarationError(f"fitting {baseline.name} failed: {result.error}")
    judge = judge_for(fitter.campaign)
    return SearchStart(fitter, baseline, library, judge, result, tuple(judge(result, baseline)))


def with_lift_models(fitter: Fitter, baseline: Candidate) -> Fitter:
    """``fitter`` with the lift models a drag or pitch structure may be fed: its own (fitted unless given), the
    thesis' final one and those given."""
    if not baseline.lift:
        return dataclasses.replace(fitter, lifts={})
    train, val = fitter.splits()
    given = dict(fitter.lifts)
    own = given.get(baseline.lift)
    if own is None:
        fitter.say(f"fitting the lift model {baseline.lift}")
        own = fit_lift_model(baseline, train, val, fitter.options)
    lifts = {baseline.lift: own}
    thesis = FINAL_MODEL_NAMES["CL"]
    if thesis not in lifts and thesis not in given:
        lifts[thesis] = fit_lift_model(dataclasses.replace(baseline, lift=thesis), train, val, fitter.options)
    lifts.update(given)
    return dataclasses.replace(fitter, lifts=lifts)
