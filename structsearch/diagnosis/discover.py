"""``discover``'s run: the structure search of a diagnosis (:func:`.diagnose.diagnose_search`) in its
``discover`` setting (:data:`~structsearch.discovery.search_setting.DISCOVER`: every move kind, simplifying moves
adopted too) from a minimal or named structure, compared with the grid's rank-1 candidate and the thesis' final
model (:func:`structsearch.discovery.discovered.build_discovery`)."""
from __future__ import annotations

import dataclasses
import time

from ..data.errors import DeclarationError
from ..fitting.fitter import Fitter
from ..data.coefficients import COEFFICIENTS, GRID_OF
from ..discovery.discovered import Discovery, build_discovery
from ..discovery.search_setting import DISCOVER, SearchSetting
from .diagnose import diagnose_search

def minimal(coefficient: str, lift: str | None):
    """The minimal structure: the intercept alone (a drag or pitch one fed the lift model ``lift``)."""
    from ..fitting.candidates import Candidate
    from ..fitting.specs import load_grid
    if COEFFICIENTS[coefficient].owns_states:
        return Candidate(f"{coefficient}-minimal", "discover", coefficient, ((f"{coefficient}0", "1"),),
                         note="the intercept alone")
    lift_c = load_grid("lift")[lift]
    return Candidate(f"{coefficient}-minimal", "discover", coefficient, ((f"{coefficient}0", "1"),), lift_c.states,
                     lift, "the intercept alone", lift_c.bounds, lift_c.forms)


def _start(coefficient: str, start: str, lift_names: list[str]):
    from ..fitting.specs import resolve_candidate
    if start == "minimal":
        return minimal(coefficient, None if COEFFICIENTS[coefficient].owns_states else lift_names[0])
    c = resolve_candidate(start)
    if c.coefficient != coefficient:
        raise DeclarationError(f"--from {start}: {c.name} models {c.coefficient}, not {coefficient}")
    return dataclasses.replace(c, grid="discover")



def discover_structures(fitter: Fitter, coefficient: str, setting: SearchSetting = DISCOVER, *,
                        start: str = "minimal", lifts=(), terms=None,
                        moment_reference: str | None = None) -> Discovery:
    """Search structures for ``coefficient`` from ``start`` ("minimal", a candidate name or a spec file) with
    ``fitter``; drag and pitch structures may be fed ``lifts`` (names of the lift grid; default the thesis' CL-VI)
    and the start's own lift model. ``moment_reference`` ("cg" or "fixed"): a pitch start takes C_m about it
    (None: as it declares; the moves keep it); ``setting`` the search (:data:`DISCOVER`: every move kind, beam and
    length as ``discover``'s defaults; ``DISCOVER.but(kinds=...)`` restricts the moves). Returns the typed
    :class:`Discovery` (nothing written)."""
    from ..fitting.options import check_box_names
    from ..fitting.specs import load_grid
    from ..flight.reference import FINAL_MODEL_NAMES
    if coefficient not in GRID_OF:
        raise DeclarationError(f"--coefficient {coefficient}: one of {', '.join(GRID_OF)}")
    lift_grid = load_grid("lift")
    names = list(dict.fromkeys(list(lifts) or [FINAL_MODEL_NAMES["CL"]]))
    for n in names:
        lift_grid[n]   # an unknown lift model: the grid's error names the candidates it has
    first = _start(coefficient, start, names).with_moment_reference(moment_reference)
    if first.lift and first.lift not in names:
        names.insert(0, first.lift)
    check_box_names(fitter.options.parameter_boxes, [first])
    if terms is not None:   # a bad term file is an error before any lift model is fitted
        from ..discovery.terms import read_terms
        read_terms(terms, coefficient)
    t0 = time.perf_counter()
    fitter = dataclasses.replace(fitter, lifts=_lift_models(fitter, first, [lift_grid[n] for n in names]))
    diagnosis, exploration = diagnose_search(fitter, first, setting, seed=fitter.options.seed,
                                             terms=None if terms is None else str(terms))
    return build_discovery(fitter, diagnosis, exploration, time.perf_counter() - t0)


def _lift_models(fitter: Fitter, first, candidates) -> dict:
    """The lift models a drag or pitch structure may be fed, fitted (none for a lift structure)."""
    from ..fitting.lift_fit import LiftFit
    if COEFFICIENTS[first.coefficient].owns_states:
        return {}
    fitter.say(f"fitting the lift model{'s' if len(candidates) > 1 else ''} {', '.join(c.name for c in candidates)}")
    lifts = {}
    # fitted together: their starts and folds are tasks on the workers
    for c, result in zip(candidates, fitter.quiet().fit(candidates)):
        if result.failed:
            raise DeclarationError(f"fitting the lift model {c.name} failed: {result.error}")
        lifts[c.name] = LiftFit(c, result)
    return lifts
