"""``discover``'s run: a structure search over moves from a minimal or named structure (the diagnosis'
engine, :func:`structsearch.diagnosis.diagnose.diagnose_with_search`), compared with the grid's rank-1
candidate and the thesis' final model (:mod:`.discovery_build`)."""
from __future__ import annotations

import dataclasses
from pathlib import Path

from ..data.errors import DeclarationError

from .discovery_build import GRIDS, build_discovery

def minimal(coefficient: str, lift: str | None):
    """The minimal structure: the intercept alone (a drag or pitch one fed the lift model ``lift``)."""
    from ..fitting.candidates import Candidate
    from ..fitting.specs import load_grid
    if coefficient == "CL":
        return Candidate("CL-minimal", "discover", "CL", (("CL0", "1"),), note="the intercept alone")
    lift_c = load_grid("lift")[lift]
    return Candidate(f"{coefficient}-minimal", "discover", coefficient, ((f"{coefficient}0", "1"),), lift_c.states,
                     lift, "the intercept alone", lift_c.bounds)


def _start(coefficient: str, start: str, lift_names: list[str]):
    from ..fitting.specs import resolve_candidate
    if start == "minimal":
        return minimal(coefficient, lift_names[0] if coefficient != "CL" else None)
    c = resolve_candidate(start)
    if c.coefficient != coefficient:
        raise DeclarationError(f"--from {start}: {c.name} models {c.coefficient}, not {coefficient}")
    return dataclasses.replace(c, grid="discover")



def discover_structures(campaign, coefficient: str, *, start: str = "minimal", lifts=(), terms=None,
                        beam: int | None = None, max_steps: int | None = None, options=None, n_jobs: int = 1,
                        backend: str = "loky", cache_dir: Path, progress=None):
    """Search structures for ``coefficient`` from ``start`` ("minimal", a candidate name or a spec file); drag and
    pitch structures may be fed ``lifts`` (names of the lift grid; default the thesis' CL-VI) and the start's own
    lift model. Fits are cached in ``cache_dir``. Returns the typed :class:`Discovery` (nothing written)."""
    from ..discovery.explore import DEFAULT_BEAM, DEFAULT_MAX_STEPS
    from ..fitting.options import FitOptions, check_box_names
    from ..fitting.specs import load_grid
    from ..flight.reference import FINAL_MODEL_NAMES
    say = progress or (lambda m: None)
    if coefficient not in GRIDS:
        raise DeclarationError(f"--coefficient {coefficient}: one of {', '.join(GRIDS)}")
    options = options or FitOptions(n_starts=2, cv_method="one-step")
    lift_grid = load_grid("lift")
    names = list(dict.fromkeys(list(lifts) or [FINAL_MODEL_NAMES["CL"]]))
    for n in names:
        lift_grid[n]   # an unknown lift model: the grid's error names the candidates it has
    first = _start(coefficient, start, names)
    if first.lift and first.lift not in names:
        names.insert(0, first.lift)
    check_box_names(options.parameter_boxes, [first])
    if terms is not None:   # a bad term file is an error before any lift model is fitted
        from ..discovery.terms import read_terms
        read_terms(terms, coefficient)
    return run_discovery(campaign, first, names, terms, beam or DEFAULT_BEAM, max_steps or DEFAULT_MAX_STEPS, options,
                         n_jobs, backend, Path(cache_dir), say, lift_grid)


def run_discovery(campaign, first, names, terms, beam, max_steps, options, n_jobs, backend, out: Path, say, lift_grid):
    import time
    from ..diagnosis.diagnose import diagnose_with_search
    from ..fitting.candidate_fit import fit_staged
    from ..fitting.lift_fit import LiftFit
    t0 = time.perf_counter()
    lifts = {}
    if first.coefficient != "CL":
        train, val = campaign.split("train"), campaign.split("validation")
        for n in names:
            say(f"fitting the lift model {n}")
            result = fit_staged(lift_grid[n], train, val, None, options)
            if result.failed:
                raise DeclarationError(f"fitting the lift model {n} failed: {result.error}")
            lifts[n] = LiftFit(lift_grid[n], result)
    diagnosis, exploration = diagnose_with_search(campaign, first, options=options, max_rounds=max_steps,
                                                  progress=say, states=False, n_jobs=n_jobs, lifts=lifts,
                                                  terms=None if terms is None else str(terms), beam=beam,
                                                  cache_dir=out, backend=backend, simplify=True)
    found = build_discovery(campaign, diagnosis, exploration, lifts, options, n_jobs, backend, out, say,
                            time.perf_counter() - t0)
    return found
