"""``structsearch discover``: a structure search over moves from a minimal or named structure, compared with
the grids' rank-1 candidate and the thesis' final model."""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Callable, Iterable

from ..data.campaign import Campaign
from ..data.errors import DeclarationError

Progress = Callable[[str], None] | None
# The grid each coefficient's rank-1 candidate comes from (the lift grid's rank 1 also needs the separation
# grid's fits: they share the cache).
GRIDS = {"CL": "lift", "CD": "drag", "Cm": "pitch"}


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


def discover(campaign: Campaign | str | os.PathLike, coefficient: str, *, start: str = "minimal",
             lifts: Iterable[str] = (), terms: str | os.PathLike | None = None, beam: int | None = None,
             max_steps: int | None = None, starts: int = 2, seed: int = 0, covariance: str | None = None,
             bounds=None, jobs: int = 0, backend: str = "loky", out: str | os.PathLike | None = None,
             progress: Progress = None):
    """Search structures for ``coefficient`` from ``start`` ("minimal", a candidate name or a spec file) as
    ``structsearch discover`` does; with ``out``, write discover.json, discover.md, path.csv and the final
    structure's spec file there (fits cached in ``out/cache``). Returns the typed :class:`Discovery`."""
    import tempfile
    from ..discovery.explore import DEFAULT_BEAM, DEFAULT_MAX_STEPS
    from ..engine.statistics import DEFAULT_COVARIANCE
    from ..fitting.options import check_box_names
    from ..fitting.specs import load_grid
    from ..flight.reference import FINAL_MODEL_NAMES
    from .commands import as_campaign, fit_options, process_count
    say = progress or (lambda m: None)
    if coefficient not in GRIDS:
        raise DeclarationError(f"--coefficient {coefficient}: one of {', '.join(GRIDS)}")
    campaign = as_campaign(campaign)
    lift_grid = load_grid("lift")
    names = list(dict.fromkeys(list(lifts) or [FINAL_MODEL_NAMES["CL"]]))
    for n in names:
        lift_grid[n]   # an unknown lift model: the grid's error names the candidates it has
    first = _start(coefficient, start, names)
    if first.lift and first.lift not in names:
        names.insert(0, first.lift)
    options = dataclasses.replace(fit_options(starts, seed, covariance or DEFAULT_COVARIANCE, bounds),
                                  cv_method="one-step")
    check_box_names(options.parameter_boxes, [first])
    if out is None:
        with tempfile.TemporaryDirectory(prefix="structsearch-discover-") as tmp:
            return _discover(campaign, first, names, terms, beam or DEFAULT_BEAM, max_steps or DEFAULT_MAX_STEPS,
                             options, process_count(jobs), backend, Path(tmp), False, say, lift_grid)
    return _discover(campaign, first, names, terms, beam or DEFAULT_BEAM, max_steps or DEFAULT_MAX_STEPS, options,
                     process_count(jobs), backend, Path(out), True, say, lift_grid)


def _discover(campaign, first, names, terms, beam, max_steps, options, n_jobs, backend, out: Path, write: bool, say,
              lift_grid):
    import time
    from ..diagnosis.diagnose import diagnose_with_search
    from ..fitting.candidate_fit import fit_staged
    from ..fitting.lift_fit import LiftFit
    from .discovery_build import build_discovery
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
                                                  cache_dir=out, backend=backend)
    found = build_discovery(campaign, diagnosis, exploration, lifts, options, n_jobs, backend, out, say,
                            time.perf_counter() - t0)
    if write:
        from ..report.discovery_doc import write_discovery
        found = write_discovery(found, out)
    return found
