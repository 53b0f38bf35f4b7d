"""``diagnose`` with a simulator as its baseline (docs/interfaces.md 7.6): ``--baseline-column NAME`` (the
simulator's coefficient along the flight, a column of the campaign) or ``--simulator jsbsim:AIRCRAFT`` (a JSBSim
aircraft evaluated at the recorded states). The gap, flight minus simulator, is diagnosed by the same structure
search (:mod:`structsearch.diagnosis.offset`)."""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Sequence

from ..data.campaign import Campaign
from ..data.errors import DeclarationError
from .settings import Settings, command_fitter, fit_options

# the separation states a search from a simulator may add (structsearch.discovery.moves.NEW_STATES): a --bound
# may name their parameters
_ADDABLE_STATES = (("ss", "U"), ("w", "U"), ("w2", "U"))


def _simulator_target(simulator: str | None, simulator_inputs: Sequence[str]) -> tuple[str | None, dict, bool]:
    """(the JSBSim target, the inputs given for it, whether it is an aircraft structsearch did not export)."""
    if simulator is None:
        if simulator_inputs:
            raise DeclarationError("--simulator-input goes with --simulator jsbsim:NAME_OR_DIR")
        return None, {}, False
    from ..diagnosis.offset import simulator_target
    from ..export.jsbsim_baseline import exported_by_structsearch
    from ..foreign.baseline import parse_inputs
    target = simulator_target(simulator)
    given = parse_inputs(simulator_inputs)
    foreign = not exported_by_structsearch(target)
    if given and not foreign:
        raise DeclarationError(f"--simulator-input: {simulator} is an export of structsearch, which reads the "
                               "campaign's own columns; the option is for other JSBSim aircraft")
    return target, given, foreign


def _baseline(campaign: Campaign, coefficient: str, baseline_column: str | None, target: str | None, given: dict,
              foreign: bool, settings: Settings):
    """The simulator's ``coefficient`` at every sample: a column of the campaign, or a JSBSim aircraft evaluated."""
    from ..diagnosis import offset
    if target is None:
        return offset.column_baseline(campaign, coefficient, baseline_column)
    if settings.progress is not None:
        settings.progress(f"evaluating the JSBSim aircraft {target} at {campaign.data.n_samples} recorded samples")
    if foreign:
        from ..foreign.baseline import jsbsim_baseline as foreign_baseline
        return foreign_baseline(target, campaign, coefficient, given)
    from ..export.jsbsim_baseline import jsbsim_baseline
    return jsbsim_baseline(target, campaign, coefficient)


def diagnose_simulator(campaign: Campaign | str | os.PathLike, *, coefficient: str | None,
                       baseline_column: str | None = None, simulator: str | None = None,
                       settings: Settings = Settings(), out: str | os.PathLike | None = None,
                       terms: str | os.PathLike | None = None, beam: int | None = None,
                       max_steps: int | None = None, simulator_inputs: Sequence[str] = ()):
    """Diagnose the gap between a flight and a simulator's ``coefficient`` (exactly one of ``baseline_column``
    and ``simulator``); with ``out``, also write ``diagnosis.json`` and ``diagnosis.md`` there. Returns the
    diagnosis, whose ``simulator`` block says what the baseline was. ``simulator`` "jsbsim:NAME_OR_DIR": an export
    of ``structsearch export --format jsbsim`` is driven as ``export --check`` drives it; any other JSBSim aircraft
    is evaluated term by term at the recorded states (:mod:`structsearch.foreign.baseline`; ``simulator_inputs``:
    "PROPERTY=COLUMN|VALUE" items for what it reads and the campaign lacks), each term a column the search may
    rescale, drop or replace."""
    from ..diagnosis import offset
    from ..diagnosis.diagnose import DIAGNOSE, diagnose_search
    from ..fitting.candidates import Candidate
    from ..fitting.options import check_box_names
    from .settings import as_campaign
    if (baseline_column is None) == (simulator is None):
        raise DeclarationError("a simulator baseline is either --baseline-column NAME or --simulator jsbsim:AIRCRAFT")
    offset.check_coefficient(coefficient)
    # a malformed value is answered before the campaign is read
    target, given, foreign = _simulator_target(simulator, simulator_inputs)
    check_box_names(fit_options("diagnose", settings).parameter_boxes,
                    [Candidate("addable states", "", coefficient, (), _ADDABLE_STATES)])
    campaign = as_campaign(campaign, settings.segment, settings.reference_point)
    baseline = _baseline(campaign, coefficient, baseline_column, target, given, foreign, settings)
    start = offset.start_structure(baseline)
    with command_fitter("diagnose", offset.gap_campaign(campaign, baseline), settings, out) as fitter:
        setting = DIAGNOSE.but(state_level=False, beam=beam, max_rounds=max_steps)
        result, search = diagnose_search(fitter, start, setting, seed=settings.seed,
                                         terms=None if terms is None else str(terms),
                                         simulator_terms=offset.library_terms(baseline))
    bias = search.final.path()[0].result.estimates.params[start.regressors[0][0]]
    record = offset.simulator_record(campaign, baseline, bias)
    final = search.final.path()[-1]
    if baseline.terms:
        record["terms"] = offset.terms_record(baseline, final.candidate, final.result.estimates)
    result = dataclasses.replace(offset.without_bias_reasons(result, start), simulator=record)
    if out is not None:
        from ..reporting.diagnosis_doc import write
        write(result, Path(out))
    return result
